"""A fixed camera's background plate: the same background in every frame (issue 30; capture.plate).

A turntable shot keeps the camera still and turns the object: each pixel sees the room in the frames
where the object is not in front of it.  Its plate is the robust mode of the frames' colours there
(:func:`robust_mode`): the heaviest cluster of samples that agree to MODE_TOL, weighted by how far
each frame's object depth is from the pixel (:func:`fixed_sample_weight`), rejected as ambiguous
when a rival cluster nearly as heavy disagrees (a needle that stayed put over several frames).  A
median of all frames would take in the needles wherever they cover a pixel in half of them.  The
frames' exposures (auto exposure) are fitted first on the pixels every frame sees
(:func:`fixed_gains`).  A sample blown out in its own frame (a channel at
``matting_known.CLIP_LEVEL``: the sunlit wall) is no measurement of the background, only a lower bound
on it: under auto exposure 1.0 x gain differs from frame to frame, and drawn into a darker frame it
fell below the clip level as if it were the exact background (:func:`censored_mode`).  As a path of
``capture.plate`` (``capture.plate.path_functions``):
:func:`fixed_start`, :func:`fixed_predict` and :func:`fixed_draw` on a ``capture.plate.PlateSet``.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from capture.plate import GAIN_PASSES, SOURCE_BAND_FRACTION, PlateSet, PlateView, fit_gains, px
from capture.plate_masks import common_grid
from capture.plate_reproject import nan_median

#: A pixel's plate needs this many frames that agree on its colour (robust_mode).
FIXED_MIN_FRAMES = 3
#: Pixels (on a regular grid) used for the first exposure gains.
FIXED_GAIN_PIXELS = 20000
#: A frame lends samples where it has no object depth within this fraction of the width (2 px at 640).
FIXED_EXCLUDE_FRACTION = 2 / 640
#: Robust mode: samples within this (8-bit sRGB, largest channel) of each other agree.
MODE_TOL = 3.0 / 255
#: Robust mode: a rival cluster (no sample in common) weighing this fraction of the heaviest one makes
#: the pixel unknown.
MODE_AMBIGUOUS = 0.5
#: Where no frame saw a pixel's background clean, solve it from the frames' lines (capture.plate_lines).
FIXED_ESTIMATE_UNSEEN = True
#: A frame's sample blown out in its own exposure (a channel at matting_known.CLIP_LEVEL) is a lower
#: bound on the background, not a sample of it (:func:`censored_mode`).  Off: every sample a
#: measurement, as before (under auto exposure the conifer with table, AE and lens lost 2.5 dB held
#: out with the true matte: docs/matting.md, issue 30 fourth round).
FIXED_CENSOR_CLIPPED = True
#: Gains taken only if they also cut the median held-back error this much (docs/speed.md round 16: 0.5-2.3 % vs 61 %).
FIXED_GAIN_MIN_CUT = 0.1
#: Robust mode: pixels per chunk (a K x K x chunk agreement array).
MODE_CHUNK = 20000
#: Frames the fixed camera's plate (its robust mode, fixed_draw) takes at most, evenly spaced over the
#: capture: a mode's cost grows with the square of the frames per pixel (a 200-frame phone capture's
#: plate stage took 297 s of its 12.5 minutes with every frame); 64 frames of one background are
#: plenty.  Captures of up to FIXED_MAX_FRAMES + 1 frames: unchanged.
FIXED_MAX_FRAMES = 64
#: ... and the frames the per-view work takes at most: each view's ring prediction (200 views x the
#: refit's rounds: 53 % of the phone capture's plate stage at 64 frames) and the lines' estimate
#: (every candidate vertex against every frame: 24 %).  Captures of up to FIXED_RING_FRAMES + 1
#: frames (the 18 kept views of a 36-view capture): unchanged.
FIXED_RING_FRAMES = 32
#: Robust mode: entries of the K x K x chunk agreement array at most (the chunk shrinks with K^2;
#: 200 frames at MODE_CHUNK pixels would take 3.2 GB per float temporary).  64 frames take 5,000
#: pixels a chunk: its float32 temporaries 82 MB each (at 20,000 they were 328 MB, a third of the
#: phone capture's plate stage peak above its views); the result does not depend on the chunk.
MODE_PAIRS = 64 * 64 * 5000
#: The plate's robust mode (fixed_draw) over the union of the views' need masks takes this many pixels at a
#: time, the chunks side by side (the same values): one call held every frame's samples of the union at
#: once (K x N x 3 float32 and its copies; 64 frames x 0.5 M pixels at 72 views of 1280x960).
DRAW_CHUNK = 20000
#: The frames' lines (unseen_fill) solve this many pixels at a time, the chunks side by side (the same values).
FILL_CHUNK = 16000
#: Robust mode by capture.plate_mode_kernel's compiled loop a pixel (the same values bit for bit as the
#: numpy path, kept as robust_mode(fast=False); 72 views of 1280x960: docs/speed.md round 5).
MODE_COMPILED = True
#: The sample weights' distances to the object (fixed_sample_weight) by OpenCV's exact Euclidean distance
#: transform (20-30x scipy's on a 1280x960 frame; the same values, tests/capture/test_plate.py).
EDT_OPENCV = True


def robust_mode(samples: np.ndarray, weights: np.ndarray | None = None,
                fast: bool | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(colour (N, 3), support (N,) int) of samples (K, N, 3) linear (NaN = none) per column: the
    heaviest cluster (the sample whose agreeing samples, within MODE_TOL in 8-bit sRGB, weigh most;
    ``weights`` (K, N), default 1), then the median of those; support = how many agree.  A needle
    crossing a background pixel in some frames leaves samples spread between B and F; the frames
    it missed agree to the noise, and they were further from the object (heavier).  ``fast`` (default
    MODE_COMPILED): capture.plate_mode_kernel's loop a pixel, equal bit for bit to the numpy path
    (``fast=False``, the reference)."""
    from capture.scan import linear_to_srgb

    if (MODE_COMPILED if fast is None else fast) and (weights is None or np.asarray(weights).dtype == np.float32):
        return _robust_mode_compiled(samples, weights)  # (float64 weights: numpy sums in float64)
    K, N, _ = samples.shape
    colour = np.full((N, 3), np.nan, np.float32)
    support = np.zeros(N, np.int64)
    chunk = max(1, min(MODE_CHUNK, MODE_PAIRS // max(1, K * K)))
    for lo in range(0, N, chunk):
        s = samples[:, lo:lo + chunk].astype(np.float32)
        have = np.isfinite(s[..., 0])
        w = have.astype(np.float32) if weights is None else np.where(have, weights[:, lo:lo + chunk], 0.0)
        e = linear_to_srgb(np.nan_to_num(s))
        close = have[:, None] & have[None]  # (K, K, n): every channel within MODE_TOL (channel by channel:
        for c in range(3):  # a (K, K, n, 3) array's max over its last axis took 3x as long)
            close &= np.abs(e[None, :, :, c] - e[:, None, :, c]) <= MODE_TOL
        score = (close * w[None]).sum(axis=1)  # (K, n): weight of the samples agreeing with each
        best = np.argmax(score, axis=0)  # (n,): the heaviest cluster's centre
        cols = np.arange(s.shape[1])
        members = close[best, :, cols].T  # (K, n): samples close to it
        # a rival cluster apart from it nearly as heavy: the pixel is ambiguous (a needle that stayed put)
        outside = ~members
        rival = np.where(outside, ((close & outside[None]) * w[None]).sum(axis=1), 0.0).max(axis=0)
        members &= (rival < MODE_AMBIGUOUS * score[best, cols])[None]
        n = members.sum(axis=0)
        med = nan_median(np.where(members[..., None], s, np.nan))
        colour[lo:lo + chunk] = np.where((n > 0)[:, None], med, np.nan)
        support[lo:lo + chunk] = n
    return colour, support


def _robust_mode_compiled(samples: np.ndarray, weights: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """:func:`robust_mode` by capture.plate_mode_kernel (the same values)."""
    from capture.plate_mode_kernel import mode_median, mode_members
    from capture.plate_threads import chunks, thread_map
    from capture.scan import linear_to_srgb

    K, N, _ = samples.shape
    colour = np.full((N, 3), np.nan, np.float32)
    support = np.zeros(N, np.int64)

    def one(span):  # the temporaries of a chunk only (K x MODE_CHUNK x 3); chunks side by side
        lo, hi = span
        s = np.asarray(samples[:, lo:hi], np.float32)
        have = np.isfinite(s[..., 0])
        w = have.astype(np.float32) if weights is None else np.where(have, weights[:, lo:hi], 0.0).astype(np.float32)
        # np.fmax(s, 0): NaN to 0 as nan_to_num; negative or infinite samples clip the same in linear_to_srgb
        members = mode_members(linear_to_srgb(np.fmax(s, 0.0)), have, w, MODE_TOL, MODE_AMBIGUOUS)
        n = members.sum(axis=0)
        colour[lo:hi] = np.where((n > 0)[:, None], mode_median(s, members), np.nan)
        support[lo:hi] = n

    for _ in thread_map(one, chunks(N, MODE_CHUNK)):
        pass
    return colour, support


def censored_mode(samples: np.ndarray, weights: np.ndarray | None, hot: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(colour (N, 3), support (N,), bound (N,) bool) of samples (K, N, 3) in the common exposure
    (NaN = none) of which ``hot`` (K, N) were blown out in their own frame: the robust mode
    (:func:`robust_mode`) of the others, raised channel by channel to the largest blown-out sample
    (a blown-out sample is at most the background: the sensor stopped there); where fewer than
    FIXED_MIN_FRAMES others agree but at least FIXED_MIN_FRAMES samples are blown out, that largest
    one, flagged ``bound`` (only a lower bound: drawn into a frame where it falls below the clip
    level, the background there is not known).  NaN where neither holds."""
    hot = np.asarray(hot, bool) & np.isfinite(samples[..., 0])
    free = np.where(hot[..., None], np.nan, samples)
    col, support = robust_mode(free, None if weights is None else np.where(hot, 0.0, weights))
    n_hot = hot.sum(axis=0)
    lb = np.where(hot[..., None], samples, -np.inf).max(axis=0)  # -inf where no sample is blown out
    ok = support >= FIXED_MIN_FRAMES
    bound = ~ok & (n_hot >= FIXED_MIN_FRAMES)
    col = np.where(ok[:, None], np.maximum(col, lb), np.where(bound[:, None], lb, np.nan)).astype(np.float32)
    return col, np.where(ok, support, np.where(bound, n_hot, support)), bound


def fixed_sample_weight(object_depth: np.ndarray, fast: bool | None = None) -> np.ndarray:
    """(H, W) float32 weight of a frame's pixels as fixed-camera plate samples: 0 within
    FIXED_EXCLUDE_FRACTION of the width of the object's depth (the robust mode takes out needles
    the depth missed), rising to 1 at SOURCE_BAND_FRACTION (confidently background).  ``fast``
    (default EDT_OPENCV): the distances from OpenCV (:func:`_edt_opencv`), the same values as
    ``fast=False`` (scipy's, the reference)."""
    m = np.asarray(object_depth) > 0
    W = m.shape[1]
    if not m.any():
        return np.ones(m.shape, np.float32)
    band, exclude = px(SOURCE_BAND_FRACTION, W), px(FIXED_EXCLUDE_FRACTION, W)
    if EDT_OPENCV if fast is None else fast:
        from capture.plate_weight import WEIGHT_BOX, near_weight_box  # the box alone (same values)

        return (near_weight_box if WEIGHT_BOX else _near_weight)(m, band, exclude)
    d = ndimage.distance_transform_edt(~m)
    return np.where(d > exclude, np.clip(d / band, 0.0, 1.0), 0.0).astype(np.float32)


def _near_weight(m: np.ndarray, band: int, exclude: int) -> np.ndarray:
    """fixed_sample_weight's weights from OpenCV's distances (:func:`_edt_opencv`'s), worked out in
    float64 only near the object (distance below ``band`` + 1: most of a frame is 1 whatever the
    rounding of a float32 distance), the same values as scipy's (the reference) at a fraction of the
    full-frame float64 passes."""
    import cv2

    d32 = cv2.distanceTransform((~m).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    out = np.ones(m.shape, np.float32)
    near = d32 < band + 1
    d = np.sqrt(np.rint(d32[near].astype(np.float64) ** 2))
    out[near] = np.where(d > exclude, np.clip(d / band, 0.0, 1.0), 0.0)
    return out


def _edt_opencv(mask: np.ndarray) -> np.ndarray:
    """``ndimage.distance_transform_edt(~mask)`` of a 2-D bool mask: OpenCV's exact Euclidean distance
    (DIST_MASK_PRECISE) in float32, squared and rounded to the integer squared distance it is, then its
    float64 square root as scipy takes it (float32 keeps the integers below 2^24 exactly enough to round
    back: 0 differences measured up to the far corner of a 1280x960 frame, and past SOURCE_BAND_FRACTION
    of the width the weight is 1 whatever the rounding)."""
    import cv2

    d32 = cv2.distanceTransform((~mask).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    return np.sqrt(np.rint(d32.astype(np.float64) ** 2))


def mode_frames(n: int, i: int | None, cap: int | None = None) -> list[int]:
    """The frames (of ``n``, all but ``i``) whose samples the robust mode takes: every one, or
    ``cap`` (default FIXED_MAX_FRAMES) of them evenly spaced when there are more."""
    cap = FIXED_MAX_FRAMES if cap is None else cap
    frames = [j for j in range(n) if j != i]
    if len(frames) <= cap:
        return frames
    pick = np.unique(np.round(np.linspace(0, len(frames) - 1, cap)).astype(int))
    return [frames[k] for k in pick]


def fixed_prediction(views: list[PlateView], pix: np.ndarray, i: int | None, gains: np.ndarray,
                     weights: list[np.ndarray] | None = None, frames: list[int] | None = None
                     ) -> tuple[np.ndarray, np.ndarray]:
    """((N, 3) fixed-camera plate at pixels ``pix`` (N, 2), (N,) bool only a lower bound) from the
    ``frames`` (default every frame but ``i``; None: all), in the common exposure (colour x gain):
    the robust mode (:func:`robust_mode`) of the frames' samples weighted by ``weights`` (default
    :func:`fixed_sample_weight`), with the samples blown out in their own frame as lower bounds
    (:func:`censored_mode`, FIXED_CENSOR_CLIPPED); NaN where fewer than FIXED_MIN_FRAMES agree."""
    from capture.matting_fast import channel_max
    from capture.matting_known import CLIP_LEVEL

    x, y = pix[:, 0], pix[:, 1]
    frames = [j for j in range(len(views)) if j != i] if frames is None else frames
    s = np.full((len(frames), len(pix), 3), np.nan, np.float32)
    w = np.zeros((len(frames), len(pix)), np.float32)
    hot = np.zeros((len(frames), len(pix)), bool)
    for row, j in enumerate(frames):
        v = views[j]
        w[row] = (fixed_sample_weight(v.object_depth) if weights is None else weights[j])[y, x]
        ok = w[row] > 0
        c = v.linear[y[ok], x[ok]]
        s[row, ok] = c * gains[j]
        hot[row, ok] = channel_max(c) >= CLIP_LEVEL  # c.max(axis=-1)
    if FIXED_CENSOR_CLIPPED:
        col, _, bound = censored_mode(s, w, hot)
        return col, bound
    col, support = robust_mode(s, w)
    col[support < FIXED_MIN_FRAMES] = np.nan
    return col, np.zeros(len(pix), bool)


def in_view(col: np.ndarray, bound: np.ndarray, gain: np.ndarray) -> np.ndarray:
    """The plate ``col`` (N, 3) of the common exposure in a view of exposure ``gain`` (3,); NaN where
    it is only a lower ``bound`` that falls below the clip level there (not known)."""
    from capture.matting_known import CLIP_LEVEL

    out = col / gain
    out[bound & (np.nan_to_num(out).max(axis=-1) < CLIP_LEVEL)] = np.nan
    return out


def fixed_gains(views: list[PlateView], weights: list[np.ndarray]) -> np.ndarray:
    """(V, 3) exposure gains of a fixed camera's frames (true colour = colour x gain) from about
    FIXED_GAIN_PIXELS pixels (a regular grid) that all frames may lend: each frame against the
    per-pixel median of the frames (GAIN_PASSES times, the median taken over the gain-corrected frames)."""
    H, W = weights[0].shape
    k = max(1, int(np.sqrt(H * W / FIXED_GAIN_PIXELS)))
    common = common_grid(weights, slice(None, None, k), slice(None, None, k))  # as the whole frames' [::k, ::k]
    obs = [v.linear[::k, ::k][common].astype(np.float64) for v in views]
    gains = np.ones((len(views), 3))
    if not common.any():
        return gains
    for _ in range(GAIN_PASSES):
        med = np.median(np.stack([o * g for o, g in zip(obs, gains, strict=True)]), axis=0)
        gains = fit_gains(obs, [med] * len(obs))
    return gains


def fixed_exposure_check(ps: PlateSet, gains: np.ndarray) -> dict:
    """Whether a fixed camera's exposure gains (V, 3) beat none on background pixels neither fit saw:
    the grid of :func:`fixed_gains` shifted by half its step, where every frame is confidently
    background and no frame is dark or blown out (capture.plate GAIN_DARK / GAIN_BRIGHT).  Per view,
    the mean largest-channel |log(colour x gain) - log(median of the other frames)| with the gains and
    with none; the gains win a view when theirs is smaller.  Accepted (``chosen`` 'plate') when they
    win at least V / 2 + sqrt(V) of the V views (a sign test: two standard errors above chance) and cut
    the views' median error by FIXED_GAIN_MIN_CUT, else 'none': the gains cannot be told from noise (a
    capture at fixed exposure), or they fit a background the fixed camera does not explain.  A fixed camera
    sees one static background, so these gains are each frame's exposure (auto exposure, white balance:
    the camera scales the whole frame), the object's included (volume/photometric.py)."""
    from capture.plate import _usable

    views, weights = [p.view for p in ps.views], [p.weight for p in ps.views]
    V = len(views)
    H, W = weights[0].shape
    k = max(2, int(np.sqrt(H * W / FIXED_GAIN_PIXELS)))
    sl = (slice(k // 2, None, k), slice(k // 2, None, k))
    common = common_grid(weights, *sl)  # np.logical_and.reduce([w >= 1 for w in weights])[sl]
    obs = np.stack([v.linear[sl][common].astype(np.float64) for v in views])  # (V, N, 3)
    obs = obs[:, np.all(_usable(obs), axis=0)]
    need = int(np.ceil(V / 2 + np.sqrt(V)))
    rec = {"chosen": "none", "views": V, "wins": 0, "needed": need, "pixels": int(obs.shape[1])}
    if V < FIXED_MIN_FRAMES or obs.shape[1] < FIXED_GAIN_PIXELS // 100:
        return {**rec, "reason": "too few frames or background pixels that every frame sees"}

    def error(g):
        lg = np.log(obs) + np.log(np.asarray(g, np.float64))[:, None]
        return np.array([np.abs(lg[i] - m).max(-1).mean() for i, m in enumerate(others_median(lg))])

    from capture.plate_exposure import gain_verdict

    got, verdict = gain_verdict(error(gains), error(np.ones((V, 3))), need)
    lg = np.log2(obs)  # each frame against the others' median: its exposure (capture.photometric_background)
    ring = [[round(float(x), 5) for x in np.median(lg[i] - m, axis=0)] for i, m in enumerate(others_median(lg))]
    return {**rec, **got, "ring_log2": ring,
            "reason": f"the background's gains beat none in {got['wins']} of {V} views on held-back pixels ({verdict})"}


def others_median(a: np.ndarray, fast: bool = True):
    """Per i (a generator), the median over axis 0 of ``a`` (V, ...) without its row i: numpy's
    ``np.median(np.delete(a, i, axis=0), axis=0)`` (``fast=False``, the reference), or from one sort of
    ``a`` (each row's rank; the median's one or two middle values of the others read past the row's own
    place, their mean as numpy takes it: the same values, V times fewer sorts; finite ``a``)."""
    V = a.shape[0]
    if not fast or V < 2:
        yield from (np.median(np.delete(a, i, axis=0), axis=0) for i in range(V))
        return
    order = np.argsort(a, axis=0)
    srt = np.take_along_axis(a, order, axis=0)
    rank = np.empty_like(order)
    np.put_along_axis(rank, order, np.arange(V).reshape((V,) + (1,) * (a.ndim - 1)), axis=0)
    m = V - 1  # the others
    for i in range(V):
        lo, hi = ((m - 1) // 2 + ((m - 1) // 2 >= rank[i]), m // 2 + (m // 2 >= rank[i]))
        a_lo = np.take_along_axis(srt, lo[None], axis=0)[0]
        yield a_lo if m % 2 else (a_lo + np.take_along_axis(srt, hi[None], axis=0)[0]) / 2.0


def fixed_start(ps: PlateSet) -> np.ndarray:
    """The fixed camera's first gains (:func:`fixed_gains` of the prepared views)."""
    return fixed_gains([p.view for p in ps.views], [p.weight for p in ps.views])


def fixed_predict(ps: PlateSet, gains: np.ndarray) -> list[np.ndarray]:
    """Per view its ring (N_i, 3) predicted from the other frames (leave one out; FIXED_RING_FRAMES of
    them at most, :func:`mode_frames`), in its own exposure."""
    from capture import plate_predict as pp  # compiled, the same rings (pp.FUSED_PREDICTION)
    from capture.plate_threads import thread_map  # views side by side (the same predictions)

    views, weights = [p.view for p in ps.views], [p.weight for p in ps.views]
    if pp.applies(views, gains, weights):
        return pp.fused_ring_predict(ps, gains)

    def one(i):
        ring = ps.views[i].ring
        return in_view(*fixed_prediction(views, ring, i, gains, weights, mode_frames(len(views), i, FIXED_RING_FRAMES)),
                       gains[i])

    return list(thread_map(one, range(len(views))))


def fixed_draw(ps: PlateSet, gains: np.ndarray):
    """Per view, one at a time (an iterator), (colour (H, W, 3) float32 in its own exposure, known
    (H, W), estimated (H, W)) of the fixed-camera plate on the union of the views' need masks
    (module docstring): one robust mode per pixel; where that finds none, the background solved from the frames' lines
    (:func:`unseen_fill`; ``estimated``, a subset of ``known``)."""
    from capture import plate_fast

    needs = [p.need for p in ps.views]
    union = plate_fast.union(needs)  # np.logical_or.reduce(needs), without the stacked masks
    y, x = np.nonzero(union)
    med, bound = _draw_prediction([p.view for p in ps.views], np.stack([x, y], axis=1), gains,
                                  [p.weight for p in ps.views], mode_frames(len(ps.views), None))
    sigma = np.full(len(y), np.nan)  # the lines' uncertainty (capture.plate_lines.vertex_sigma)
    est = unseen_fill(ps, gains, y, x, med, bound, sigma) if FIXED_ESTIMATE_UNSEEN else np.zeros(len(y), bool)
    return _fixed_views(ps, gains, needs, union.shape, y, x, med, est, bound, sigma)


def _draw_prediction(views, pix, gains, weights, frames) -> tuple[np.ndarray, np.ndarray]:
    """:func:`fixed_prediction` of every pixel ``pix`` from ``frames`` (none left out), DRAW_CHUNK pixels
    at a time, the chunks side by side (capture.plate_threads): each pixel's plate is its own samples'
    alone, so the values are the same as one call's."""
    from capture import plate_predict as pp
    from capture.plate_threads import chunked_prediction

    if pp.applies(views, gains, weights):  # compiled, the same values (pp.FUSED_PREDICTION)
        return pp.fused_draw_prediction(views, pix, gains, weights, frames)
    return chunked_prediction(lambda lo, hi: fixed_prediction(views, pix[lo:hi], None, gains, weights, frames),
                              len(pix), DRAW_CHUNK)


def _fixed_views(ps: PlateSet, gains, needs, shape, y, x, med, est, bound, sigma):
    """fixed_draw's plates, one view at a time (a generator: the caller may crop each before the next);
    each also with the lines' uncertainty (H, W) float32 in its own exposure (0 where not estimated).
    The views are drawn side by side (capture.plate_threads; the same plates), a few ahead at most."""
    from capture.plate_draw import DRAW_FLAT, fixed_view_flat  # one flat index (the same plates)
    from capture.plate_threads import thread_map

    view = fixed_view_flat if DRAW_FLAT else _fixed_view
    return thread_map(lambda j: view(ps.views[j], gains[j], needs[j], shape, y, x, med, est, bound, sigma),
                      range(len(ps.views)))


def _fixed_view(p, gain, need, shape, y, x, med, est, bound, sigma):
    """One view's plate of :func:`_fixed_views`."""
    here = in_view(med, bound, gain)
    col = np.zeros(p.view.linear.shape, np.float32)
    col[y, x] = np.nan_to_num(here)
    known = np.zeros(shape, bool)
    known[y, x] = np.isfinite(here[:, 0])
    estimated = np.zeros(shape, bool)
    estimated[y, x] = est
    unc = np.zeros(shape, np.float32)
    unc[y, x] = np.where(est, sigma / float(np.mean(gain)), 0.0)
    return col, known & need, estimated & need, np.where(known & need, unc, 0.0)


def _sigma_scale(usable, samples, pal, med, opaque, covered, hot) -> float | None:
    """capture.plate_lines.held_back_scale at the fill's pixels (``usable``: the samples the robust
    mode could use, weight > 0; ``covered``, ``hot``: unseen_fill's at every pixel, not only the unknown)."""
    from capture.plate_lines import held_back_scale

    return held_back_scale(samples, pal, med, usable, opaque, covered, hot)


def _unseen_chunks(samples, pal, opaque, covered, hot, bound, sigma) -> np.ndarray:
    """capture.plate_lines.unseen_background of the pixels (columns) ``samples`` (K, N, 3), FILL_CHUNK
    pixels at a time, the chunks side by side (capture.plate_threads): each pixel's background is
    solved from its own samples and the palette alone, so the values are the same as one call's."""
    from capture.plate_lines import unseen_background
    from capture.plate_threads import chunks, thread_map

    out = np.full((samples.shape[1], 3), np.nan)

    def one(span):
        sl = slice(*span)
        out[sl] = unseen_background(samples[:, sl], pal, opaque[:, sl], covered[:, sl],
                                    None if hot is None else hot[:, sl], bound[sl], sigma[sl])

    for _ in thread_map(one, chunks(samples.shape[1], FILL_CHUNK)):
        pass
    return out


def _frames_at(views, y, x, fn) -> np.ndarray:
    """(K, N, ...) ``fn(prepared view)`` (an (H, W, ...) image or mask) at the pixels ``y``, ``x`` of each
    of ``views``, the views side by side (capture.plate_threads)."""
    from capture.plate_threads import thread_map

    return np.stack(list(thread_map(lambda p: fn(p)[y, x], views)))


def unseen_fill(ps: PlateSet, gains: np.ndarray, y: np.ndarray, x: np.ndarray, med: np.ndarray,
                bound: np.ndarray | None = None, sigma: np.ndarray | None = None) -> np.ndarray:
    """Fill ``med`` (N, 3) (the plate at pixels ``y``, ``x`` in the common exposure; NaN = unknown) in
    place where the frames' lines give the background (capture.plate_lines); (N,) bool where they did.
    ``bound`` (N,) bool, when given, is set in place where the fill is only a lower bound (a blown-out
    background; FIXED_CENSOR_CLIPPED: the samples blown out in their own frame say so).
    The lines take FIXED_RING_FRAMES frames at most (:func:`mode_frames`): every candidate vertex is
    scored against every frame, so the cost grows with the square of the frames.  ``sigma`` (N,), when
    given, is set in place to the fill's uncertainty (capture.plate_lines.vertex_sigma) where it filled."""
    from capture.matting import FG, depth_trimap
    from capture.matting_fast import channel_max
    from capture.matting_known import CLIP_LEVEL
    from capture.plate_fast import DRAW_IN_PLACE, scaled_samples, unseen_at  # the same values
    from capture.plate_lines import object_palette
    from capture.plate_threads import thread_map

    frames = mode_frames(len(ps.views), None, FIXED_RING_FRAMES)  # its cost grows with frames^2
    views = [ps.views[j] for j in frames]
    own = _frames_at(views, y, x, lambda p: p.view.linear)
    samples = scaled_samples(own, gains, frames, thread_map)  # capture.plate_fast (the same samples)
    opaque = _frames_at(views, y, x, lambda p: depth_trimap(p.view.object_depth) >= FG)
    pal = object_palette(samples, med, opaque)
    todo = ~np.isfinite(med[:, 0])
    est = np.zeros(len(y), bool)
    if not todo.any() or len(pal) == 0:
        return est
    # where the depth sees the object, and the blown-out samples, at every pixel once: the fill reads
    # them at the unknown pixels, the held-back check (_sigma_scale) at the known ones
    covered = _frames_at(views, y, x, lambda p: np.asarray(p.view.object_depth) > 0)
    hot = channel_max(own) >= CLIP_LEVEL if FIXED_CENSOR_CLIPPED else None  # own.max(axis=-1)
    hot_bound = np.zeros(int(todo.sum()), bool)
    unc = np.full(int(todo.sum()), np.nan)
    b = unseen_at(samples, np.flatnonzero(todo), pal, opaque, covered, hot, hot_bound, unc, FILL_CHUNK) \
        if DRAW_IN_PLACE else _unseen_chunks(samples[:, todo], pal, opaque[:, todo], covered[:, todo],
                                             None if hot is None else hot[:, todo], hot_bound, unc)
    filled = np.isfinite(b[:, 0])
    if sigma is not None:  # the lines' sigma held to their error where the robust mode knew the background
        usable = _frames_at(views, y, x, lambda p: p.weight > 0)
        scale = _sigma_scale(usable, samples, pal, med, opaque, covered, hot)
        sigma[np.flatnonzero(todo)[filled]] = unc[filled] * (np.inf if scale is None else scale)
    est[np.flatnonzero(todo)[filled]] = True
    med[est] = b[filled]
    if bound is not None:
        bound[np.flatnonzero(todo)[filled]] = hot_bound[filled]
    return est

"""A fixed camera's background where no frame saw it clean: solved from the frames' lines (issue 30).

On a turntable the trunk and the crown's core stand partly before the same screen pixels in every
frame, so the fixed-camera plate (``capture.plate_fixed``) finds no clean samples there and the
matte has to guess alpha without B: on the path-traced conifer those pixels were half the object
and 96 % of its colour error.  Yet the frames hold B: at a pixel p every frame sees
C_i = a_i F_i + (1 - a_i) B_p with the SAME B_p and a coverage a_i that changes as the object turns,
so the frames' colours lie on segments from B_p towards the object's colours.  B_p is the common
end of those segments (:func:`line_vertex`):

1. **Object colours.**  A palette (``capture.matting_known.palette``) of the frames' sure object
   colours: pixels of the depth's opaque core whose alpha bound against the known plate is at least
   ``matting_known.SOURCE_ALPHA``, and if those are too few pixels opaque in every frame
   (:func:`object_palette`).
2. **The vertex.**  Each frame's sample is a candidate for B_p; a candidate explains another sample
   when that sample lies near a segment from the candidate to a palette colour.  The candidate with
   the least summed (capped) squared distance wins: a sample part-covered by the object explains
   only the samples more covered than itself, the clean one explains all.  B_p is the
   median of the samples within LINE_AGREE of it.
3. **When it cannot beat doing nothing** the pixel stays unknown (the matte then estimates alpha
   without B, as before): the frames' lines disagree (RMS residual above LINE_MAX_RESIDUAL, e.g. a
   pixel before a moving shadow), fewer than LINE_MIN_FRAMES samples, all samples alike (nothing
   moved across the pixel: a core's edge covering it by the same part in every frame looks the
   same as a clean pixel next to it), too few sure object colours for a palette
   (LINE_MIN_SOURCES), or the vertex is the object's: every frame agreeing with it calls the pixel
   opaque in its depth, or it lies within LINE_MIN_SEPARATION of an object colour and every frame
   agreeing with it has object depth there (the trunk covers p in every frame).  A separation from
   the object colours alone rejected the shaded bricks behind the conifer's core, brown like a
   needle, and leaving those unknown cost more than the estimate.  Clipping (a channel at
   ``matting_known.CLIP_LEVEL``) bends the lines: where they disagree and at least LINE_MIN_HOT
   frames (LINE_HOT_SHARE of them) are blown out alike (their median is blown out too), B is that
   median; the matte treats a blown-out background as such (alpha from the Laplacian, the colour of the nearest exact
   pixels instead of one pulled towards the window).

The result is marked ``estimated`` in the plate's record (the share of the band it filled).
"""

from __future__ import annotations

import numpy as np

from capture.plate_reproject import nan_median

#: Samples this far (linear, Euclidean) from the nearest segment count as unexplained by a candidate
#: (the capped squared distance of step 2: one stray frame, a needle of a colour outside the palette,
#: costs no more than this).
LINE_CAP = 0.05
#: RMS over the frames of the winning candidate's (capped) distances above which the lines disagree
#: and B stays unknown (linear).  On the path-traced conifer turntable 0.01 separated the estimates
#: within 0.01 of the true background (median) from the blown-out ones; 0.02 leaves margin for noise.
LINE_MAX_RESIDUAL = 0.02
#: The median of the samples within this (linear, largest channel) of the winning candidate is B
#: (conifer turntable, estimated B against the truth: 0.02 median error 0.0084, 0.01 0.0064, 0.005
#: 0.0062, 0.04 0.0165: wider takes in partly covered frames).
LINE_AGREE = 0.01
#: Least blown-out samples for a blown-out background where the lines disagree (step 3; with 2,
#: 8 % of pixels of random colours passed) ...
LINE_MIN_HOT = 3
#: ... and at least this share of the pixel's frames (with 3 frames of 12, 4 % of pixels of random
#: colours passed; behind the conifer's crown 11 of 18 frames were blown out).
LINE_HOT_SHARE = 1 / 3
#: Least samples (frames) at a pixel for an estimate.
LINE_MIN_FRAMES = 3
#: A vertex this close to an object colour (linear, Euclidean) that agrees only with frames whose
#: depth sees the object at the pixel is the object (an opaque core before it in every frame).
LINE_MIN_SEPARATION = 0.05
#: Least sure object colours for the palette (step 1; as matting_known.MIN_SOURCES: the conifer
#: with table, auto exposure and lens found 20, and its held-out score gained 0.08 dB from the core's
#: colours added to them).
LINE_MIN_SOURCES = 50
#: Least uncertainty of a line vertex (linear, Euclidean; :func:`vertex_sigma`): the median of 8-bit
#: samples (one sRGB step at mid grey is about 0.004 linear per channel).
LINE_SIGMA_FLOOR = 0.004
#: Held-back check of the vertex's uncertainty (:func:`held_back_scale`): at most this many pixels whose
#: background the robust mode knew (evenly spaced), and at least LINE_CALIBRATE_MIN of them solved.
LINE_CALIBRATE_PIXELS = 3000
LINE_CALIBRATE_MIN = 200
#: Pixels per chunk (a K x K x chunk array per palette colour).
LINE_CHUNK = 4000
#: The samples' channel maxima (K x N x 3 -> K x N) by capture.matting_fast.channel_max (two elementwise
#: maxima; numpy's ``.max(-1)`` over three channels loops per pixel: 0.7 s of the 72 views' plate stage,
#: round 14), the same values; False: ``.max(-1)``, the reference.
LINES_CHANNEL_MAX = True


def _cmax(x: np.ndarray) -> np.ndarray:
    """``x.max(-1)`` (LINES_CHANNEL_MAX: capture.matting_fast.channel_max, the same values)."""
    from capture.matting_fast import channel_max

    return channel_max(x) if LINES_CHANNEL_MAX else x.max(-1)


def segment_distance(samples: np.ndarray, start: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """(K, N) distance of each sample (K, N, 3) to the nearest segment from ``start`` (N, 3) to one of
    ``ends`` (P, 3) (Euclidean, linear)."""
    best = np.full(samples.shape[:2], np.inf)
    v = samples - start[None]
    for p in ends:
        e = p[None] - start  # (N, 3)
        e2 = np.maximum((e * e).sum(-1), 1e-12).astype(e.dtype)
        t = np.clip((v * e[None]).sum(-1) / e2[None], 0.0, 1.0)
        best = np.minimum(best, np.linalg.norm(v - t[..., None] * e[None], axis=-1))
    return best


def _vertex_chunk(s: np.ndarray, pal: np.ndarray, fast: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """:func:`line_vertex` on one chunk (K, n, 3) without NaN checks beyond the samples' own; ``fast``:
    the winners from the compiled loop (capture.plate_lines_kernel), else from the numpy reference."""
    have = np.isfinite(s[..., 0])
    s0 = np.nan_to_num(s)
    best, cost = (_winners_compiled if fast else _winners_numpy)(s0, have, pal)
    cols = np.arange(s.shape[1])
    cand = s0[best, cols]
    agree = have & (_cmax(np.abs(s0 - cand[None])) <= LINE_AGREE)
    colour = nan_median(np.where(agree[..., None], s0, np.nan))
    residual = np.sqrt(cost / np.maximum(have.sum(0), 1))
    return colour, residual


def _winners_numpy(s0: np.ndarray, have: np.ndarray, pal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(winning candidate (n,), its cost (n,)) of step 2, every candidate's cost in numpy (the
    reference of capture.plate_lines_kernel): samples ``s0`` (K, n, 3) with NaN zeroed, ``have`` (K, n)."""
    K, n, _ = s0.shape
    cost = np.full((K, n), np.inf)
    for c in range(K):
        dist = np.minimum(segment_distance(s0, s0[c], pal), LINE_CAP)
        cost[c] = np.where(have[c], np.where(have, dist * dist, 0.0).sum(0), np.inf)
    best = np.argmin(cost, axis=0)
    return best, cost[best, np.arange(n)]


def _winners_compiled(s0: np.ndarray, have: np.ndarray, pal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_winners_numpy` from the compiled loop (capture.plate_lines_kernel.vertex_costs)."""
    from capture import plate_lines_simd as simd  # vectorised, the same winners (simd.LINES_SIMD)
    from capture.plate_lines_kernel import vertex_costs

    costs = simd.vertex_costs_simd if simd.LINES_SIMD else vertex_costs
    best, cost = costs(np.ascontiguousarray(s0, np.float32), np.ascontiguousarray(have),
                       np.ascontiguousarray(pal, np.float32), float(LINE_CAP))
    return np.maximum(best, 0), cost  # no sample at all: numpy's argmin of all-inf is 0


def line_vertex(samples: np.ndarray, pal: np.ndarray, fast: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """(B (N, 3), residual (N,)) of linear ``samples`` (K, N, 3) (frames x pixels, NaN = no sample)
    and the object colours ``pal`` (P, 3): per pixel the common end of the segments the samples lie
    on (module docstring, step 2), and the RMS of the samples' capped distances to its segments.
    Only the estimator; :func:`unseen_background` applies the checks of step 3.  Computed in
    float32 (float64 took 1.7x as long; colours are 8-bit to 16-bit data).  ``fast``: the compiled
    loop (capture.plate_lines_kernel), else the numpy reference (the same winners and costs)."""
    s = np.asarray(samples, np.float32)
    pal = np.asarray(pal, np.float32).reshape(-1, 3)
    N = s.shape[1]
    colour = np.full((N, 3), np.nan)
    residual = np.full(N, np.inf)
    if len(pal) == 0:
        return colour, residual
    from capture.plate_threads import chunks, thread_map  # chunks side by side (the same values)

    def one(span):
        lo, hi = span
        colour[lo:hi], residual[lo:hi] = _vertex_chunk(s[:, lo:hi], pal, fast)

    for _ in thread_map(one, chunks(N, LINE_CHUNK)):
        pass
    return colour, residual


def unseen_background(samples: np.ndarray, pal: np.ndarray, opaque: np.ndarray | None = None,
                      covered: np.ndarray | None = None, hot: np.ndarray | None = None,
                      bound: np.ndarray | None = None, sigma: np.ndarray | None = None) -> np.ndarray:
    """(N, 3) linear background of each pixel whose ``samples`` (K, N, 3) (NaN = none) lie on
    segments towards the object colours ``pal`` (P, 3); ``opaque`` (K, N) bool: where the frame's
    depth calls the pixel opaque (its trimap's sure object), ``covered``: where the depth sees the
    object there at all (None: nowhere).  NaN where the estimate cannot beat doing nothing (module
    docstring, step 3).  ``hot`` (K, N) bool: the samples blown out in their own frame; given, they
    are lower bounds, not points of the lines (:func:`_censored_background`), and ``bound`` (N,) bool,
    when given, is set where the result is only such a bound.  None: one exposure, the samples at
    CLIP_LEVEL here are the blown-out ones (as before auto exposure was told apart).  ``sigma`` (N,)
    float, when given, is set to each result's uncertainty (:func:`vertex_sigma`; inf where the
    result is a blown-out median or bound, NaN where there is none)."""
    from capture.matting_known import CLIP_LEVEL

    s = np.asarray(samples, np.float64)
    pal = np.asarray(pal, np.float64).reshape(-1, 3)
    out = np.full((s.shape[1], 3), np.nan)
    if bound is not None:
        bound[:] = False
    if sigma is not None:
        sigma[:] = np.nan
    if len(pal) == 0 or s.shape[1] == 0:
        return out
    if hot is not None:
        return _censored_background(s, pal, opaque, covered, np.asarray(hot, bool), bound, sigma)
    B, res = line_vertex(s, pal)
    have = np.isfinite(s[..., 0])
    enough, agree, seen = _evidence(s, B, pal, opaque, covered)
    # clipping bends the lines: where they disagree and a frame is blown out, the background is
    # (the median of) the blown-out samples, which the matte treats as such
    hot = have & (_cmax(np.nan_to_num(s)) >= CLIP_LEVEL)
    bent = (res > LINE_MAX_RESIDUAL) & (hot.sum(0) >= np.maximum(LINE_MIN_HOT, LINE_HOT_SHARE * have.sum(0)))
    if bent.any():  # ... when the blown-out samples' median is blown out too (they clip alike)
        B[bent] = nan_median(np.where(hot[:, bent, None], s[:, bent], np.nan))
        bent &= B.max(-1) >= CLIP_LEVEL
    moved = (have & ~agree).any(0)  # a frame unlike the vertex: else no evidence of what lies behind
    ok = enough & moved & (seen | bent) & ((res <= LINE_MAX_RESIDUAL) | bent)
    out[ok] = B[ok]
    if sigma is not None:
        sigma[ok] = np.where(bent[ok], np.inf, vertex_sigma(res[ok]))
    return out


def vertex_sigma(residual: np.ndarray) -> np.ndarray:
    """(N,) uncertainty of a line vertex (linear, Euclidean over the channels): its RMS residual
    (:func:`line_vertex`; a vertex off the true background by d leaves the partly covered samples
    about d from its segments), at least LINE_SIGMA_FLOOR."""
    return np.maximum(np.asarray(residual, np.float64), LINE_SIGMA_FLOOR)


def _evidence(s, B, pal, opaque, covered):
    """(enough frames (N,), samples agreeing with the vertex (K, N), vertex seen as background (N,))
    of step 3 for samples ``s`` (K, N, 3) and vertices ``B`` (N, 3)."""
    have = np.isfinite(s[..., 0])
    enough = have.sum(0) >= LINE_MIN_FRAMES
    agree = have & (_cmax(np.abs(np.nan_to_num(s) - B[None])) <= LINE_AGREE)
    seen = agree.any(0) if opaque is None else (agree & ~np.asarray(opaque, bool)).any(0)
    if covered is not None:  # an object colour seen only where the depth saw the object: the object
        apart = np.linalg.norm(B[:, None] - pal[None], axis=-1).min(-1) >= LINE_MIN_SEPARATION
        seen &= apart | (agree & ~np.asarray(covered, bool)).any(0)
    return enough, agree, seen


def _censored_background(s, pal, opaque, covered, hot, bound, sigma=None) -> np.ndarray:
    """:func:`unseen_background` with the samples blown out in their own frame (``hot``) as lower
    bounds (auto exposure: 1.0 x gain differs from frame to frame in the common exposure): the vertex
    of the other samples' lines, refused where it is darker than a blown-out sample by more than
    LINE_AGREE in a channel (the sensor stopped at or below the background); where the lines
    disagree, are too few or are so refused, and at least LINE_MIN_HOT samples (LINE_HOT_SHARE of
    them) are blown out, the largest blown-out sample, a bound (``bound``)."""
    have_all = np.isfinite(s[..., 0])
    hot = hot & have_all
    free = np.where(hot[..., None], np.nan, s)
    B, res = line_vertex(free, pal)
    have = np.isfinite(free[..., 0])
    enough, agree, seen = _evidence(free, B, pal, opaque, covered)
    lb = np.where(hot[..., None], s, -np.inf).max(axis=0)
    darker = (np.nan_to_num(B, nan=-np.inf) < lb - LINE_AGREE).any(-1)
    moved = (have & ~agree).any(0)
    vertex = enough & moved & seen & (res <= LINE_MAX_RESIDUAL) & ~darker
    bent = ~vertex & (hot.sum(0) >= np.maximum(LINE_MIN_HOT, LINE_HOT_SHARE * have_all.sum(0)))
    out = np.full((s.shape[1], 3), np.nan)
    out[vertex] = B[vertex]
    out[bent] = lb[bent]
    if bound is not None:
        bound[:] = bent
    if sigma is not None:
        sigma[vertex] = vertex_sigma(res[vertex])
        sigma[bent] = np.inf
    return out


def object_palette(samples: np.ndarray, plate: np.ndarray, opaque: np.ndarray) -> np.ndarray:
    """(P, 3) palette of the frames' sure object colours (module docstring, step 1) from the frames'
    linear samples (K, N, 3) of N pixels in one exposure, the plate there (N, 3; NaN = not known)
    and where the depth calls them opaque (K, N) bool: where the plate is known, the opaque samples
    whose alpha bound is at least SOURCE_ALPHA; with fewer than LINE_MIN_SOURCES of those, also the
    pixels opaque in every frame where it is not (an opaque core that never moves off them).
    (0, 3) with fewer than LINE_MIN_SOURCES in all."""
    from capture.matting_known import SOURCE_ALPHA, alpha_lower_bound, palette

    s = np.asarray(samples)  # the samples picked go to float64 (exact), not all of them (K x N x 3)
    b = np.asarray(plate, np.float64)
    opaque = np.asarray(opaque, bool) & np.isfinite(s[..., 0])
    known = np.isfinite(b[:, 0])
    kk, nn = np.nonzero(opaque & known[None])
    picked = s[kk, nn].astype(np.float64)
    src = [picked[alpha_lower_bound(picked, b[nn]) >= SOURCE_ALPHA]] if len(kk) else []
    src = np.concatenate(src) if src else np.zeros((0, 3))
    if len(src) < LINE_MIN_SOURCES:  # the core's colours mixed into a full palette cost the conifer 0.19 dB
        src = np.concatenate([src, s[:, opaque.all(0) & ~known].reshape(-1, 3).astype(np.float64)])
    return palette(src) if len(src) >= LINE_MIN_SOURCES else np.zeros((0, 3))


def held_back_scale(samples: np.ndarray, pal: np.ndarray, truth: np.ndarray, usable: np.ndarray,
                    opaque: np.ndarray | None = None, covered: np.ndarray | None = None,
                    hot: np.ndarray | None = None) -> float | None:
    """How far the lines' error exceeds their :func:`vertex_sigma`, measured where it is known: at
    pixels whose background ``truth`` (N, 3; NaN = not known) the robust mode took from the samples
    ``usable`` (K, N) bool, those samples are hidden and the rest (each pixel then looks like one no
    frame saw clean) solved by :func:`unseen_background` (``opaque``, ``covered``, ``hot`` as there);
    the RMS of the (Euclidean) errors over the RMS of their sigma.  At most LINE_CALIBRATE_PIXELS
    pixels (evenly spaced); None with fewer than LINE_CALIBRATE_MIN solved (the uncertainty is then
    not known)."""
    from capture.matting_known import CLIP_LEVEL

    s = np.asarray(samples)  # the candidates' samples go to float64 (exact), not every pixel's
    t = np.asarray(truth, np.float64)
    usable = np.asarray(usable, bool)
    rest = np.isfinite(s[..., 0]) & ~usable
    cand = np.flatnonzero(np.isfinite(t[:, 0]) & (np.nan_to_num(t).max(-1) < CLIP_LEVEL) & usable.any(0)
                          & (rest.sum(0) >= LINE_MIN_FRAMES))
    if len(cand) < LINE_CALIBRATE_MIN:
        return None
    cand = cand[np.unique(np.linspace(0, len(cand) - 1, min(len(cand), LINE_CALIBRATE_PIXELS)).astype(int))]
    pick = (lambda m: None if m is None else np.asarray(m, bool)[:, cand])
    sig = np.full(len(cand), np.nan)
    hid = np.where(rest[:, cand, None], s[:, cand].astype(np.float64), np.nan)
    b = unseen_background(hid, pal, pick(opaque), pick(covered), pick(hot), None, sig)
    ok = np.isfinite(b[:, 0]) & np.isfinite(sig)
    if ok.sum() < LINE_CALIBRATE_MIN:
        return None
    err2 = ((b[ok] - t[cand][ok]) ** 2).sum(-1)
    return float(np.sqrt(err2.mean() / np.mean(sig[ok] ** 2)))

"""The background behind the object in every view (a clean plate), from the capture itself (issue 30).

A partial pixel of a needle or a strand is C = a F + (1 - a) B: without B, even the true alpha leaves
the room in F (PITFALLS: 19.4 dB held out with the true matte against 24.3 over black).  The capture
holds B: what one view's object hides, other views see beside it.  :func:`background_plates` gives
every view a plate (B per pixel where known) by the first path that applies (``PlateConfig.mode``
``auto``, or one forced):

1. ``user``: plates the user shot (``furrow model --background-plates DIR``: the same path without
   the object, or a fixed camera; ``capture.plate_io``), one per view.
2. ``fixed``: the camera stood still while the object turned (a turntable shot): the background is
   the same image in every frame; each pixel's plate is the median of the frames in which it is
   confidently background (:func:`fixed_plates`).
3. ``panorama``: the camera moved (an orbit, a phone): the background is looked up in the other
   views along each pixel's ray, with the support plane and the room's depth for parallax and a
   point at infinity for a far environment (``capture.plate_reproject``).

``auto`` takes user plates when given, else tells ``fixed`` from ``panorama`` from the data: both
predict a sample of every view's background pixels near the object from the other views, and the
one with the smaller error wins (:func:`choose_mode`); nobody is asked whether the camera moved.

"Confidently background" (``source`` mask) is outside the object's depth (after the extent stage)
dilated by ``SOURCE_BAND_FRACTION`` of the width, twice the matting band.  Each view's exposure
gain (auto exposure, white balance: colour = true colour / g) is fitted on those pixels
(:func:`fit_gains`) so that one view's plate is drawn in its own exposure.

Every view's record says what share of its matting band got a known background and the plate's
error on background pixels it was not built from (a ring of the view's own background pixels just
outside the band, predicted from the other views only: leave one out).  Where no view saw the
background, the plate is unknown and the matte falls back to the estimate without it.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from capture.camera import Camera
from capture.matting import UNKNOWN, depth_trimap
from capture.matting_known import WIDEN_FRACTION
from capture.plate_reproject import PlateSource, reproject_plate, room_depth

#: Plate modes of PlateConfig.mode / ``furrow model --plate``.
PLATE_MODES = ("auto", "user", "fixed", "panorama", "off")
#: Confidently background: outside the object's depth dilated by this fraction of the width (8 px at 640).
SOURCE_BAND_FRACTION = 8 / 640
#: The held-back ring for the plate's error: background pixels this fraction of the width beyond the source band.
RING_FRACTION = 6 / 640
#: Most ring pixels per view used for errors and for telling the modes apart (an even subsample).
RING_SAMPLES = 4000
#: Views consulted per view (moving camera): the nearest by optical axis.
NEIGHBOURS = 8
#: Fixed camera: a pixel's plate needs this many frames that agree on its colour (robust_mode).
FIXED_MIN_FRAMES = 3
#: Fixed camera: pixels (on a regular grid) used for the first exposure gains.
FIXED_GAIN_PIXELS = 20000
#: Fixed camera: a frame lends samples where it has no object depth within this fraction of the width (2 px at 640).
FIXED_EXCLUDE_FRACTION = 2 / 640
#: Robust mode: samples within this (8-bit sRGB, largest channel) of each other agree; pixels per chunk.
MODE_TOL = 3.0 / 255
#: Robust mode: a rival cluster (no sample in common) weighing this fraction of the heaviest one makes
#: the pixel unknown.
MODE_AMBIGUOUS = 0.5
MODE_CHUNK = 20000
#: Gain fit: colours below this (linear, any channel) or above GAIN_BRIGHT are not used (quantisation, clipping).
GAIN_DARK = 0.01
GAIN_BRIGHT = 0.95
#: Gain fit: passes (predict, fit; the last prediction uses the last fit).
GAIN_PASSES = 2
#: A background depth point higher than this above the support plane is the room, not the support (metres).
PLANE_OFF_METRES = 0.02
#: Gain fit: least samples for a view's gain; fewer keeps gain 1.
GAIN_MIN_SAMPLES = 200
#: Noise passed to the matte: this multiple of the view's median held-back plate error ...
NOISE_PER_ERROR = 1.5
#: ... at least one 8-bit sRGB step at black (linear) and at most NOISE_MAX.
NOISE_MIN = 1.0 / 255 / 12.92
NOISE_MAX = 0.05


@dataclass(frozen=True)
class PlateConfig:
    """Settings of :func:`background_plates`."""

    #: One of PLATE_MODES (module docstring); 'off' = no plate (the matte is estimated without one).
    mode: str = "auto"
    #: Views consulted per view when the camera moves (the nearest by optical axis).
    neighbours: int = NEIGHBOURS

    def __post_init__(self) -> None:
        if self.mode not in PLATE_MODES:
            raise ValueError(f"plate mode must be one of {', '.join(PLATE_MODES)}, got {self.mode!r}")
        if int(self.neighbours) < 1:
            raise ValueError(f"plate neighbours must be >= 1, got {self.neighbours}")


@dataclass(frozen=True)
class Plate:
    """One view's background plate.

    Attributes:
        background: (H, W, 3) float32 linear colour of the background in the view's own exposure
            (0 where not known).
        known: (H, W) bool, where the background is known.
        noise: linear noise of C - B to allow in the matte (from the held-back error).
        method: 'user', 'fixed', 'panorama' or 'none'.
        band_known: fraction of the view's matting band (trimap unknown) with a known background.
        error: median over held-back background pixels of the largest channel's |plate - colour| (linear;
            NaN without any).
        error_rmse: RMS over those pixels and channels (linear; NaN without any).
    """

    background: np.ndarray
    known: np.ndarray
    noise: float
    method: str
    band_known: float
    error: float
    error_rmse: float

    def record(self) -> dict:
        """JSON-able summary of the view's plate (model.json, the stage table)."""
        return {"method": self.method, "band_known": round(self.band_known, 4),
                "error": None if not np.isfinite(self.error) else round(self.error, 5),
                "error_rmse": None if not np.isfinite(self.error_rmse) else round(self.error_rmse, 5),
                "noise": round(self.noise, 5)}


@dataclass(frozen=True)
class PlateView:
    """One view as the plate stage reads it.

    Attributes:
        camera: its camera.
        linear: (H, W, 3) float32 linear colour.
        object_depth: (H, W) float32 the object's depth (after the extent stage; 0 = not the object).
        depth: (H, W) float32 the capture's depth (before the extent stage: the support, walls too).
    """

    camera: Camera
    linear: np.ndarray
    object_depth: np.ndarray
    depth: np.ndarray


def _px(frac: float, width: int) -> int:
    return max(1, int(round(frac * width)))


def source_mask(object_depth: np.ndarray) -> np.ndarray:
    """(H, W) bool confidently background: outside the object's depth dilated by SOURCE_BAND_FRACTION."""
    m = np.asarray(object_depth) > 0
    return ~ndimage.binary_dilation(m, iterations=_px(SOURCE_BAND_FRACTION, m.shape[1]))


def need_mask(object_depth: np.ndarray) -> np.ndarray:
    """(H, W) bool pixels whose background the matte may ask for: the trimap's band and opaque
    pixels, widened as capture.matting_known widens it."""
    tri = depth_trimap(object_depth)
    return ndimage.binary_dilation(tri > 0, iterations=_px(WIDEN_FRACTION, tri.shape[1]))


def ring_pixels(object_depth: np.ndarray) -> np.ndarray:
    """(N, 2) int (x, y) of the held-back ring: source pixels within RING_FRACTION of the source
    band's edge, at most RING_SAMPLES (evenly)."""
    src = source_mask(object_depth)
    near = ndimage.binary_dilation(~src, iterations=_px(RING_FRACTION, src.shape[1]))
    y, x = np.nonzero(src & near)
    if len(y) > RING_SAMPLES:
        k = np.linspace(0, len(y) - 1, RING_SAMPLES).round().astype(np.int64)
        y, x = y[k], x[k]
    return np.stack([x, y], axis=1)


def _usable(c: np.ndarray) -> np.ndarray:
    return np.all((c > GAIN_DARK) & (c < GAIN_BRIGHT), axis=-1)


def fit_gains(observed: list[np.ndarray], predicted: list[np.ndarray], prior: np.ndarray | None = None) -> np.ndarray:
    """(V, 3) exposure gains g (true colour = colour x g, median view 1 per channel) from each view's
    observed background colours (N_i, 3) and the same pixels predicted from the other views in
    the common exposure (N_i, 3), NaN rows = no prediction: g_i = median(predicted / observed).
    Views with under GAIN_MIN_SAMPLES usable pairs keep their ``prior`` gain (default 1)."""
    V = len(observed)
    logg = np.zeros((V, 3)) if prior is None else np.log(np.asarray(prior, np.float64))
    for i, (o, p) in enumerate(zip(observed, predicted, strict=True)):
        ok = np.isfinite(p).all(axis=1) & _usable(o) & _usable(np.nan_to_num(p))
        if ok.sum() >= GAIN_MIN_SAMPLES:
            logg[i] = np.median(np.log(p[ok]) - np.log(o[ok]), axis=0)
    logg -= np.median(logg, axis=0)
    return np.exp(logg)


def robust_mode(samples: np.ndarray, weights: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(colour (N, 3), support (N,) int) of samples (K, N, 3) linear (NaN = none) per column: the
    heaviest cluster (the sample whose agreeing samples, within MODE_TOL in 8-bit sRGB, weigh most;
    ``weights`` (K, N), default 1), then the median of those; support = how many agree.  A needle
    crossing a background pixel in some frames leaves samples spread between B and F; the frames
    it missed agree to the noise, and they were further from the object (heavier)."""
    from capture.scan import linear_to_srgb

    K, N, _ = samples.shape
    colour = np.full((N, 3), np.nan, np.float32)
    support = np.zeros(N, np.int64)
    for lo in range(0, N, MODE_CHUNK):
        s = samples[:, lo:lo + MODE_CHUNK].astype(np.float32)
        have = np.isfinite(s[..., 0])
        w = have.astype(np.float32) if weights is None else np.where(have, weights[:, lo:lo + MODE_CHUNK], 0.0)
        e = linear_to_srgb(np.nan_to_num(s))
        close = (np.abs(e[:, None] - e[None]).max(axis=-1) <= MODE_TOL) & have[:, None] & have[None]
        score = (close * w[None]).sum(axis=1)  # (K, n): weight of the samples agreeing with each
        best = np.argmax(score, axis=0)  # (n,): the heaviest cluster's centre
        cols = np.arange(s.shape[1])
        members = close[best, :, cols].T  # (K, n): samples close to it
        # a rival cluster apart from it nearly as heavy: the pixel is ambiguous (a needle that stayed put)
        outside = ~members
        rival = np.where(outside, ((close & outside[None]) * w[None]).sum(axis=1), 0.0).max(axis=0)
        members &= (rival < MODE_AMBIGUOUS * score[best, cols])[None]
        with warnings.catch_warnings():  # all-NaN columns: no sample there
            warnings.simplefilter("ignore", RuntimeWarning)
            colour[lo:lo + MODE_CHUNK] = np.nanmedian(np.where(members[..., None], s, np.nan), axis=0)
        support[lo:lo + MODE_CHUNK] = members.sum(axis=0)
    return colour, support


def fixed_sample_weight(object_depth: np.ndarray) -> np.ndarray:
    """(H, W) float32 weight of a frame's pixels as fixed-camera plate samples: 0 within
    FIXED_EXCLUDE_FRACTION of the width of the object's depth (the robust mode takes out needles
    the depth missed), rising to 1 at SOURCE_BAND_FRACTION (confidently background)."""
    m = np.asarray(object_depth) > 0
    W = m.shape[1]
    if not m.any():
        return np.ones(m.shape, np.float32)
    d = ndimage.distance_transform_edt(~m)
    w = np.clip(d / _px(SOURCE_BAND_FRACTION, W), 0.0, 1.0)
    return np.where(d > _px(FIXED_EXCLUDE_FRACTION, W), w, 0.0).astype(np.float32)


def fixed_prediction(views: list[PlateView], pix: np.ndarray, i: int | None, gains: np.ndarray,
                     weights: list[np.ndarray] | None = None) -> np.ndarray:
    """(N, 3) fixed-camera plate at pixels ``pix`` (N, 2) from every frame but ``i`` (None: all), in
    the common exposure (colour x gain): the robust mode (:func:`robust_mode`) of the frames' samples
    weighted by ``weights`` (default :func:`fixed_sample_weight`); NaN where fewer than
    FIXED_MIN_FRAMES agree."""
    x, y = pix[:, 0], pix[:, 1]
    s = np.full((len(views), len(pix), 3), np.nan, np.float32)
    w = np.zeros((len(views), len(pix)), np.float32)
    for j, v in enumerate(views):
        if j == i:
            continue
        w[j] = (fixed_sample_weight(v.object_depth) if weights is None else weights[j])[y, x]
        ok = w[j] > 0
        s[j, ok] = v.linear[y[ok], x[ok]] * gains[j]
    col, support = robust_mode(s, w)
    col[support < FIXED_MIN_FRAMES] = np.nan
    return col


def fixed_gains(views: list[PlateView], weights: list[np.ndarray]) -> np.ndarray:
    """(V, 3) exposure gains of a fixed camera's frames (true colour = colour x gain) from about
    FIXED_GAIN_PIXELS pixels (a regular grid) that all frames may lend: each frame against the
    per-pixel median of the frames (GAIN_PASSES times, the median taken over the gain-corrected frames)."""
    H, W = weights[0].shape
    k = max(1, int(np.sqrt(H * W / FIXED_GAIN_PIXELS)))
    common = np.logical_and.reduce([w >= 1 for w in weights])[::k, ::k]
    obs = [v.linear[::k, ::k][common].astype(np.float64) for v in views]
    gains = np.ones((len(views), 3))
    if not common.any():
        return gains
    for _ in range(GAIN_PASSES):
        med = np.median(np.stack([o * g for o, g in zip(obs, gains, strict=True)]), axis=0)
        gains = fit_gains(obs, [med] * len(obs))
    return gains


def fixed_plates(views: list[PlateView], needs: list[np.ndarray], gains: np.ndarray) -> list[tuple]:
    """Per view (colour (H, W, 3) in its own exposure, known (H, W)) of the fixed-camera plate on
    the union of the views' ``needs`` (module docstring)."""
    union = np.logical_or.reduce(needs)
    y, x = np.nonzero(union)
    weights = [fixed_sample_weight(v.object_depth) for v in views]
    med = fixed_prediction(views, np.stack([x, y], axis=1), None, gains, weights)
    out = []
    for j, v in enumerate(views):
        col = np.zeros(v.linear.shape, np.float32)
        col[y, x] = np.nan_to_num(med / gains[j])
        known = np.zeros(union.shape, bool)
        known[y, x] = np.isfinite(med[:, 0])
        out.append((col, known & needs[j]))
    return out


def neighbour_order(cams: list[Camera], i: int, k: int) -> list[int]:
    """Indices of the ``k`` cameras other than ``i`` nearest to it by optical axis."""
    f = np.array([c.forward for c in cams])
    ang = np.arccos(np.clip(f @ f[i], -1, 1))
    ang[i] = np.inf
    return [int(j) for j in np.argsort(ang)[:k] if np.isfinite(ang[j])]


def _sources(views: list[PlateView], gains: np.ndarray, focus: tuple[np.ndarray, float]) -> list[PlateSource]:
    center, radius = focus
    out = []
    for j, v in enumerate(views):
        bgd = np.where(np.asarray(v.object_depth) > 0, 0.0, v.depth).astype(np.float32)
        far = float(v.camera.world_to_cam(center)[2] + radius)
        out.append(PlateSource(v.camera, v.linear, source_mask(v.object_depth), bgd, gains[j], far))
    return out


def _room(v: PlateView, plane: np.ndarray | None) -> np.ndarray | None:
    """The view's room depth under the object (capture.plate_reproject.room_depth)."""
    bgd = np.where(np.asarray(v.object_depth) > 0, 0.0, v.depth)
    pts, m = v.camera.depth_to_points(bgd)
    off = np.zeros(bgd.shape, bool)
    if len(pts):
        off[m] = True if plane is None else (pts @ plane[:3] + plane[3]) > PLANE_OFF_METRES
    src = source_mask(v.object_depth)
    ring = src & ndimage.binary_dilation(~src, iterations=_px(RING_FRACTION, src.shape[1]))
    return room_depth(bgd, ring, off)


def panorama_prediction(views: list[PlateView], i: int, pix: np.ndarray, sources: list[PlateSource],
                        plane: np.ndarray | None, k: int) -> tuple[np.ndarray, np.ndarray]:
    """(colour (N, 3) in view i's exposure with NaN where unknown, samples (N,)) behind pixels
    ``pix`` of view i from its ``k`` nearest other views."""
    cams = [v.camera for v in views]
    nb = [sources[j] for j in neighbour_order(cams, i, k)]
    col, known, count = reproject_plate(cams[i], pix, sources[i].gain, nb, plane, _room(views[i], plane))
    col = col.astype(np.float32)
    col[~known] = np.nan
    return col, count


def _error(observed: np.ndarray, predicted: np.ndarray) -> tuple[float, float]:
    """(median of the largest channel's |error|, RMS) over the predicted rows (NaN: none)."""
    ok = np.isfinite(predicted).all(axis=1)
    if not ok.any():
        return float("nan"), float("nan")
    d = np.abs(predicted[ok] - observed[ok])
    return float(np.median(d.max(axis=1))), float(np.sqrt(np.mean(d * d)))


def ring_errors(views: list[PlateView], rings: list[np.ndarray], mode: str, cfg: PlateConfig,
                plane, focus) -> tuple[np.ndarray, list[tuple[float, float]]]:
    """(gains (V, 3), per view (median error, RMS) of its held-back ring) for ``mode`` 'fixed' or
    'panorama': predictions from the other views with unit gains, the gains fitted to them, the
    predictions again with the gains."""
    V = len(views)
    gains = np.ones((V, 3))
    obs = [v.linear[r[:, 1], r[:, 0]].astype(np.float64) for v, r in zip(views, rings, strict=True)]
    weights = [fixed_sample_weight(v.object_depth) for v in views] if mode == "fixed" else None
    if mode == "fixed":
        gains = fixed_gains(views, weights)
    for step in range(1 + GAIN_PASSES):
        if mode == "fixed":
            pred = [fixed_prediction(views, r, i, gains, weights) / gains[i] for i, r in enumerate(rings)]
        else:
            src = _sources(views, gains, focus)
            pred = [panorama_prediction(views, i, r, src, plane, cfg.neighbours)[0] for i, r in enumerate(rings)]
        if step < GAIN_PASSES:
            gains = fit_gains(obs, [p * gains[i] for i, p in enumerate(pred)], gains)
    return gains, [_error(o, p) for o, p in zip(obs, pred, strict=True)]


def choose_mode(errors: dict) -> str:
    """The plate mode ('fixed' / 'panorama') whose held-back error (median over views) is smaller."""
    score = {m: np.nanmedian([e[0] for e in errs]) if np.isfinite([e[0] for e in errs]).any() else np.inf
             for m, errs in errors.items()}
    return min(score, key=lambda m: score[m])


def user_gains(views: list[PlateView], user: list[np.ndarray]) -> np.ndarray:
    """(V, 3) gain of each view relative to its user plate (the plate's exposure: gain 1), fitted on
    the view's confidently background pixels."""
    g = np.ones((len(views), 3))
    for i, (v, u) in enumerate(zip(views, user, strict=True)):
        m = source_mask(v.object_depth)
        o = v.linear[m].astype(np.float64)
        p = np.asarray(u, np.float64)[m]
        ok = _usable(o) & _usable(p)
        if ok.sum() >= GAIN_MIN_SAMPLES:
            g[i] = np.exp(np.median(np.log(p[ok]) - np.log(o[ok]), axis=0))
    return g


def _plate(v: PlateView, col: np.ndarray, known: np.ndarray, err: tuple[float, float], method: str) -> Plate:
    band = depth_trimap(v.object_depth) == UNKNOWN
    noise = float(np.clip(NOISE_PER_ERROR * err[0], NOISE_MIN, NOISE_MAX)) if np.isfinite(err[0]) else NOISE_MAX
    return Plate(col.astype(np.float32), known, noise, method, float(known[band].mean()) if band.any() else 0.0,
                 err[0], err[1])


def _panorama_plate(views, i, need, sources, plane, cfg) -> tuple[np.ndarray, np.ndarray]:
    y, x = np.nonzero(need)
    col, _ = panorama_prediction(views, i, np.stack([x, y], axis=1), sources, plane, cfg.neighbours)
    out = np.zeros(views[i].linear.shape, np.float32)
    known = np.zeros(need.shape, bool)
    ok = np.isfinite(col[:, 0])
    out[y[ok], x[ok]] = col[ok]
    known[y[ok], x[ok]] = True
    return out, known


def background_plates(views: list[PlateView], cfg: PlateConfig | None = None, plane: np.ndarray | None = None,
                      focus: tuple[np.ndarray, float] | None = None,
                      user: list[np.ndarray] | None = None) -> tuple[list[Plate | None], dict]:
    """(per view its Plate, or None for mode 'off'; record for model.json / the console) (module
    docstring).  ``plane``: the support plane (capture.extent, (4,) or None); ``focus``: (centre,
    radius) of the region the rig looks at (default capture.extent.focus_region); ``user``: per
    view a (H, W, 3) linear plate the user shot (capture.plate_io)."""
    from capture.extent import focus_region

    cfg = cfg or PlateConfig()
    if cfg.mode == "off":
        return [None] * len(views), {"mode": "off"}
    if cfg.mode == "user" and user is None:
        raise ValueError("--plate user needs --background-plates DIR")
    focus = focus or focus_region([v.camera for v in views])
    rings = [ring_pixels(v.object_depth) for v in views]
    needs = [need_mask(v.object_depth) for v in views]
    errors, gains = {}, {}
    if user is not None and cfg.mode in ("auto", "user"):
        mode = "user"
        g = user_gains(views, user)
        errs = [_error(v.linear[r[:, 1], r[:, 0]].astype(np.float64), np.asarray(u)[r[:, 1], r[:, 0]] / g[i])
                for i, (v, r, u) in enumerate(zip(views, rings, user, strict=True))]
        plates = [_plate(v, np.asarray(u, np.float32) / g[i], np.ones(needs[i].shape, bool), errs[i], "user")
                  for i, (v, u) in enumerate(zip(views, user, strict=True))]
        return plates, _record(mode, plates, g, {})
    for m in (("fixed", "panorama") if cfg.mode == "auto" else (cfg.mode,)):
        gains[m], errors[m] = ring_errors(views, rings, m, cfg, plane, focus)
    mode = choose_mode(errors)
    g = gains[mode]
    if mode == "fixed":
        made = fixed_plates(views, needs, g)
    else:
        src = _sources(views, g, focus)
        made = [_panorama_plate(views, i, needs[i], src, plane, cfg) for i in range(len(views))]
    plates = [_plate(v, c, k, errors[mode][i], mode) for i, (v, (c, k)) in enumerate(zip(views, made, strict=True))]
    return plates, _record(mode, plates, g, {m: _summary(e) for m, e in errors.items()})


def _summary(errs) -> float | None:
    e = [x[0] for x in errs if np.isfinite(x[0])]
    return round(float(np.median(e)), 5) if e else None


def _record(mode: str, plates: list[Plate], gains: np.ndarray, tried: dict) -> dict:
    band = [p.band_known for p in plates]
    return {"mode": mode, "tried_error": tried,
            "band_known_mean": round(float(np.mean(band)), 4), "band_known_min": round(float(np.min(band)), 4),
            "error_median": _summary([(p.error, p.error_rmse) for p in plates]),
            "gains_ev": [[round(float(x), 3) for x in np.log2(g)] for g in gains],
            "per_view": [p.record() for p in plates]}

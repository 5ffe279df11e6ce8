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
    """Settings of :func:`background_plates` (the pipeline's background plate stage)."""

    #: One of PLATE_MODES (module docstring); 'off' = no plate (the matte is estimated without one).
    mode: str = "auto"
    #: Views consulted per view when the camera moves (the nearest by optical axis).
    neighbours: int = NEIGHBOURS
    #: Folder of plates the user shot (``--background-plates``; capture.plate_io), or None.
    plates_dir: str | None = None

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
        frame: None for a full-frame plate; (H, W, y0, x0) for a plate cropped to its known box
            (:meth:`cropped`): ``background`` and ``known`` are then the box at (y0, x0).
    """

    background: np.ndarray
    known: np.ndarray
    noise: float
    method: str
    band_known: float
    error: float
    error_rmse: float
    frame: tuple | None = None

    def cropped(self) -> Plate:
        """The plate on the box around its known pixels, colour as float16 (what waits for the matte
        stage); :meth:`full` gives it back at its (H, W)."""
        rows, cols = np.flatnonzero(self.known.any(axis=1)), np.flatnonzero(self.known.any(axis=0))
        H, W = self.known.shape
        if not len(rows):
            box = (0, 0, 0, 0)
        else:
            box = (int(rows[0]), int(cols[0]), int(rows[-1]) + 1, int(cols[-1]) + 1)
        sl = (slice(box[0], box[2]), slice(box[1], box[3]))
        return Plate(self.background[sl].astype(np.float16), self.known[sl].copy(), self.noise, self.method,
                     self.band_known, self.error, self.error_rmse, (H, W, box[0], box[1]))

    def full(self) -> Plate:
        """The plate at its image's full (H, W) (itself when not cropped)."""
        if self.frame is None:
            return self
        H, W, y0, x0 = self.frame
        bg = np.zeros((H, W, 3), np.float32)
        known = np.zeros((H, W), bool)
        h, w = self.known.shape
        bg[y0:y0 + h, x0:x0 + w] = self.background
        known[y0:y0 + h, x0:x0 + w] = self.known
        return Plate(bg, known, self.noise, self.method, self.band_known, self.error, self.error_rmse)

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


def px(frac: float, width: int) -> int:
    """Pixels of a fraction of the image width (at least 1)."""
    return max(1, int(round(frac * width)))


def source_mask(object_depth: np.ndarray) -> np.ndarray:
    """(H, W) bool confidently background: outside the object's depth dilated by SOURCE_BAND_FRACTION."""
    m = np.asarray(object_depth) > 0
    return ~ndimage.binary_dilation(m, iterations=px(SOURCE_BAND_FRACTION, m.shape[1]))


def need_mask(object_depth: np.ndarray) -> np.ndarray:
    """(H, W) bool pixels whose background the matte may ask for: the trimap's band and opaque
    pixels, widened as capture.matting_known widens it."""
    tri = depth_trimap(object_depth)
    return ndimage.binary_dilation(tri > 0, iterations=px(WIDEN_FRACTION, tri.shape[1]))


def ring_pixels(object_depth: np.ndarray) -> np.ndarray:
    """(N, 2) int (x, y) of the held-back ring: source pixels within RING_FRACTION of the source
    band's edge, at most RING_SAMPLES (evenly)."""
    src = source_mask(object_depth)
    near = ndimage.binary_dilation(~src, iterations=px(RING_FRACTION, src.shape[1]))
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


def neighbour_order(cams: list[Camera], i: int, k: int) -> list[int]:
    """Indices of the ``k`` cameras other than ``i`` nearest to it by optical axis."""
    f = np.array([c.forward for c in cams])
    ang = np.arccos(np.clip(f @ f[i], -1, 1))
    ang[i] = np.inf
    return [int(j) for j in np.argsort(ang)[:k] if np.isfinite(ang[j])]


@dataclass(frozen=True)
class _Prep:
    """What the plate stage works out once per view: its confidently background pixels (source
    mask), the pixels it needs a plate at (need mask), its held-back ring (N, 2) and its room depth
    under the object (or None)."""

    source: np.ndarray
    need: np.ndarray
    ring: np.ndarray
    room: np.ndarray | None


def _prepare(v: PlateView, plane: np.ndarray | None) -> _Prep:
    src = source_mask(v.object_depth)
    bgd = np.where(np.asarray(v.object_depth) > 0, 0.0, v.depth)
    pts, m = v.camera.depth_to_points(bgd)
    off = np.zeros(bgd.shape, bool)
    if len(pts):
        off[m] = True if plane is None else (pts @ plane[:3] + plane[3]) > PLANE_OFF_METRES
    ring = src & ndimage.binary_dilation(~src, iterations=px(RING_FRACTION, src.shape[1]))
    return _Prep(src, need_mask(v.object_depth), ring_pixels(v.object_depth), room_depth(bgd, ring, off))


def _sources(views: list[PlateView], pre: list[_Prep], gains: np.ndarray,
             focus: tuple[np.ndarray, float]) -> list[PlateSource]:
    center, radius = focus
    out = []
    for j, v in enumerate(views):
        bgd = np.where(np.asarray(v.object_depth) > 0, 0.0, v.depth).astype(np.float32)
        far = float(v.camera.world_to_cam(center)[2] + radius)
        out.append(PlateSource(v.camera, v.linear, pre[j].source, bgd, gains[j], far))
    return out


def panorama_prediction(views: list[PlateView], i: int, pix: np.ndarray, sources: list[PlateSource],
                        plane: np.ndarray | None, k: int, room: np.ndarray | None) -> np.ndarray:
    """(N, 3) colour behind pixels ``pix`` of view i in its exposure from its ``k`` nearest other
    views (NaN where unknown; ``room``: its room depth, capture.plate_reproject.room_depth)."""
    cams = [v.camera for v in views]
    nb = [sources[j] for j in neighbour_order(cams, i, k)]
    col, known, _ = reproject_plate(cams[i], pix, sources[i].gain, nb, plane, room)
    col = col.astype(np.float32)
    col[~known] = np.nan
    return col


def _error(observed: np.ndarray, predicted: np.ndarray) -> tuple[float, float]:
    """(median of the largest channel's |error|, RMS) over the predicted rows (NaN: none)."""
    ok = np.isfinite(predicted).all(axis=1)
    if not ok.any():
        return float("nan"), float("nan")
    d = np.abs(predicted[ok] - observed[ok])
    return float(np.median(d.max(axis=1))), float(np.sqrt(np.mean(d * d)))


def _predict(mode: str, views, pre: list[_Prep], gains: np.ndarray, cfg: PlateConfig, plane, focus,
             weights=None) -> list[np.ndarray]:
    """Per view its held-back ring predicted from the other views (N_i, 3), in its own exposure."""
    from capture.plate_fixed import fixed_prediction

    if mode == "fixed":
        return [fixed_prediction(views, p.ring, i, gains, weights) / gains[i] for i, p in enumerate(pre)]
    src = _sources(views, pre, gains, focus)
    return [panorama_prediction(views, i, p.ring, src, plane, cfg.neighbours, p.room) for i, p in enumerate(pre)]


def choose_and_fit(views, pre: list[_Prep], cfg: PlateConfig, plane, focus):
    """(mode, gains (V, 3), per view (median error, RMS) of its held-back ring, {mode tried: its
    median error}): each mode tried ('fixed' / 'panorama', or the forced one) predicts every view's
    ring from the other views (a fixed camera with the exposure gains of the pixels every frame
    sees, capture.plate_fixed.fixed_gains; a moving one with unit gains); the one with the smaller
    error wins (:func:`choose_mode`); its gains are then fitted to its predictions GAIN_PASSES times."""
    from capture.plate_fixed import fixed_gains, fixed_sample_weight

    obs = [v.linear[p.ring[:, 1], p.ring[:, 0]].astype(np.float64) for v, p in zip(views, pre, strict=True)]
    weights = [fixed_sample_weight(v.object_depth) for v in views]
    tried = {}
    for m in (("fixed", "panorama") if cfg.mode == "auto" else (cfg.mode,)):
        g = fixed_gains(views, weights) if m == "fixed" else np.ones((len(views), 3))
        pred = _predict(m, views, pre, g, cfg, plane, focus, weights)
        tried[m] = (g, pred, [_error(o, p) for o, p in zip(obs, pred, strict=True)])
    mode = choose_mode({m: t[2] for m, t in tried.items()})
    gains, pred, _ = tried[mode]
    for _ in range(GAIN_PASSES):
        gains = fit_gains(obs, [p * gains[i] for i, p in enumerate(pred)], gains)
        pred = _predict(mode, views, pre, gains, cfg, plane, focus, weights)
    errs = [_error(o, p) for o, p in zip(obs, pred, strict=True)]
    return mode, gains, errs, {m: _summary(t[2]) for m, t in tried.items()}


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


def _panorama_plate(views, i, pre: _Prep, sources, plane, cfg) -> tuple[np.ndarray, np.ndarray]:
    y, x = np.nonzero(pre.need)
    col = panorama_prediction(views, i, np.stack([x, y], axis=1), sources, plane, cfg.neighbours, pre.room)
    out = np.zeros(views[i].linear.shape, np.float32)
    known = np.zeros(pre.need.shape, bool)
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
    from capture.plate_fixed import fixed_plates

    cfg = cfg or PlateConfig()
    if cfg.mode == "off":
        return [None] * len(views), {"mode": "off"}
    if cfg.mode == "user" and user is None:
        raise ValueError("--plate user needs --background-plates DIR")
    if user is not None and cfg.mode in ("auto", "user"):
        return _user_plates(views, user)
    focus = focus or focus_region([v.camera for v in views])
    pre = [_prepare(v, plane) for v in views]
    mode, g, errs, tried = choose_and_fit(views, pre, cfg, plane, focus)
    if mode == "fixed":
        made = fixed_plates(views, [p.need for p in pre], g)
    else:
        src = _sources(views, pre, g, focus)
        made = [_panorama_plate(views, i, pre[i], src, plane, cfg) for i in range(len(views))]
    plates = [_plate(v, c, k, errs[i], mode) for i, (v, (c, k)) in enumerate(zip(views, made, strict=True))]
    return plates, _record(mode, plates, g, tried)


def _user_plates(views: list[PlateView], user: list[np.ndarray]) -> tuple[list[Plate], dict]:
    """The user's plates in each view's exposure (:func:`user_gains`), their errors on the held-back ring."""
    g = user_gains(views, user)
    plates = []
    for i, (v, u) in enumerate(zip(views, user, strict=True)):
        r = ring_pixels(v.object_depth)
        err = _error(v.linear[r[:, 1], r[:, 0]].astype(np.float64), np.asarray(u)[r[:, 1], r[:, 0]] / g[i])
        plates.append(_plate(v, np.asarray(u, np.float32) / g[i], np.ones(v.object_depth.shape, bool), err, "user"))
    return plates, _record("user", plates, g, {})


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

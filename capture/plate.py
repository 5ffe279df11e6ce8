"""The background behind the object in every view (a clean plate), from the capture itself (issue 30).

A partial pixel of a needle or a strand is C = a F + (1 - a) B: without B, even the true alpha leaves
the room in F (issue 30: 19.4 dB held out with the true matte against 24.3 over black).  The capture
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
one with the smaller error (RMS) wins (:func:`choose_mode`); nobody is asked whether the camera moved.

"Confidently background" (``source`` mask) is outside the object's depth (after the extent stage)
dilated by ``SOURCE_BAND_FRACTION`` of the width, twice the matting band.  Each view's exposure
gain (auto exposure, white balance: colour = true colour / g) is fitted on those pixels
(:func:`fit_gains`) so that one view's plate is drawn in its own exposure.

The orchestration (:func:`background_plates`): every view is prepared once (:func:`prepare`: its
masks, held-back ring and what each path reads of it, a :class:`PlateSet`); each path tried
(:data:`PATHS`: its first gains, its prediction of every view's ring from the other views, its
drawing of the plates) predicts the rings (a :class:`Trial`); the winner's gains are refitted on its
own predictions GAIN_PASSES times (:func:`refit`); then it draws the plates.

Every view's record says what share of its matting band got a known background and the plate's
error on background pixels it was not built from (a ring of the view's own background pixels just
outside the band, predicted from the other views only: leave one out).  Where no view saw the
background, the plate is unknown and the matte falls back to the estimate without it; a view whose
plate cannot beat its own nearby background on that ring gets none (capture.plate_gate).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from capture.camera import Camera
from capture.matting import UNKNOWN, depth_trimap
from capture.matting_cells import band_crossing
from capture.matting_fast import dilate
from capture.matting_known import widen_px
from capture.plate_gate import gate_record, gated  # each view's plate against none
from capture.plate_record import plate_record
from capture.plate_reproject import room_depth
from capture.plate_threads import thread_map
from capture.sampling import mask_box
from capture.vignetting import measured

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
#: Gain fit: least samples for a view's gain; fewer keeps gain 1.
GAIN_MIN_SAMPLES = 200
#: Noise passed to the matte: this multiple of the view's median held-back plate error ...
NOISE_PER_ERROR = 1.5
#: ... at least one 8-bit sRGB step at black (linear) and at most NOISE_MAX.
NOISE_MIN = 1.0 / 255 / 12.92
NOISE_MAX = 0.05
#: choose_mode compares the paths by the median over views of each view's held-back RMS (True) or of
#: each view's median error (False: the reference rule, which a dark backdrop fools).
CHOOSE_BY_RMS = True
#: The photo's ceiling (linear): a prediction above it is compared as the sensor recorded it (a plate drawn into
#: a brighter frame's exposure exceeds 1 where that frame is blown out; the held-back error then measured the
#: clipping, 0.026 median on the conifer with auto exposure, and set the matte's noise allowance from it).
SENSOR_MAX = 1.0


@dataclass(frozen=True)
class PlateConfig:
    """Settings of :func:`background_plates` (the pipeline's background plate stage)."""

    #: One of PLATE_MODES (module docstring); 'off' = no plate (the matte is estimated without one).
    mode: str = "auto"
    #: Views consulted per view when the camera moves (the nearest by optical axis).
    neighbours: int = NEIGHBOURS
    #: Folder of plates the user shot (``--background-plates``; capture.plate_io), or None.
    plates_dir: str | None = None
    #: 'auto': the frames' sensor noise is measured and, where it is at least capture.noise.NOISE_MIN_SIGMA
    #: 8-bit steps, the plate is made from the frames through a bilateral filter on the scale of the noise (the
    #: matte still reads the photos; capture.noise); 'off': the frames as they are.
    denoise: str = "auto"
    #: Frames blurred where the others are sharp (capture.blurred_views; the fixed camera's): 'keep' (tested, said,
    #: kept), 'leave out' (left out of the model: volume/surroundings.py), 'off' (not tested).
    blurred: str = "keep"
    #: A moving camera's lens vignetting (capture.vignetting): 'auto' (measured on the panorama's held-back
    #: background, taken out of every frame where it beats none), 'off' (not measured).
    vignetting: str = "auto"

    def __post_init__(self) -> None:
        if self.mode not in PLATE_MODES:
            raise ValueError(f"plate mode must be one of {', '.join(PLATE_MODES)}, got {self.mode!r}")
        if {self.denoise, self.vignetting} - {"auto", "off"} or self.blurred not in ("keep", "leave out", "off"):
            raise ValueError(f"plate denoise, vignetting 'auto'|'off'; blurred 'keep', 'leave out' or 'off': {self!r}")
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
        band_estimated: the part of ``band_known`` whose background no frame saw clean but the
            frames' lines gave (capture.plate_lines; fixed camera only).
        band_crossing: the share of the band whose background a frame saw, not dark, not blown out
            (capture.matting_cells.band_crossing: where the colour across the views can gain).
        frame: None for a full-frame plate; (H, W, y0, x0) for a plate cropped to its known box
            (:meth:`cropped`): ``background``, ``known`` and ``estimated`` are then the box at (y0, x0).
        estimated: (H, W) bool or None, the known pixels whose background came from the frames' lines
            (capture.plate_lines), not from a frame that saw it clean; None = none.
        sigma: (H, W) float32 or None, the uncertainty of the ``estimated`` background (linear,
            Euclidean over the channels; capture.plate_lines.vertex_sigma; inf where it is a blown-out
            bound), 0 elsewhere; None = not reported (the matte then fills every estimated pixel's colour).
    """

    background: np.ndarray
    known: np.ndarray
    noise: float
    method: str
    band_known: float
    error: float
    error_rmse: float
    band_estimated: float = 0.0
    frame: tuple | None = None
    estimated: np.ndarray | None = None
    sigma: np.ndarray | None = None
    band_crossing: float = 0.0

    def seen(self) -> np.ndarray:
        """(H, W) bool: the known pixels some frame (or the user's plate) saw clean (``known`` less
        ``estimated``).  A matte given by the user unmixes the colour only there: with the true
        matte of the path-traced conifer turntable the lines' estimate cost 2.8 dB held out (25.79
        -> 22.95), while the known-background matte gains from it."""
        return self.known if self.estimated is None else self.known & ~self.estimated

    def cropped(self) -> Plate:
        """The plate on the box around its known pixels, colour as float16 (what waits for the matte
        stage); :meth:`full` gives it back at its (H, W)."""
        H, W = self.known.shape
        r0, r1, c0, c1 = mask_box(self.known) or (0, 0, 0, 0)
        sl = (slice(r0, r1), slice(c0, c1))
        return Plate(self.background[sl].astype(np.float16), self.known[sl].copy(), self.noise, self.method,
                     self.band_known, self.error, self.error_rmse, self.band_estimated, (H, W, r0, c0),
                     None if self.estimated is None else self.estimated[sl].copy(),
                     None if self.sigma is None else self.sigma[sl].copy(), self.band_crossing)

    def full(self) -> Plate:
        """The plate at its image's full (H, W) (itself when not cropped)."""
        if self.frame is None:
            return self
        H, W, y0, x0 = self.frame
        h, w = self.known.shape

        def put(a, dtype, *c):  # the box's array at its place in a frame of zeros (None: None)
            out = None if a is None else np.zeros((H, W, *c), dtype)
            if out is not None:
                out[y0:y0 + h, x0:x0 + w] = a
            return out

        return Plate(put(self.background, np.float32, 3), put(self.known, bool), self.noise, self.method,
                     self.band_known, self.error, self.error_rmse, self.band_estimated,
                     estimated=put(self.estimated, bool), sigma=put(self.sigma, np.float32),
                     band_crossing=self.band_crossing)

    def record(self) -> dict:
        """JSON-able summary of the view's plate (model.json, the stage table)."""
        return {"method": self.method, "band_known": round(self.band_known, 4),
                "band_estimated": round(self.band_estimated, 4), "band_crossing": round(self.band_crossing, 4),
                "error": None if not np.isfinite(self.error) else round(self.error, 5),
                "error_rmse": None if not np.isfinite(self.error_rmse) else round(self.error_rmse, 5),
                "noise": round(self.noise, 5), "sigma_median": self._sigma_median()}

    def _sigma_median(self) -> float | None:
        """Median of ``sigma`` over the finite estimated pixels (None without any)."""
        s = np.zeros(0) if self.sigma is None or self.estimated is None else np.asarray(self.sigma)[self.estimated]
        return round(float(np.median(s[np.isfinite(s)])), 5) if np.isfinite(s).any() else None


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
    return ~dilate(m, px(SOURCE_BAND_FRACTION, m.shape[1]))  # ndimage.binary_dilation(m, iterations=...)


def need_mask(object_depth: np.ndarray, fast: bool | None = None) -> np.ndarray:
    """(H, W) bool pixels whose background the matte may ask for: the trimap's band and opaque
    pixels, widened as capture.matting_known widens it.  ``fast`` (default NEED_ONE_DILATION): by one
    dilation (capture.plate_weight.need_by_one_dilation), the same mask as the trimap's (False)."""
    from capture import plate_weight as pw

    if pw.NEED_ONE_DILATION if fast is None else fast:
        return pw.need_by_one_dilation(object_depth)
    tri = depth_trimap(object_depth)
    return dilate(tri > 0, widen_px(tri.shape[1]))  # ndimage.binary_dilation(..., iterations=...)


def ring_pixels(object_depth: np.ndarray, source: np.ndarray | None = None) -> np.ndarray:
    """(N, 2) int (x, y) of the held-back ring: source pixels within RING_FRACTION of the source
    band's edge, at most RING_SAMPLES (evenly); ``source``: the view's :func:`source_mask` if known."""
    src = source_mask(object_depth) if source is None else source
    near = dilate(~src, px(RING_FRACTION, src.shape[1]))  # ndimage.binary_dilation(..., iterations=...)
    return even_sample(*np.nonzero(src & near))


def even_sample(y: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(N, 2) int (x, y) of the pixels (y, x), at most RING_SAMPLES of them, evenly spaced in that order."""
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


@dataclass(frozen=True)
class PreparedView:
    """One view as every plate path reads it, worked out once (:func:`prepare`).

    Attributes:
        view: the view, without its capture's ``depth`` (None: ``background_depth`` holds what is read).
        source: (H, W) bool, confidently background (:func:`source_mask`); None once a path that does
            not read it is chosen (:meth:`PlateSet.for_path`, as ``background_depth``).
        need: (H, W) bool, where the matte may ask for the plate (:func:`need_mask`).
        ring: (N, 2) int (x, y) of its held-back ring (:func:`ring_pixels`).
        observed: (N, 3) float64 its linear colour on the ring.
        background_depth: (H, W) float32 the capture's depth where it is not the object (0 = none).
        room: (H, W) z-depth of the room filled in under the object
            (capture.plate_reproject.room_depth), or None (none measured, or no moving-camera path).
        weight: (H, W) float32 its pixels' weight as fixed-camera samples
            (capture.plate_fixed.fixed_sample_weight), or None (no fixed-camera path).
    """

    view: PlateView
    source: np.ndarray
    need: np.ndarray
    ring: np.ndarray
    observed: np.ndarray
    background_depth: np.ndarray
    room: np.ndarray | None
    weight: np.ndarray | None


@dataclass(frozen=True)
class PlateSet:
    """Every view prepared, and what the paths share.

    Attributes:
        views: the prepared views.
        plane: (4,) the support plane (n, d; n . X + d = 0, metres) or None.
        focus: (centre (3,), radius) of the region the rig looks at (metres).
        neighbours: views consulted per view by the moving-camera path.
        dropped: views that lend the others nothing (their plate was refused: capture.plate_gate).
    """

    views: tuple[PreparedView, ...]
    plane: np.ndarray | None
    focus: tuple[np.ndarray, float]
    neighbours: int
    dropped: frozenset = frozenset()

    @property
    def cameras(self) -> list[Camera]:
        return [p.view.camera for p in self.views]

    def for_path(self, path: str) -> PlateSet:
        """The set with only what ``path`` reads (:data:`PATH_READS`): the chosen path's gains and drawing no longer
        hold the other path's per-view arrays (at 200 phone views the room depths alone are 8 bytes a working pixel)."""
        drop = {k: None for k in PATH_ONLY if k not in PATH_READS[path]}
        return replace(self, views=tuple(replace(p, **drop) for p in self.views))


#: The per-view arrays of a PreparedView that one path alone reads (the rest every path reads) ...
PATH_ONLY = ("source", "background_depth", "room", "weight")
#: ... and which of them each path reads (PlateSet.for_path drops the others once the path is chosen).
PATH_READS = {"fixed": ("weight",), "panorama": ("source", "background_depth", "room")}


def tried_paths(cfg: PlateConfig) -> tuple[str, ...]:
    """The paths background_plates tries: both in 'auto', else the one forced."""
    return ("fixed", "panorama") if cfg.mode == "auto" else (cfg.mode,)


def prepare(v: PlateView, plane: np.ndarray | None, paths: tuple[str, ...]) -> PreparedView:
    """The view's :class:`PreparedView`; the room depth only for the 'panorama' path, the sample
    weights only for the 'fixed' one."""
    from capture.plate_fixed import fixed_sample_weight
    from capture.plate_masks import off_plane_at, view_masks  # the same masks (MASKS_BOX, OFF_PLANE_BAND)

    src, ring, need, band = view_masks(v.object_depth, "panorama" in paths)
    bgd = np.where(np.asarray(v.object_depth) > 0, 0.0, v.depth).astype(np.float32, copy=False)
    room = None if band is None else room_depth(bgd, band, off_plane_at(v.camera, bgd, plane, band))
    weight = fixed_sample_weight(v.object_depth) if "fixed" in paths else None
    observed = np.asarray(v.linear[ring[:, 1], ring[:, 0]], np.float64)
    # the capture's depth is read here only (background_depth keeps what the paths need of it)
    return PreparedView(replace(v, depth=None), src, need, ring, observed, bgd, room, weight)


def plate_set(views, plane: np.ndarray | None, focus: tuple[np.ndarray, float] | None,
              cfg: PlateConfig) -> PlateSet:
    """Every view prepared (:func:`prepare`) for the paths ``cfg`` tries; ``views``: PlateViews, any
    iterable (read once, so that a generator's views need not all wait at once); ``focus`` default
    capture.extent.focus_region of the cameras."""
    from capture.extent import focus_region

    paths = tried_paths(cfg)
    prepared = tuple(thread_map(lambda v: prepare(v, plane, paths), views))  # side by side (the same views)
    focus = focus or focus_region([p.view.camera for p in prepared])
    return PlateSet(prepared, plane, focus, int(cfg.neighbours))


def path_functions(path: str):
    """(first gains, ring prediction, plate drawing) of a path: each takes the PlateSet (and gains);
    predictions and plates are in each view's own exposure."""
    from capture import plate_fixed as pf
    from capture import plate_reproject as pr

    return {"fixed": (pf.fixed_start, pf.fixed_predict, pf.fixed_draw),
            "panorama": (pr.panorama_start, pr.panorama_predict, pr.panorama_draw)}[path]


# --- the orchestration ---


@dataclass(frozen=True)
class Trial:
    """One path's gains (V, 3), its prediction of every view's ring (list of (N_i, 3), NaN =
    unknown) and per view (median of the largest channel's |error|, RMS) against the ring."""

    gains: np.ndarray
    predicted: list
    errors: list


def _error(observed: np.ndarray, predicted: np.ndarray) -> tuple[float, float]:
    """(median of the largest channel's |error|, RMS) over the predicted rows (NaN: none), the
    prediction clipped to the sensor's ceiling (SENSOR_MAX) as the photo is."""
    if not (ok := np.isfinite(predicted).all(axis=1)).any():
        return float("nan"), float("nan")
    d = np.abs(np.minimum(predicted[ok], SENSOR_MAX) - observed[ok])
    return float(np.median(d.max(axis=1))), float(np.sqrt(np.mean(d * d)))


def ring_trial(ps: PlateSet, path: str, gains: np.ndarray | None = None) -> Trial:
    """The path's prediction of every ring with ``gains`` (default the path's first gains)."""
    start, predict, _ = path_functions(path)
    pred = predict(ps, g := start(ps) if gains is None else gains)
    return Trial(g, pred, [_error(p.observed, q) for p, q in zip(ps.views, pred, strict=True)])


def refit(ps: PlateSet, path: str, trial: Trial) -> Trial:
    """The path's gains fitted to its own predictions GAIN_PASSES times (:func:`fit_gains`), each
    pass predicting again with the new gains."""
    for _ in range(GAIN_PASSES):
        common = [q * trial.gains[i] for i, q in enumerate(trial.predicted)]
        trial = ring_trial(ps, path, fit_gains([p.observed for p in ps.views], common, trial.gains))
    return trial


def choose_mode(errors: dict) -> str:
    """The plate mode ('fixed' / 'panorama') whose held-back error is smaller: the median over views of
    each view's RMS (CHOOSE_BY_RMS; else of each view's median error, the rule before).  A view's median
    says nothing where most of its ring is one dark backdrop: any path that predicts black gets 0 there
    (a phone orbit over a black room with a table: the fixed camera's median 0.00015 against the
    panorama's 0.00048, while its RMS, 0.06-0.12, is ten times the panorama's on the table it gets
    wrong; docs/matting.md "The plate's choice by RMS")."""
    k = 1 if CHOOSE_BY_RMS else 0
    score = {m: np.nanmedian([e[k] for e in errs]) if np.isfinite([e[k] for e in errs]).any() else np.inf
             for m, errs in errors.items()}
    return min(score, key=lambda m: score[m])


def background_plates(views, cfg: PlateConfig | None = None, plane: np.ndarray | None = None,
                      focus: tuple[np.ndarray, float] | None = None,
                      user: list[np.ndarray] | None = None, crop: bool = False) -> tuple[list[Plate | None], dict]:
    """(per view its Plate, or None for mode 'off'; record for model.json / the console) (module
    docstring).  ``views``: a list of PlateViews (mode 'off', user plates), else any iterable of them
    (read once: :func:`plate_set`).  ``plane``: the support plane (capture.extent, (4,) or None);
    ``focus``: (centre, radius) of the region the rig looks at (default capture.extent.focus_region);
    ``user``: per view a (H, W, 3) linear plate the user shot (capture.plate_io); ``crop``: each plate
    cropped to its known box (:meth:`Plate.cropped`) as soon as it is drawn, so that full-frame plates
    never wait together (the same plates as cropping them afterwards)."""
    cfg = cfg or PlateConfig()
    if cfg.mode == "off":
        return [None] * len(views), {"mode": "off"}
    if cfg.mode == "user" and user is None:
        raise ValueError("--plate user needs --background-plates DIR")
    if user is not None and cfg.mode in ("auto", "user"):
        from capture.plate_io import user_plates

        plates, rec = user_plates(views, user)
        return ([p.cropped() for p in plates] if crop else plates), rec
    ps = plate_set(views, plane, focus, cfg)
    trials = {path: ring_trial(ps, path) for path in tried_paths(cfg)}
    mode = choose_mode({path: t.errors for path, t in trials.items()})
    ps, vig = measured(ps.for_path(mode), mode, cfg, trials)  # a moving camera's vignetting (capture.vignetting)
    from capture.plate_exposure import plate_exposure  # the gains against none on held-back pixels
    from capture.plate_pairs import fitted  # the panorama's gains from pairs of views at once

    fit, samples = fitted(ps, mode, trials[mode])

    exposure, fit = plate_exposure(ps, mode, trials[mode], fit, samples)
    plates = draw_plates(ps, mode, fit, crop)
    plates, gate, dropped = gated(ps, mode, fit, plates, crop)  # refused plates out, and their views as sources
    rec = gate_record(plate_record(mode, plates, fit.gains, {path: t.errors for path, t in trials.items()}), gate,
                      dropped)
    if mode == "fixed" and cfg.blurred != "off":  # frames blurred where the others are sharp (capture.blurred_views)
        from capture.blurred_views import blurred_views

        rec = {**rec, "per_view": [{**r, "blur": b} for r, b in zip(rec["per_view"], blurred_views(ps, fit.gains))]}
    rec = rec if vig is None else {**rec, "vignetting": vig}
    return plates, rec if exposure is None else {**rec, "exposure": exposure}


def draw_plates(ps: PlateSet, mode: str, fit: Trial, crop: bool) -> list[Plate]:
    """Every view's Plate drawn by ``mode``'s path with ``fit``'s gains, its held-back errors from ``fit`` (one
    view's plate at a time, finished side by side; ``crop``: :meth:`Plate.cropped` as soon as drawn)."""
    made = path_functions(mode)[2](ps, fit.gains)
    return list(thread_map(lambda a: _plate(a[0].view, a[1][0], a[1][1], a[2], mode, *a[1][2:], crop=crop),
                           zip(ps.views, made, fit.errors, strict=True)))


def _plate(v: PlateView, col: np.ndarray, known: np.ndarray, err: tuple[float, float], method: str,
           estimated: np.ndarray | None = None, sigma: np.ndarray | None = None, crop: bool = False) -> Plate:
    tri = depth_trimap(v.object_depth)
    band = tri == UNKNOWN
    noise = float(np.clip(NOISE_PER_ERROR * err[0], NOISE_MIN, NOISE_MAX)) if np.isfinite(err[0]) else NOISE_MAX
    est = float(estimated[band].mean()) if estimated is not None and band.any() else 0.0
    plate = Plate(np.asarray(col, np.float32), known, noise, method, float(known[band].mean()) if band.any() else 0.0,
                  err[0], err[1], band_estimated=est, estimated=estimated, sigma=sigma,
                  band_crossing=band_crossing(v.linear, band, col, known, estimated, tri == 1.0))
    return plate.cropped() if crop else plate  # crop: the box around its known pixels (Plate.cropped)

"""A soft alpha matte per view and the object's straight colour under it (issues 20 and 30).

Needles and strands are mostly *partial* pixels: any rule that treats "has depth" as "is opaque"
paints the background into the object.  :func:`matte_scan` gives each view a straight alpha matte
in [0, 1] and the foreground colour F (so that image = alpha F + (1 - alpha) B), by the first
path that applies (``MatteConfig.mode`` = ``auto``; or one forced):

1. ``given``: the capture's own matte (``Scan.alpha``: transforms.json ``mask_path`` or an RGBA
   image's alpha, ``capture.matte_io``); with the view's background plate its colour is unmixed
   exactly, F = B + (C - B) / alpha (:func:`unmixed`).
2. ``backdrop``: a known plain backdrop B (``MatteConfig.backdrop``; in ``auto`` also a backdrop
   detected from the view: the pixels certainly behind the object all within ``BACKDROP_TOL`` of
   their median colour), solved as a known background everywhere (:func:`solve_known`) with the
   backdrop's own noise (:func:`backdrop_noise`): over black the premultiplied colour is the
   photo itself, so a black capture renders as without a matte.
3. ``plate``: the view's background plate (``capture.plate``, the pipeline's plate stage) where
   it is known: alpha and F from C = a F + (1 - a) B with B known (``capture.matting_known``), the
   closed-form Laplacian alone where it is not; where B is the frames' lines' estimate the colour is
   unmixed or filled per pixel by the expected error of each (``capture.matting_colour``); the depth's
   opaque pixels of thin branches are solved too where a moving camera's plate saw behind them
   (``capture.matting_rim``).
4. ``estimate``: a trimap from the object's depth (:func:`depth_trimap`: opaque where the object's
   depth is dense, i.e. the depth mask eroded by ``ERODE_FRACTION`` of the width; background
   beyond a band of ``BAND_FRACTION`` of the width around it; unknown between, which covers the
   edges and every thin structure), then closed-form matting (Levin et al. 2008, pymatting's
   ``estimate_alpha_cf``) on the crop around the unknown and opaque pixels, and pymatting's
   ``estimate_foreground_ml`` (Germer et al. 2020) for the colour.

Outside the crop alpha is 0 and F is the image.  All of it runs in linear light, where the
compositing equation holds.  ``off`` gives None (the binary depth mask stays the only mask).

:func:`closed_form_alpha_reference` is the slow numpy / scipy reference of the closed-form
matte (the Laplacian built by loops over windows, a sparse direct solve) for tests of the
pymatting path on small crops; ``capture.matting_known`` keeps its own twin.
"""

from __future__ import annotations

import contextlib
import io
from dataclasses import dataclass, field

import numpy as np

from capture.matting_fast import channel_max, dilate, erode
from capture.scan import Scan

#: Matting modes of MatteConfig.mode / ``furrow model --matte``.
MATTE_MODES = ("auto", "given", "backdrop", "plate", "estimate", "off")
#: Resolutions the estimated and the known-background matte are solved at (MatteConfig.resolution /
#: ``furrow model --matte-resolution``):
#: ``full`` every pixel (the reference), ``working`` capture.matting_scale's working resolution.
MATTE_RESOLUTIONS = ("full", "working")
#: When the matte stage gives the partial pixels the colour their 3D cell's lines cross at across the
#: views (volume.surroundings, capture.matting_cells): on, off, or auto (the rule of
#: volume.surroundings.across_wanted).
MATTE_ACROSS = ("auto", "on", "off")
#: Opaque = the object's depth mask eroded by this fraction of the image width (2 px at 640).
ERODE_FRACTION = 2 / 640
#: Unknown band: this fraction of the width around the object's depth (4 px at 640; measured on the plant over
#: its map at 320x240: alpha MSE 0.0037 with 2 px, 0.0052 with 3, 0.0057 with 4, binary depth mask 0.0077).
BAND_FRACTION = 4 / 640
#: A pixel within this (linear RGB, max over channels) of the backdrop colour, outside the
#: object's depth, is background; detection of a plain backdrop wants BACKDROP_PLAIN of the
#: certain-background pixels that close to their median.
BACKDROP_TOL = 0.02
BACKDROP_PLAIN = 0.98
#: An 8-bit view's plain-backdrop test counted on its codes (capture.matting_backdrop: the same answer,
#: 0.066 s a 1280x960 view less in the matte workers; docs/speed.md round 10); False: on the linear colour.
BACKDROP_CODES = True
#: Noise of a plain backdrop: this quantile of its certain pixels' difference from its colour,
#: at least NOISE_FLOOR (one 8-bit sRGB step at black, linear).
BACKDROP_NOISE_QUANTILE = 0.95
NOISE_FLOOR = 1.0 / 255 / 12.92
#: A backdrop this dark (linear, largest channel; 8-bit sRGB 37) leaves a faint strand's alpha to the body's colour
#: (C - B = a (F - B) with |F - B| about |F|): the matte's notes say ``dark_backdrop`` and furrow model warns.  On
#: path-traced fur over black the kept views' alpha came out 1.5-1.8 x the truth at true alpha 0.1-0.5
#: (docs/matting.md "Fur over a black backdrop: the fringe's alpha").
DARK_BACKDROP = 0.02
#: Pixels of margin around the crop that is matted (the matting windows are 3x3).
CROP_PAD = 4
#: Closed-form matting: regularisation epsilon of the Laplacian and the CG solver's tolerance.
CF_EPSILON = 1e-7
CF_RADIUS = 1
#: Iterations of pymatting's conjugate gradient solve before a view falls back to its depth mask.
CG_MAX_ITERATIONS = 2000
#: Trimap values: background, unknown, opaque (pymatting's convention).
BG, UNKNOWN, FG = 0.0, 0.5, 1.0


#: With a plate, where the background is the frames' lines' estimate (capture.plate.Plate.estimated)
#: the straight colour is unmixed only where its expected error, (1 - a) x the plate's sigma, is below
#: the fill's, measured in the view (capture.matting_colour.colour_gate), and filled elsewhere
#: (capture.matting_known.foreground_colour's fill); a plate without sigma: filled everywhere there
#: (the fifth round's rule, the record says so).  The alpha still uses the lines' estimate.  Computed
#: once, in the known-background matte's own colour step.  Off: unmixed everywhere B is known.
#: Held out, the fifth round's fill-everywhere rule (docs/matting.md): conifer turntable 23.97 ->
#: 24.59 dB, room + table + AE + lens 22.85 -> 24.46, fur before similar bricks 23.07 -> 23.16; the
#: sixth round's per-pixel choice, with capture.matting_colour.GATE_SEEN the same choice where B was
#: seen (also for panorama plates): 24.64, 24.57, 23.16, orbit 25.88 -> 26.09 (docs/matting.md).
COLOUR_FROM_SEEN = True


@dataclass(frozen=True)
class MatteConfig:
    """Settings of :func:`matte_scan`."""

    #: One of MATTE_MODES (module docstring).
    mode: str = "auto"
    #: Known plain backdrop, (3,) linear RGB in [0, 1] (``furrow model --backdrop``); None = none named.
    backdrop: tuple[float, float, float] | None = None
    #: One of MATTE_RESOLUTIONS: the solve at the working resolution (capture.matting_scale: on a
    #: smaller copy, brought back by the fast guided filter; full size for objects under ~800 pixels),
    #: or at full size (the reference).
    resolution: str = "working"
    #: Width (pixels) the depth was measured at when coarser than the colour (the scan set's
    #: ``depth_size``; set by the pipeline), which the working resolution keeps twice; None = unknown.
    depth_width: int | None = None
    #: One of MATTE_ACROSS: the colour across the views (needs a plate; volume.surroundings).
    across: str = "auto"
    #: The view's frame is a JPEG with subsampled chroma (capture.jpeg_chroma.subsampled_chroma; set per view
    #: by the pipeline): the alpha bound allows its chroma's error near edges of colour.
    subsampled: bool = False
    #: 'auto': the views whose frame is a JPEG with subsampled chroma get ``subsampled`` (capture.jpeg_chroma);
    #: 'off': none does (``furrow model --jpeg-chroma off``).
    jpeg_chroma: str = "auto"
    #: The extent stage's support plane and the object's place, (nx, ny, nz, d, cx, cy, cz, radius) in world units
    #: (set by the pipeline), or None: where a fixed camera's plate lacks the object's own shadow on it
    #: (capture.plate_shadow).
    support: tuple | None = None
    #: 'auto': a fixed camera's plate is lit as the frame is on the support beside the object where the ring shows
    #: a shadow (capture.plate_shadow); 'off': not (``furrow model --plate-shadow off``).
    shadow: str = "auto"
    #: The depth-opaque colour sources' coverage measured over the capture's views (capture.matting_sources; set by
    #: the pipeline's matte stage), in (0, 1]; None: they count as opaque.
    source_coverage: float | None = None

    def __post_init__(self) -> None:
        if self.mode not in MATTE_MODES:
            raise ValueError(f"matte mode must be one of {', '.join(MATTE_MODES)}, got {self.mode!r}")
        if self.resolution not in MATTE_RESOLUTIONS:
            raise ValueError(f"matte resolution must be one of {', '.join(MATTE_RESOLUTIONS)}, got {self.resolution!r}")
        if self.across not in MATTE_ACROSS:
            raise ValueError(f"matte colour across views must be one of {', '.join(MATTE_ACROSS)}, got {self.across!r}")
        if self.source_coverage is not None and not 0.0 < self.source_coverage <= 1.0:
            raise ValueError(f"source coverage must be in (0, 1], got {self.source_coverage}")
        if self.shadow not in ("auto", "off"):
            raise ValueError(f"plate shadow must be 'auto' or 'off', got {self.shadow!r}")
        if self.jpeg_chroma not in ("auto", "off"):
            raise ValueError(f"jpeg chroma must be 'auto' or 'off', got {self.jpeg_chroma!r}")
        if self.backdrop is not None:
            b = np.asarray(self.backdrop, float)
            if b.shape != (3,) or not np.all((b >= 0) & (b <= 1)):
                raise ValueError(f"backdrop must be 3 linear RGB values in [0, 1], got {self.backdrop}")


@dataclass(frozen=True)
class Matte:
    """A view's matte.

    Attributes:
        alpha: (H, W) float32 straight alpha in [0, 1].
        foreground: (H, W, 3) float32 linear straight colour of the object.
        method: 'given', 'backdrop' or 'estimate' (+ ' (not converged: depth mask)' when the solve failed).
        unknown_fraction: fraction of the view's pixels the trimap left unknown (0 for 'given').
        scale: the resolution it was solved at over the view's (1: full size).
        notes: the solver's record (capture.matting_known: ``blind_prior``; capture.matting_colour:
            ``colour``, how many estimated-background pixels were unmixed and filled; ``dark_backdrop``: the
            backdrop was at most DARK_BACKDROP; capture.matting_fringe: ``fringe``).
    """

    alpha: np.ndarray
    foreground: np.ndarray
    method: str
    unknown_fraction: float = 0.0
    scale: float = 1.0
    notes: dict = field(default_factory=dict)


def _px(frac: float, width: int) -> int:
    return max(1, int(round(frac * width)))


def depth_trimap(object_depth: np.ndarray) -> np.ndarray:
    """(H, W) float64 trimap (BG / UNKNOWN / FG) from the object's (H, W) depth (0 = none) (module docstring)."""
    m = np.asarray(object_depth) > 0
    W = m.shape[1]
    fg = erode(m, _px(ERODE_FRACTION, W))  # ndimage.binary_erosion(m, iterations=..., border_value=0)
    near = dilate(m, _px(BAND_FRACTION, W))  # ndimage.binary_dilation(m, iterations=...)
    tri = np.full(m.shape, BG)
    tri[near] = UNKNOWN
    tri[fg] = FG
    return tri


def detect_backdrop(image: np.ndarray, trimap: np.ndarray, codes: np.ndarray | None = None) -> np.ndarray | None:
    """(3,) colour of a plain backdrop: the median of the certain-background pixels when
    BACKDROP_PLAIN of them lie within BACKDROP_TOL of it; None otherwise (a room, clutter).
    ``codes``: the view's uint8 sRGB colour when ``image`` is its linear colour: then counted on the
    codes (capture.matting_backdrop, the same answer bit for bit) where :data:`BACKDROP_CODES`."""
    if codes is not None and BACKDROP_CODES and np.asarray(codes).dtype == np.uint8:
        from capture.matting_backdrop import backdrop_from_codes

        if np.shape(codes) != np.shape(image):
            raise ValueError(f"detect_backdrop: 8-bit codes {np.shape(codes)} are not the image's {np.shape(image)}")
        return backdrop_from_codes(codes, trimap == BG, BACKDROP_TOL, BACKDROP_PLAIN)
    bg = image[trimap == BG]
    if len(bg) < 16:
        return None
    med = np.median(bg, axis=0)
    close = channel_max(np.abs(bg - med)) <= BACKDROP_TOL
    return med if close.mean() >= BACKDROP_PLAIN else None


def _crop(trimap: np.ndarray) -> tuple[slice, slice] | None:
    ys, xs = np.nonzero(trimap > BG)
    if not len(ys):
        return None
    H, W = trimap.shape
    return (slice(max(0, ys.min() - CROP_PAD), min(H, ys.max() + CROP_PAD + 1)),
            slice(max(0, xs.min() - CROP_PAD), min(W, xs.max() + CROP_PAD + 1)))


def solve_matte(image: np.ndarray, trimap: np.ndarray, method: str, reference: bool = False,
                fallback: np.ndarray | None = None) -> Matte:
    """Closed-form alpha + ML foreground of linear ``image`` (H, W, 3) under ``trimap`` on its crop.
    When the solver does not converge (CG_MAX_ITERATIONS; seen on a 1920x1440 phone frame whose
    unknown band covers a whole pot plant), alpha is ``fallback`` (H, W) (the object's depth mask;
    default the trimap's opaque pixels) and the method says so: one view's matte must not stop a
    model."""
    from pymatting import estimate_alpha_cf

    from capture.foreground_ml import estimate_foreground_ml

    img = np.clip(np.asarray(image, np.float64), 0.0, 1.0)
    H, W = trimap.shape
    alpha = np.zeros((H, W), np.float32)
    fg = img.astype(np.float32).copy()
    unknown = float(np.mean(trimap == UNKNOWN))
    box = _crop(trimap)
    if box is None:
        return Matte(alpha, fg, method, unknown)
    ci, ct = img[box], trimap[box]
    if not np.any(ct == UNKNOWN):
        a = (ct == FG).astype(np.float64)
    elif reference:
        a = closed_form_alpha_reference(ci, ct)
    else:
        # pymatting prints its preconditioner's warnings on stdout, which holds `furrow model --json`
        try:
            with contextlib.redirect_stdout(io.StringIO()):
                a = estimate_alpha_cf(ci, ct, laplacian_kwargs={"epsilon": CF_EPSILON, "radius": CF_RADIUS},
                                      cg_kwargs={"maxiter": CG_MAX_ITERATIONS})
        except ValueError as e:  # pymatting: "Conjugate gradient descent did not converge ..."
            if "converge" not in str(e):
                raise
            a = (np.asarray(fallback)[box] if fallback is not None else ct == FG).astype(np.float64)
            method = f"{method} (not converged: depth mask)"
    a = np.clip(a, 0.0, 1.0)
    alpha[box] = a
    fg[box] = estimate_foreground_ml(ci, a)
    return Matte(alpha, np.clip(fg, 0.0, None).astype(np.float32), method, unknown)


def matte_scan(scan: Scan, object_depth: np.ndarray | None = None, cfg: MatteConfig | None = None,
               plate=None) -> Matte | None:
    """The matte of ``scan`` (module docstring); ``object_depth`` = the object's depth after the
    extent stage (default the scan's depth); ``plate``: the view's background plate
    (capture.plate.Plate) or None.  None for mode 'off'.  ValueError when a forced path does not
    apply (no given matte, no backdrop named, no plate)."""
    cfg = cfg or MatteConfig()
    if cfg.mode == "off":
        return None
    img = scan.linear_rgb
    if cfg.mode == "given" or (cfg.mode == "auto" and scan.alpha is not None):
        if scan.alpha is None:
            raise ValueError(f"scan {scan.name!r}: --matte given but the capture has no matte (mask_path / RGBA)")
        a = np.asarray(scan.alpha, np.float32)
        if plate is not None and plate.seen().any():  # the room unmixed from the colour where a frame saw B
            return Matte(a, unmixed(img, a, plate.background, plate.seen()), "given", 0.0)
        return Matte(a, _foreground(img, a), "given", 0.0)
    depth = scan.depth if object_depth is None else object_depth
    tri = depth_trimap(depth)
    mask = np.asarray(depth) > 0
    backdrop = None if cfg.backdrop is None else np.asarray(cfg.backdrop, np.float64)
    if cfg.mode == "backdrop" and backdrop is None:
        raise ValueError("--matte backdrop needs --backdrop COLOUR")
    if cfg.mode == "plate" and (plate is None or not plate.known.any()):
        raise ValueError(f"scan {scan.name!r}: --matte plate but the view has no background plate")
    refused = None  # capture.matting_choice: a detected backdrop the view's plate predicts better
    if cfg.mode == "auto" and backdrop is None:
        from capture.matting_choice import plate_beats_backdrop

        backdrop = detect_backdrop(img, tri, scan.rgb)
        if backdrop is not None and (refused := plate_beats_backdrop(img, depth, backdrop, plate)):
            backdrop = None
    if backdrop is not None and cfg.mode in ("auto", "backdrop"):
        B = np.broadcast_to(np.asarray(backdrop, np.float32), img.shape)
        m = solve_known(img, tri, B, np.ones(tri.shape, bool), backdrop_noise(img, tri, backdrop), "backdrop",
                        mask, cfg)
        if float(np.max(backdrop)) <= DARK_BACKDROP:
            m.notes["dark_backdrop"] = 1
        return m
    if plate is not None and plate.known.any() and cfg.mode in ("auto", "plate"):
        from capture.matting_colour import GATE_SEEN
        from capture.matting_rim import open_rim

        tri, rim = open_rim(tri, img, plate)
        est = plate.estimated if plate.estimated is not None else np.zeros(plate.known.shape, bool)
        gated = COLOUR_FROM_SEEN and (GATE_SEEN or est.any())
        B, known, est, shadow = _shadowed(scan, img, plate, est, tri, cfg)
        m = solve_known(img, tri, B, known, plate.noise, "plate", mask, cfg, (est, plate.sigma) if gated else None)
        if rim:
            m.notes["rim"] = rim
        if shadow:
            m.notes["shadow"] = shadow
        if refused:
            m.notes["backdrop_refused"] = refused
        return m
    return _solve_at(img, tri, "estimate", mask, cfg)


def _shadowed(scan: Scan, image: np.ndarray, plate, estimated: np.ndarray, trimap: np.ndarray, cfg: MatteConfig):
    """(the plate's background for the matte, where it is known, where the frames' lines ``estimated`` it, the shadow
    record or None): a fixed camera's plate lit as the frame is on the support beside the object where its ring shows
    a shadow, and the lines' estimates on that support taken out (capture.plate_shadow; cfg.shadow, cfg.support)."""
    if cfg.shadow == "off" or cfg.support is None or plate.method != "fixed":
        return plate.background, plate.known, estimated, None
    from capture.plate_shadow import lines_off_shadow, reach_box, shadow_relit, support_pixels

    s = cfg.support
    sup = support_pixels(scan.camera, s[:4], s[4:7], s[7], trimap.shape, reach_box(trimap))
    lit, rec = shadow_relit(image, plate.background, plate.known, trimap, sup)
    return lit, *lines_off_shadow(plate.known, estimated, sup, rec), rec


def _solve_at(image: np.ndarray, trimap: np.ndarray, method: str, mask: np.ndarray, cfg: MatteConfig) -> Matte:
    """:func:`solve_matte` at the resolution ``cfg`` asks (capture.matting_scale); a working solve that
    does not converge falls back to the full-size depth mask as the full-size one does."""
    from capture.matting_scale import matte_at_scale, working_scale

    scale = working_scale(trimap, cfg.depth_width) if cfg.resolution == "working" else 1.0
    if scale >= 1.0:
        return solve_matte(image, trimap, method, fallback=mask)
    alpha, fg, m = matte_at_scale(image, trimap, lambda i, t, b, k: solve_matte(i, t, method), scale)
    unknown = float(np.mean(trimap == UNKNOWN))
    if m is not None and "not converged" in m.method:
        a = np.asarray(mask, np.float32)
        return Matte(a, _foreground(image, a), f"{method} (not converged: depth mask)", unknown)
    return Matte(alpha, fg, method, unknown, 1.0 if m is None or m.alpha.shape == trimap.shape else scale)


def unmixed(image: np.ndarray, alpha: np.ndarray, background: np.ndarray, known: np.ndarray) -> np.ndarray:
    """(H, W, 3) float32 straight colour under a given ``alpha`` with the background known where
    ``known``: capture.matting_known.foreground_colour (exact where B is known, the nearest exact
    colours elsewhere), on the crop around alpha > 0."""
    from capture.matting_known import foreground_colour

    fg = np.asarray(image, np.float32).copy()
    box = _crop(np.where(np.asarray(alpha) > 0, UNKNOWN, BG))
    if box is not None:
        fg[box] = foreground_colour(np.asarray(image)[box], np.asarray(alpha)[box], np.asarray(background)[box],
                                    np.asarray(known)[box], lambda C, a, need: _foreground(C, a))
    return fg


def backdrop_noise(image: np.ndarray, trimap: np.ndarray, backdrop: np.ndarray) -> float:
    """Linear noise of a plain backdrop: the BACKDROP_NOISE_QUANTILE of its certain pixels' largest
    channel difference from ``backdrop``, at least one 8-bit sRGB step at black."""
    bg = np.asarray(image)[trimap == BG]
    d = channel_max(np.abs(bg - backdrop)) if len(bg) else np.zeros(1)
    return float(max(np.quantile(d, BACKDROP_NOISE_QUANTILE), NOISE_FLOOR))


def solve_known(image: np.ndarray, trimap: np.ndarray, background: np.ndarray, known: np.ndarray, noise: float,
                method: str, fallback: np.ndarray, cfg: MatteConfig | None = None, estimated=None) -> Matte:
    """Matte of linear ``image`` (H, W, 3) with the background (H, W, 3) known where ``known``
    (capture.matting_known), solved on the crop around the trimap's band and opaque pixels grown
    by the widening; not converged: alpha from the per-pixel fit (the method says so).  With
    ``cfg.resolution`` 'working' alpha is solved at capture.matting_scale's working scale
    (``known_matte_at_scale``: the colour still exact at full size where the background is known).
    ``estimated``: (where the background is the frames' lines' estimate (H, W), its uncertainty (H, W)
    or None) for the colour's per-pixel choice (capture.matting_colour; its record in the notes)."""
    from capture.matting_colour import colour_gate
    from capture.matting_known import foreground_colour, known_background_matte, widen_px
    from capture.matting_lines import LINES, refine_colour
    from capture.matting_scale import known_matte_at_scale, working_scale

    H, W = trimap.shape
    alpha = np.zeros((H, W), np.float32)
    fg = np.asarray(image, np.float32).copy()
    notes: dict = {}
    grown = dilate(trimap > BG, widen_px(W) + 1)  # ndimage.binary_dilation(..., iterations=...)
    box = _crop(np.where(grown, UNKNOWN, BG))
    if box is None:
        return Matte(alpha, fg, method, 0.0)
    scale = working_scale(trimap, cfg.depth_width) if cfg is not None and cfg.resolution == "working" else 1.0
    gate = None if estimated is None else colour_gate(
        np.asarray(estimated[0])[box], None if estimated[1] is None else np.asarray(estimated[1])[box], notes)
    chosen = {}
    if gate is not None:  # where the colour was unmixed, for the lines' colour (capture.matting_lines)
        gate = _kept(gate, chosen)
    chroma = cfg is not None and cfg.subsampled  # a JPEG's chroma (capture.jpeg_chroma)
    cov = cfg.source_coverage if cfg is not None and method == "plate" else None  # capture.matting_sources
    out = known_matte_at_scale(image, trimap, background, known, noise, scale, box, fallback, notes, chroma, cov) \
        if scale < 1.0 else None
    if out is None:  # full size: the reference (or a working copy with no opaque pixel left)
        scale = 1.0
        out = known_background_matte(np.asarray(image)[box], trimap[box], np.asarray(background)[box],
                                     np.asarray(known)[box], noise, np.asarray(fallback, bool)[box], notes, gate,
                                     chroma, cov)
    elif gate is not None:  # the working solve's colour unmixed every known pixel: the choice at full size
        ci, bi, ki, Fw = np.asarray(image)[box], np.asarray(background)[box], np.asarray(known)[box], out[1]
        out = (out[0], foreground_colour(ci, out[0], bi, gate(ci, out[0], bi, ki), lambda C, a, need: Fw, notes),
               *out[2:])
    a, F, tri, ok = out
    if estimated is not None and LINES:
        est_b, sig_b = (None if x is None else np.asarray(x)[box] for x in estimated)
        kb = np.asarray(known)[box]
        F = refine_colour(np.asarray(image)[box], a, np.asarray(background)[box], kb, est_b, sig_b, F,
                          chosen.get("known", kb), W, notes)
    alpha[box] = a
    fg[box] = F
    unknown = float(np.count_nonzero(tri == UNKNOWN)) / (H * W)
    return Matte(alpha, np.clip(fg, 0.0, None).astype(np.float32), method if ok else f"{method} (not converged)",
                 unknown, scale, notes)


def _kept(gate, out: dict):
    """``gate`` (capture.matting_colour.colour_gate's function) that also keeps its answer in ``out['known']``."""
    def kept(*args):
        out["known"] = gate(*args)
        return out["known"]

    return kept


def _foreground(image: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """ML foreground of ``image`` under a given ``alpha`` on the crop around alpha > 0."""
    from capture.foreground_ml import estimate_foreground_ml

    fg = np.asarray(image, np.float32).copy()
    box = _crop(np.where(alpha > 0, UNKNOWN, BG))
    if box is not None:
        fg[box] = estimate_foreground_ml(np.clip(np.asarray(image, np.float64)[box], 0, 1),
                                         np.asarray(alpha, np.float64)[box])
    return np.clip(fg, 0.0, None).astype(np.float32)


def warm_up() -> None:
    """Compile pymatting's numba kernels on a tiny image (tens of seconds once per process when
    numba's cache is cold), so that a timed matting stage measures matting alone."""
    img = np.random.default_rng(0).random((12, 12, 3))
    tri = np.full((12, 12), UNKNOWN)
    tri[:3], tri[-3:] = BG, FG
    solve_matte(img, tri, "estimate")


def closed_form_laplacian_reference(image: np.ndarray, epsilon: float = CF_EPSILON):
    """The matting Laplacian (Levin, Lischinski, Weiss 2008, 3x3 windows) of (h, w, 3) ``image``
    in [0, 1], built window by window in numpy: (h w, h w) scipy CSR.  Keep it small."""
    from scipy.sparse import coo_matrix

    h, w, _ = image.shape
    idx = np.arange(h * w).reshape(h, w)
    rows, cols, vals = [], [], []
    n = 9
    for y in range(1, h - 1):
        for x in range(1, w - 1):
            win = idx[y - 1:y + 2, x - 1:x + 2].ravel()
            c = image[y - 1:y + 2, x - 1:x + 2].reshape(n, 3)
            d = c - c.mean(0)
            cov = d.T @ d / n + (epsilon / n) * np.eye(3)
            g = (1 + d @ np.linalg.inv(cov) @ d.T) / n
            rows.append(np.repeat(win, n))
            cols.append(np.tile(win, n))
            vals.append((np.eye(n) - g).ravel())
    return coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), (h * w, h * w)).tocsr()


def closed_form_alpha_reference(image: np.ndarray, trimap: np.ndarray, epsilon: float = CF_EPSILON) -> np.ndarray:
    """Slow reference of the closed-form matte: :func:`closed_form_laplacian_reference`, then
    L_U a_U = -R a_K with the known pixels fixed (as pymatting solves it), by a sparse direct
    solve.  (h, w, 3) ``image`` in [0, 1]; keep it small."""
    from scipy.sparse.linalg import spsolve

    h, w, _ = image.shape
    L = closed_form_laplacian_reference(image, epsilon)
    t = trimap.ravel()
    unk = t == UNKNOWN
    a = t.astype(np.float64).copy()
    a[unk] = spsolve(L[unk][:, unk].tocsc(), -L[unk][:, ~unk] @ (t[~unk] >= FG))
    return np.clip(a.reshape(h, w), 0.0, 1.0)

"""Every capture layout as a source of the same frames: cameras first, then each frame read on demand.

A :class:`Source` is what a capture says before any image is read: one :class:`FrameRef` per
frame (its pinhole camera, the camera as captured and its lens, the paths of its colour, depth,
confidence and matte files, its depth unit), the bounds the capture gives (or None) and its
metadata.  ``transforms.json`` (capture.io), a plain folder (capture.io) and a COLMAP model
(capture.io_colmap) each open as one; :func:`open_source` tells them apart.

A frame is then read by the same five steps whatever the layout, in this order (the first five
stages of the model pipeline, volume/pipeline/stages.py, which lists these very functions):

1. :func:`read_images`: the colour image, the stored depth values and the confidence image.
2. :func:`depth_units`: depth to metres (``depth_unit_scale_factor``), low confidence removed.
3. :func:`resample_depth`: a depth map smaller than the colour is resampled to it edge-aware
   (capture.resample); the frame becomes a :class:`capture.scan.Scan` of the captured camera.
4. :func:`read_matte`: the matte (``mask_path``, ``masks/NAME.png``, or the colour image's alpha;
   capture.matte_io) at the captured size.
5. :func:`undistort`: a frame with a lens is resampled to its pinhole camera (capture.lens).

Each step is a plain top-level function ``step(view, ref, cfg) -> (view, note)`` (picklable, for a
process pool): ``view`` is what the previous step made, ``ref`` the frame, ``cfg`` the step's own
config, ``note`` what the step wants said about the frame (or None), gathered by
:func:`finish_scanset` into the scan set's metadata.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from capture.camera import Camera
from capture.imageio import ScanIOError, read_color, read_confidence, read_depth_raw
from capture.lens import DEFAULT_UNDISTORT, UNDISTORT_MODES, Lens, undistort_scan
from capture.resample import MIN_CONFIDENCE
from capture.scan import Scan, ScanError, ScanSet, select_indices

#: Suffixes tried, in order, when a frame's file path names no existing file (a stem).
FILE_SUFFIXES = (".png", ".jpg", ".jpeg", ".exr", ".npy")
#: A colour image whose every pixel and channel lies within this many 8-bit levels (of 255 for a float image) of
#: one value is a blank frame (a dropped frame, a lens cap): refused like an all-zero depth.  Kept silently, one
#: black frame among 36 cost its two neighbouring held-out views 3.3 and 4.7 dB (path-traced fur, stop 64).
BLANK_LEVELS = 1
#: Every this-th row and column is looked at first: where they span more than BLANK_LEVELS the frame is not blank
#: (the whole frame spans at least as much), so only a blank-looking sample costs a pass over the whole frame.
BLANK_STRIDE = 16


@dataclass(frozen=True)
class FrameRef:
    """One frame of a capture, known before any image is read (plain values: picklable).

    Attributes:
        index: position in the capture (0-based, capture order).
        name: the frame's name (transforms.json ``file_path``, COLMAP image name, plain-folder stem).
        camera: the pinhole camera the frame ends up with (OpenCV convention; undistorted when
            ``lens`` is set, else the camera as captured).
        captured: the camera as captured (its images' size and intrinsics).
        lens: lens distortion of ``captured`` (capture.lens), None for a pinhole camera.
        rgb: colour image path (a stem is completed with FILE_SUFFIXES when read).
        depth: depth file path, or None (no depth: zeros).
        confidence: confidence image path (8-bit, the depth's size), or None.
        mask: matte image path, or None (then the colour image's own alpha, if any).
        depth_unit: metres per stored depth unit; None = float depth in metres.
        units_from: the file that should give ``depth_unit`` (named when it is missing).
        where: how errors name the frame (e.g. "PATH/transforms.json frame 3").
    """

    index: int
    name: str
    camera: Camera
    captured: Camera
    lens: Lens | None
    rgb: Path
    depth: Path | None
    confidence: Path | None = None
    mask: Path | None = None
    depth_unit: float | None = None
    units_from: str = ""
    where: str = ""

    @property
    def distorted(self) -> Camera | None:
        """The captured camera when it has a lens (else None)."""
        return self.captured if self.lens is not None else None


@dataclass(frozen=True)
class Source:
    """A capture before its images are read.

    Attributes:
        path: the capture (transforms.json, plain folder or COLMAP folder).
        format: 'transforms.json', 'plain-folder' or 'colmap'.
        frames: every frame, in capture order.
        bounds: (2, 3) float64 object bounds the capture gives (metres), or None (derived from the depth).
        metadata: the capture's own metadata (provenance, generator, ...).
        undistort: the undistortion mode the pinhole cameras were made with (capture.lens).
        fallback_bounds: bounds when no frame has depth (COLMAP: from its 3-D points), or None.
    """

    path: Path
    format: str
    frames: tuple[FrameRef, ...]
    bounds: np.ndarray | None = None
    metadata: dict = field(default_factory=dict, compare=False)
    undistort: str = DEFAULT_UNDISTORT
    fallback_bounds: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.frames)

    @property
    def cameras(self) -> list[Camera]:
        return [f.camera for f in self.frames]

    def select(self, spec: str | None) -> Source:
        """The source of the frames picked by a slice spec (capture.scan.select_indices)."""
        if not spec:
            return self
        idx = select_indices(spec, len(self.frames))
        return replace(self, frames=tuple(self.frames[i] for i in idx), metadata={**self.metadata, "frames": spec})


@dataclass(frozen=True)
class RawFrame:
    """A frame as its files hold it, before it is a Scan.

    Attributes:
        rgb: (H, W, 3) uint8 sRGB (or float32 linear) at the captured camera's size.
        depth: (h, w) depth: stored values (integer units or float), metres once ``metres``.
        confidence: (h, w) confidence as stored, or None.
        metres: the depth is in metres (the units step has run).
        depth_path: the depth file (named in errors), or None.
    """

    rgb: np.ndarray
    depth: np.ndarray
    confidence: np.ndarray | None = None
    metres: bool = False
    depth_path: Path | None = None


# ------------------------------------------------------------------------------- step configs
@dataclass(frozen=True)
class ReadConfig:
    """Settings of the read stage."""

    frames: str | None = None
    """Frames read, python-slice style (``--frames``: '0::2', '3', '1,4,7'); None = every frame."""


@dataclass(frozen=True)
class UnitsConfig:
    """Settings of the units-and-confidence stage."""

    min_confidence: float = MIN_CONFIDENCE
    """Depth is kept where its confidence reaches this fraction of the highest level (capture.resample)."""

    def __post_init__(self) -> None:
        if not 0 <= self.min_confidence <= 1:
            raise ValueError(f"min_confidence must be in [0, 1], got {self.min_confidence}")


@dataclass(frozen=True)
class ResampleConfig:
    """Settings of the depth-resample stage: none to set.  A depth map smaller than the colour is
    always resampled edge-aware, guided by the colour (capture.resample.upsample_depth; its rule's
    constants are capture/resample.py's); a depth map of the colour's size passes unchanged."""


@dataclass(frozen=True)
class MatteReadConfig:
    """Settings of the matte-read stage."""

    rgba_alpha: bool = True
    """A colour image's alpha channel is the frame's matte when no mask file is named (capture.matte_io)."""


@dataclass(frozen=True)
class UndistortConfig:
    """Settings of the undistort stage."""

    mode: str = DEFAULT_UNDISTORT
    """``--undistort``: 'keep' (the camera matrix kept: one resampling, no rescale), 'crop' (every pixel
    valid, as nerfstudio) or 'full' (every source pixel kept); capture.lens."""

    def __post_init__(self) -> None:
        if self.mode not in UNDISTORT_MODES:
            raise ValueError(f"--undistort must be one of {', '.join(UNDISTORT_MODES)}, got {self.mode!r}")


# ------------------------------------------------------------------------------- the steps
def resolve_file(path: Path, what: str, where: str) -> Path:
    """``path`` when it is a file, else the path with the first FILE_SUFFIXES suffix that is one;
    ScanIOError naming ``path``, ``what`` and ``where`` otherwise."""
    p = Path(path)
    if p.is_file():
        return p
    for ext in FILE_SUFFIXES:
        c = p.with_name(p.name + ext)
        if c.is_file():
            return c
    raise ScanIOError(f"{p}: {what} not found (referenced by {where})")


def read_images(view, ref: FrameRef, cfg: ReadConfig) -> tuple[RawFrame, None]:
    """Step 1: the colour image (its size checked against the captured camera), the stored depth
    values (zeros without a depth file) and the confidence image."""
    rgb_path = resolve_file(ref.rgb, "colour image", ref.where)
    rgb = read_color(rgb_path)
    cam = ref.captured
    if rgb.shape[:2] != (cam.height, cam.width):
        raise ScanIOError(f"{rgb_path}: image is {rgb.shape[1]}x{rgb.shape[0]} but its camera ({ref.where}) "
                          f"says {cam.width}x{cam.height}")
    level = BLANK_LEVELS / (1.0 if rgb.dtype == np.uint8 else 255.0)
    sample = rgb[::BLANK_STRIDE, ::BLANK_STRIDE]  # a frame with any contrast shows it here: no full pass
    lo, hi = (float(sample.min()), float(sample.max())) if sample.max() - sample.min() > level else \
        (float(rgb.min()), float(rgb.max()))
    if hi - lo <= level:
        raise ScanIOError(f"{rgb_path}: colour image is blank (every pixel {lo:.4g} to {hi:.4g}): a dropped frame? "
                          "leave it out (furrow model --frames, or remove it from the capture)")
    if ref.depth is None:
        return RawFrame(rgb, np.zeros((cam.height, cam.width), np.float32), None, True), None
    depth_path = resolve_file(ref.depth, "depth file", ref.where)
    conf = None
    if ref.confidence is not None:
        conf = read_confidence(resolve_file(ref.confidence, "confidence file", ref.where))
    return RawFrame(rgb, read_depth_raw(depth_path), conf, False, depth_path), None


def depth_metres(raw: np.ndarray, unit: float | None, path: Path, units_from: str = "") -> np.ndarray:
    """Depth in metres; ``units_from`` names the file that should give the unit (for the error)."""
    if np.issubdtype(raw.dtype, np.integer):
        if unit is None:
            src = f" in {units_from}" if units_from else ""
            raise ScanIOError(f"{path}: integer depth image but no depth_unit_scale_factor{src}: unknown units "
                              "(add \"depth_unit_scale_factor\": 0.001 for millimetres)")
        d = raw.astype(np.float64) * unit
    else:
        d = raw.astype(np.float64) * (1.0 if unit is None else unit)
    bad = ~np.isfinite(d) | (d < 0)
    d[bad] = 0.0
    return d.astype(np.float32)


def depth_units(view: RawFrame, ref: FrameRef, cfg: UnitsConfig) -> tuple[RawFrame, None]:
    """Step 2: the depth in metres; samples whose confidence is below ``cfg.min_confidence`` removed."""
    from capture.resample import ResampleError, confidence_mask

    if view.metres:
        return view, None
    depth = depth_metres(view.depth, ref.depth_unit, view.depth_path, ref.units_from)
    if view.confidence is not None:
        if view.confidence.shape != depth.shape:
            c = view.confidence.shape
            raise ScanIOError(f"{ref.confidence}: confidence is {c[1]}x{c[0]} but its depth {view.depth_path.name} "
                              f"is {depth.shape[1]}x{depth.shape[0]}")
        try:
            depth = np.where(confidence_mask(view.confidence, cfg.min_confidence), depth, 0.0).astype(np.float32)
        except ResampleError as e:
            raise ScanIOError(f"{ref.confidence}: {e}") from None
    return RawFrame(view.rgb, depth, None, True, view.depth_path), None


def resample_depth(view: RawFrame, ref: FrameRef, cfg: ResampleConfig):
    """Step 3: the Scan of the captured camera; a depth map smaller than the colour is resampled
    to it (note: its capture.resample.ResampleStats; None when the sizes already agree)."""
    from capture.resample import ResampleError, guide_from_colour, upsample_depth

    cam, depth, stats = ref.captured, view.depth, None
    if view.depth_path is not None and depth.shape != (cam.height, cam.width):
        if depth.shape[0] > cam.height or depth.shape[1] > cam.width:
            raise ScanIOError(f"{view.depth_path}: depth is {depth.shape[1]}x{depth.shape[0]}, larger than the colour "
                              f"image and camera ({cam.width}x{cam.height}); resize the depth to the colour")
        try:
            depth, stats = upsample_depth(depth, guide_from_colour(view.rgb))
        except ResampleError as e:
            raise ScanIOError(f"{view.depth_path}: {e}") from None
    if view.depth_path is not None and not np.any(depth > 0):
        raise ScanIOError(f"{view.depth_path}: depth is all zero (no measurement at all)")
    try:
        return Scan(view.rgb, depth, cam, ref.name), stats
    except ScanError as e:
        raise ScanIOError(f"{resolve_file(ref.rgb, 'colour image', ref.where)}: {e}") from None


def read_matte(view: Scan, ref: FrameRef, cfg: MatteReadConfig) -> tuple[Scan, None]:
    """Step 4: the frame's matte (capture.matte_io) at the captured size: its mask file, else
    (``cfg.rgba_alpha``) the colour image's alpha channel; the scan unchanged without either."""
    from capture.matte_io import read_matte as read_mask
    from capture.matte_io import rgba_alpha

    if ref.mask is not None:
        alpha = read_mask(ref.mask, view.depth.shape)
    elif cfg.rgba_alpha:
        alpha = rgba_alpha(resolve_file(ref.rgb, "colour image", ref.where))
    else:
        alpha = None
    if alpha is None:
        return view, None
    try:
        return Scan(view.rgb, view.depth, view.camera, view.name, alpha), None
    except ScanError as e:
        raise ScanIOError(f"{ref.where}: {e}") from None


def undistort(view: Scan, ref: FrameRef, cfg: UndistortConfig):
    """Step 5: a frame with a lens resampled to its pinhole camera (capture.lens.undistort_scan;
    note: the lens); a pinhole frame unchanged."""
    if ref.lens is None:
        return view, None
    return undistort_scan(view, ref.lens, ref.captured.K, ref.camera), ref.lens


#: The steps that read a frame, in order, with the name of each one's stage (volume/pipeline/stages.py).
FRAME_STEPS = (("read", read_images), ("units and confidence", depth_units), ("depth resample", resample_depth),
               ("matte read", read_matte), ("undistort", undistort))
#: The config class of each step, in FRAME_STEPS order.
STEP_CONFIGS = (ReadConfig, UnitsConfig, ResampleConfig, MatteReadConfig, UndistortConfig)


def read_frame(ref: FrameRef, configs=None) -> tuple[Scan, list]:
    """(the frame as a Scan, the steps' notes in FRAME_STEPS order): every step of FRAME_STEPS in
    turn, each with its config from ``configs`` (default: the defaults)."""
    configs = configs or tuple(c() for c in STEP_CONFIGS)
    view, notes = None, []
    for (_, step), cfg in zip(FRAME_STEPS, configs, strict=True):
        view, note = step(view, ref, cfg)
        notes.append(note)
    return view, notes


# ------------------------------------------------------------------------------- opening and finishing
def open_source(path: Path, undistort: str = DEFAULT_UNDISTORT) -> Source:
    """The source of a capture: transforms.json (the file or a folder holding one), a plain folder
    (``cameras/``, ``rgb/``, ``depth/``) or a COLMAP folder (``sparse/0`` + ``images/``); its
    cameras are read, none of its images.  ``undistort`` makes the pinhole cameras of frames with a lens."""
    from capture import io

    UndistortConfig(undistort)
    path = Path(path)
    if path.is_dir() and not (path / io.TRANSFORMS).is_file():
        if (path / "cameras").is_dir():
            return io.plain_source(path, undistort)
        for model in (path / "sparse" / "0", path / "sparse", path):
            if (model / "cameras.bin").is_file() or (model / "cameras.txt").is_file():
                from capture.io_colmap import colmap_folder_source

                return colmap_folder_source(path, model, undistort)
        raise ScanIOError(f"{path}: neither a {io.TRANSFORMS}, a plain folder layout (cameras/, rgb/, depth/) "
                          "nor a COLMAP layout (sparse/0/, images/, depth/)")
    return io.transforms_source(path, undistort)


def finish_scanset(source: Source, scans, notes_per_step: dict | None = None, sample=None) -> ScanSet:
    """The ScanSet of ``scans`` (read from ``source``): the capture's bounds, else the robust box of
    the depth (capture.io.auto_bounds; ``sample``: its depth points' sampler, default in this process),
    else ``source.fallback_bounds``; its metadata with what the steps noted (``notes_per_step``: step
    name -> one note per frame): depth resampled, frames undistorted."""
    from capture.io import auto_bounds
    from capture.io_lens import note_undistorted
    from capture.resample import describe

    notes_per_step = notes_per_step or {}
    md = {**source.metadata, "source": source.metadata.get("source", str(source.path)), "format": source.format}
    resampled = [n for n in notes_per_step.get("depth resample", ()) if n is not None]
    if resampled:
        import logging

        line = describe(resampled)
        logging.getLogger("furrow.capture").info(line)
        md.update(depth_resampled=line, depth_size=list(resampled[0].depth_size))  # (w, h) the sensor measured
    note_undistorted(list(notes_per_step.get("undistort", ())), source.undistort, md)
    bounds = source.bounds
    if bounds is None:
        has_depth = any(f.depth is not None for f in source.frames)
        bounds = auto_bounds(scans, str(source.path), sample) if has_depth or source.fallback_bounds is None \
            else source.fallback_bounds
    try:
        return ScanSet(tuple(scans), bounds, md)
    except ScanError as e:
        raise ScanIOError(f"{source.path}: {e}") from None


def read_source(source: Source, progress=None, keep=None, configs=None) -> ScanSet:
    """Every frame of ``source`` read by :func:`read_frame` (one at a time, each handed to ``keep``
    as soon as it is read: capture.scan_store) as a ScanSet (:func:`finish_scanset`)."""
    from capture.scan_store import keep_in_memory

    keep = keep or keep_in_memory
    scans, notes = [], {name: [] for name, _ in FRAME_STEPS}
    for ref in (progress(source.frames, "reading scans") if progress else source.frames):
        scan, frame_notes = read_frame(ref, configs)
        for (name, _), n in zip(FRAME_STEPS, frame_notes, strict=True):
            notes[name].append(n)
        scans.append(keep(scan))
    return finish_scanset(source, scans, notes)

"""Scan sets on disk: nerfstudio ``transforms.json`` (the default) and a plain folder layout.

transforms.json (docs/design.md "Scan format on disk"): per frame ``file_path``,
``depth_file_path``, ``transform_matrix`` (camera-to-world, OpenGL axes); intrinsics
``fl_x fl_y cx cy w h`` globally or per frame, with pixel centres at i + 0.5 (the reader
subtracts 0.5, the writer adds it back: all conversions live in ``capture.camera``);
``depth_unit_scale_factor`` = metres per stored depth unit (16-bit PNG in mm: 0.001),
globally or per frame (read both ways; written once, at the top level, as nerfstudio's
dataparser takes the scale from its own ``--depth-unit-scale-factor`` option, default 1e-3, and
ignores per-frame keys: furrow's default millimetre PNG opens there at the right depth).
Float EXR depth is in metres when no factor is given; a 16-bit PNG
without a factor is an error (unknown units).  Depth is z-depth, 0 = no measurement.
Lens distortion (``camera_model`` OPENCV / OPENCV_FISHEYE) is undistorted at read time (capture.lens).
furrow adds an optional ``furrow`` block: ``{"bounds": [[x,y,z],[x,y,z]], "metadata": {...}}``.

Phone and RGB-D captures as they come (Polycam, Record3D, ARKit): colour may be JPEG; a depth map
smaller than its colour image over the same field of view (e.g. 256x192 beside 1920x1440) is
resampled to the colour camera edge-aware (``capture.resample``; logged on logger ``furrow`` and
noted in the metadata); an optional per-frame ``confidence_file_path`` (plain folder:
``confidence/NAME.png``), 8-bit at the depth's size, removes low-confidence depth before that.

Plain folder layout: ``rgb/NAME.png``, ``depth/NAME.png|.exr``, ``cameras/NAME.json`` with
``K`` (OpenCV, pixel centres at integers), ``cam_from_world`` (OpenCV 4x4), ``width``,
``height``, ``depth_unit_scale_factor`` and optionally a lens (``camera_model`` and its
coefficients, as in transforms.json); optional ``confidence/NAME.png``, ``masks/NAME.png`` (the
matte, read as transforms.json's ``mask_path``) and ``bounds.json``.

Every layout opens as a :class:`capture.sources.Source` (cameras first, no image read) and every
frame is read by the same steps (capture.sources: read, units and confidence, depth resample,
matte read, undistort), so mattes, lenses, confidence and spilling work alike for all three.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from capture.atomic import atomic_dir, jsonable
from capture.camera import Camera, CameraError
from capture.imageio import ScanIOError, depth_to_uint16, finite_number, write_exr, write_png
from capture.io_lens import frame_lens, pinhole_camera
from capture.lens import DEFAULT_UNDISTORT, Lens, nerfstudio_keys
from capture.matte_io import MASK_DIR, write_matte
from capture.resample import nearest_depth
from capture.scan import Scan, ScanSet, bounds_from_points, sampled_points
from capture.sources import FrameRef, Source, UndistortConfig, open_source

TRANSFORMS = "transforms.json"
#: Percentiles of the back-projected depth used for automatic bounds (robust to outliers).
AUTO_BOUNDS_PERCENTILES = (0.5, 99.5)
#: Margin added around automatic bounds, as a fraction of their diagonal.
AUTO_BOUNDS_MARGIN = 0.05
#: Default 16-bit PNG depth unit written by furrow: millimetres (RGB-D sensors' z16 unit, and
#: nerfstudio's default ``--depth-unit-scale-factor``).
DEFAULT_PNG_DEPTH_UNIT = 0.001
#: Depth formats of the writers: name -> (file extension, metres per stored unit; None = the
#: ``png_depth_unit`` argument).  ``png``: 16-bit millimetres (default, range 65.5 m);
#: ``png-0.1mm``: 16-bit tenths of a millimetre (range 6.5 m, 0.03 mm RMS quantisation);
#: ``exr``: float32 metres (unit 1).
DEPTH_FORMATS = {"png": ("png", None), "png-0.1mm": ("png", 1e-4), "exr": ("exr", 1.0)}

__all__ = ["ScanIOError", "read_scanset", "read_cameras", "write_transforms", "write_plain_folder",
           "resolve_transforms", "DEPTH_FORMATS", "depth_format_spec", "transforms_source", "plain_source"]


def resolve_transforms(path: Path) -> Path:
    """A transforms.json path, or a folder containing one -> the file; error otherwise."""
    path = Path(path)
    if path.is_dir():
        cand = path / TRANSFORMS
        if cand.is_file():
            return cand
        raise ScanIOError(f"{path}: folder has no {TRANSFORMS}")
    if not path.exists():
        raise ScanIOError(f"{path}: no such file or folder")
    return path


def _load_json(path: Path) -> dict:
    try:
        data = json.loads(Path(path).read_bytes())
    except (json.JSONDecodeError, UnicodeDecodeError, RecursionError) as e:
        raise ScanIOError(f"{path}: invalid JSON ({type(e).__name__}: {str(e)[:120]})") from None
    except OSError as e:
        raise ScanIOError(f"{path}: cannot read ({e.strerror})") from None
    if not isinstance(data, dict):
        raise ScanIOError(f"{path}: expected a JSON object at the top level")
    return data


def transforms_source(path: Path, undistort: str = DEFAULT_UNDISTORT) -> Source:
    """The Source of a transforms.json (file or folder): its cameras (undistorted: capture.lens),
    file paths, units and mattes, parsed once; no image is read."""
    tj = resolve_transforms(path)
    meta = _load_json(tj)
    frames = meta.get("frames")
    if not isinstance(frames, list) or not frames:
        raise ScanIOError(f"{tj}: 'frames' must be a non-empty list")
    refs = tuple(_transforms_frame(tj, meta, i, fr, undistort) for i, fr in enumerate(frames))
    fblock = meta.get("furrow", {}) if isinstance(meta.get("furrow"), dict) else {}
    bounds = _read_bounds(fblock.get("bounds"), f"{tj} furrow.bounds")
    md = fblock.get("metadata", {})
    md = dict(md) if isinstance(md, dict) else {}
    md.update(source=str(tj), format="transforms.json")
    return Source(tj, "transforms.json", refs, bounds, md, undistort)


def _transforms_frame(tj: Path, meta: dict, i: int, fr, undistort: str) -> FrameRef:
    """One frame of a transforms.json as a FrameRef (module docstring)."""
    where = f"{tj} frame {i}"
    if not isinstance(fr, dict) or "file_path" not in fr:
        raise ScanIOError(f"{where}: missing 'file_path'")
    paths = {k: _path_field(fr, k, where) for k in ("file_path", "depth_file_path", "confidence_file_path")}
    mask = fr.get("mask_path")
    if mask is not None and (not isinstance(mask, str) or not mask.strip()):
        raise ScanIOError(f"{where}: 'mask_path' must be a non-empty file path string, got {mask!r}")
    named = f"{where} ({paths['file_path']})"

    def get(key):
        v = fr.get(key, meta.get(key))
        if v is None:
            raise ScanIOError(f"{named}: missing intrinsic '{key}' (per frame or global)")
        return finite_number(v, f"intrinsic '{key}'", named)

    if "transform_matrix" not in fr:
        raise ScanIOError(f"{named}: missing 'transform_matrix'")
    try:
        tm = np.asarray(fr["transform_matrix"], dtype=np.float64)
    except (TypeError, ValueError):
        raise ScanIOError(f"{named}: 'transform_matrix' is not a 4x4 number matrix") from None
    try:
        w, h = _pixels(get("w"), "w", named), _pixels(get("h"), "h", named)
        cam = Camera.from_nerfstudio(tm, *_intrinsics(fr, meta, named, get, w, h), w, h, name=paths["file_path"])
    except CameraError as e:
        raise ScanIOError(f"{named}: {e}") from None
    lens = frame_lens(fr, meta, named)
    pinhole = cam if lens is None else pinhole_camera(cam, lens, undistort, named)
    unit = fr.get("depth_unit_scale_factor", meta.get("depth_unit_scale_factor"))
    if unit is not None:
        unit = finite_number(unit, "depth_unit_scale_factor", named)
        if unit <= 0:
            raise ScanIOError(f"{named}: depth_unit_scale_factor must be a positive number (metres per "
                              f"depth unit), got {unit}")

    def file(rel):
        return None if rel is None else (Path(rel) if Path(rel).is_absolute() else tj.parent / rel)

    return FrameRef(i, paths["file_path"], pinhole, cam, lens, file(paths["file_path"]), file(paths["depth_file_path"]),
                    file(paths["confidence_file_path"]), file(mask), unit, str(tj), where)


def _intrinsics(fr: dict, meta: dict, named: str, get, w: int, h: int) -> tuple[float, float, float, float]:
    """(fl_x, fl_y, cx, cy) of a frame, in nerfstudio's units.  Where fl_x is absent, from ``camera_angle_x`` (the
    horizontal field of view in radians, as the NeRF synthetic and instant-ngp layouts give it); fl_y from
    ``camera_angle_y``, else fl_x (square pixels) when fl_y is absent too; cx, cy the image centre (w / 2, h / 2)
    when absent, as instant-ngp takes them.  A frame with neither fl_x nor camera_angle_x names fl_x missing."""
    def has(key):
        return fr.get(key, meta.get(key)) is not None

    def from_angle(key, size):
        a = finite_number(fr.get(key, meta.get(key)), f"'{key}'", named)
        if not 0 < a < np.pi:
            raise ScanIOError(f"{named}: '{key}' must be a field of view in radians in (0, pi), got {a}")
        return 0.5 * size / np.tan(0.5 * a)

    fx = get("fl_x") if has("fl_x") or not has("camera_angle_x") else from_angle("camera_angle_x", w)
    fy = get("fl_y") if has("fl_y") else from_angle("camera_angle_y", h) if has("camera_angle_y") else fx
    cx = get("cx") if has("cx") else w / 2.0
    cy = get("cy") if has("cy") else h / 2.0
    return fx, fy, cx, cy


def _path_field(fr: dict, key: str, where: str) -> str | None:
    """A frame's relative / absolute file path: a non-empty string, or None when absent (file_path is required)."""
    v = fr.get(key)
    if v is None and key != "file_path":
        return None
    if not isinstance(v, str) or not v.strip() or "\0" in v:
        raise ScanIOError(f"{where}: '{key}' must be a non-empty file path string, got {v!r}")
    return v


#: Largest image side accepted from a camera description (pixels).
MAX_IMAGE_SIDE = 65536


def _pixels(v: float, key: str, where: str) -> int:
    """An image size: a whole number of pixels in 1..MAX_IMAGE_SIDE."""
    if v != int(v) or not 1 <= v <= MAX_IMAGE_SIDE:
        raise ScanIOError(f"{where}: image size '{key}' must be a whole number of pixels in 1..{MAX_IMAGE_SIDE}, "
                          f"got {v!r}")
    return int(v)


def plain_source(folder: Path, undistort: str = DEFAULT_UNDISTORT) -> Source:
    """The Source of the plain folder layout (module docstring): cameras, lenses, units and
    mattes (``masks/NAME.png``) of every frame; no image is read."""
    folder = Path(folder)
    cam_dir = folder / "cameras"
    files = sorted(cam_dir.glob("*.json"))
    if not files:
        raise ScanIOError(f"{cam_dir}: no camera JSON files")
    refs = tuple(_plain_frame(folder, i, cj, undistort) for i, cj in enumerate(files))
    bj = folder / "bounds.json"
    bounds = _read_bounds(_load_json(bj).get("bounds"), str(bj)) if bj.is_file() else None
    return Source(folder, "plain-folder", refs, bounds, {"source": str(folder), "format": "plain-folder"}, undistort)


def _plain_frame(folder: Path, i: int, cj: Path, undistort: str) -> FrameRef:
    """One camera JSON of the plain folder layout as a FrameRef."""
    c = _load_json(cj)
    try:
        cam = Camera(np.asarray(c["K"], float), np.asarray(c["cam_from_world"], float),
                     _pixels(finite_number(c["width"], "width", str(cj)), "width", str(cj)),
                     _pixels(finite_number(c["height"], "height", str(cj)), "height", str(cj)), name=cj.stem)
    except KeyError as e:
        raise ScanIOError(f"{cj}: missing key {e}") from None
    except (CameraError, TypeError, ValueError) as e:
        raise ScanIOError(f"{cj}: {e}") from None
    unit = c.get("depth_unit_scale_factor")
    if unit is not None and finite_number(unit, "depth_unit_scale_factor", str(cj)) <= 0:
        raise ScanIOError(f"{cj}: depth_unit_scale_factor must be a positive number of metres, got {unit!r}")
    lens = frame_lens(c, {}, str(cj))
    pinhole = cam if lens is None else pinhole_camera(cam, lens, undistort, str(cj))
    conf = folder / "confidence" / cj.stem if (folder / "confidence").is_dir() else None
    mask = folder / MASK_DIR / f"{cj.stem}.png"
    return FrameRef(i, cj.stem, pinhole, cam, lens, folder / "rgb" / cj.stem, folder / "depth" / cj.stem, conf,
                    mask if mask.is_file() else None, None if unit is None else float(unit), str(cj), str(cj))


def auto_bounds(scans, where: str = "", sample=None) -> np.ndarray:
    """Robust (2, 3) bounds from the back-projected depth of every scan; ``where`` (the scan set's
    file or folder) prefixes the error when there are none.  Above AUTO_BOUNDS_MAX_POINTS depth
    pixels in all, a regular sample of them (capture.scan.sampled_points, or ``sample(scans)`` that
    gives the same points: the pipeline's views mapped over its pool, capture.extent.mapped_sampled_points)."""
    prefix = f"{where}: " if where else ""
    pts = (sample or sampled_points)(scans)
    pts = finite_rows(pts)
    if len(pts) == 0:
        raise ScanIOError(f"{prefix}cannot derive object bounds: no scan has depth; "
                          "give \"furrow\": {\"bounds\": ...}")
    with np.errstate(over="ignore", invalid="ignore"):
        # one partition, in place (the points are this call's own: ``sample`` makes them): the same two rows
        lo, hi = np.percentile(pts, AUTO_BOUNDS_PERCENTILES, axis=0, overwrite_input=True)
    with np.errstate(over="ignore", invalid="ignore"):
        b = bounds_from_points(np.stack([lo, hi]), AUTO_BOUNDS_MARGIN)
    if not (np.all(np.isfinite(b)) and np.all(b[1] > b[0])):
        raise ScanIOError(f"{prefix}cannot derive object bounds from the depth: the back-projected points span "
                          f"{np.stack([lo, hi]).tolist()} (camera poses or depth out of range?)")
    return b


def finite_rows(pts: np.ndarray) -> np.ndarray:
    """``pts[np.all(np.isfinite(pts), axis=1)]`` of (N, 3) points, by the three columns' tests (numpy's
    reduction over a short last axis ran a loop per row: 0.5 s of 8 million points) and ``pts`` itself
    when every row is finite (the same values, no copy)."""
    fin = np.isfinite(pts)
    if pts.ndim != 2 or pts.shape[1] != 3:
        return pts[np.all(fin, axis=1)]
    ok = fin[:, 0] & fin[:, 1] & fin[:, 2]
    return pts if ok.all() else pts[ok]


def _read_bounds(block, where: str):
    if block is None:
        return None
    try:
        b = np.asarray(block, dtype=np.float64)
    except (TypeError, ValueError):
        raise ScanIOError(f"{where}: bounds must be [[xmin,ymin,zmin],[xmax,ymax,zmax]]") from None
    if b.shape != (2, 3) or not np.all(np.isfinite(b)) or np.any(b[1] <= b[0]):
        raise ScanIOError(f"{where}: bounds must be a finite [[min],[max]] box with max > min, got {block}")
    return b


def read_cameras(path: Path, undistort: str = DEFAULT_UNDISTORT) -> tuple[FrameRef, ...]:
    """The frames of a capture (any layout, capture.sources.open_source) without reading any image:
    each one's pinhole ``camera`` (undistorted: capture.lens), ``captured`` camera and ``lens``."""
    return open_source(path, undistort).frames


def read_scanset(path: Path, frames: str | None = None, progress=None, undistort: str = DEFAULT_UNDISTORT,
                 keep=None) -> ScanSet:
    """Read a scan set: transforms.json (file or folder holding one), a plain folder, or a COLMAP
    folder (``sparse/0`` + ``images/`` + optional ``depth/``, ``masks/`` and ``depth_units.json``),
    every frame by the same steps (capture.sources).  ``keep``: each scan is passed through it as
    soon as it is read (capture.scan_store.ScanSpill.keep puts it on disk)."""
    from capture.sources import STEP_CONFIGS, read_source

    source = open_source(path, undistort).select(frames)
    configs = tuple(c() for c in STEP_CONFIGS[:-1]) + (UndistortConfig(undistort),)
    return read_source(source, progress, keep, configs)


# --------------------------------------------------------------------------- writing
def atomic_folder(target: Path, overwrite: bool = False):
    """``with atomic_folder(out) as tmp:`` write into ``tmp``; it becomes ``out`` on success only
    (``capture.atomic.atomic_dir``). An existing ``out`` is an error unless ``overwrite``."""
    if Path(target).exists() and not overwrite:
        raise ScanIOError(f"{target}: already exists (choose another output or allow overwrite)")
    return atomic_dir(target)


def depth_format_spec(depth_format: str, png_depth_unit: float = DEFAULT_PNG_DEPTH_UNIT) -> tuple[str, float]:
    """(file extension, metres per stored unit) of a :data:`DEPTH_FORMATS` name; ``png_depth_unit``
    is the unit of plain ``png``.  ValueError naming the choices otherwise."""
    if depth_format not in DEPTH_FORMATS:
        raise ValueError(f"depth_format must be one of {', '.join(DEPTH_FORMATS)}, got {depth_format!r}")
    ext, unit = DEPTH_FORMATS[depth_format]
    unit = float(png_depth_unit) if unit is None else unit
    if not (np.isfinite(unit) and unit > 0):
        raise ValueError(f"PNG depth unit must be a positive number of metres, got {unit}")
    return ext, unit


def _write_images(scan: Scan, rgb_path: Path, depth_path: Path, ext: str, unit: float, depth_size=None) -> None:
    write_png(rgb_path, scan.srgb8)
    depth = scan.depth
    if depth_size is not None:  # a phone's coarser depth map: the nearest pixel centre of each
        (w, h), (W, H) = depth_size, (scan.camera.width, scan.camera.height)
        if not (0 < w <= W and 0 < h <= H):
            raise ScanIOError(f"{depth_path}: depth size {w}x{h} must be within the colour's {W}x{H}")
        depth = nearest_depth(depth, w, h)
    if ext == "png":
        write_png(depth_path, depth_to_uint16(depth, unit, str(depth_path)))
    else:
        write_exr(depth_path, depth)


def write_transforms(scanset: ScanSet, out_dir: Path, depth_format: str = "png",
                     png_depth_unit: float = DEFAULT_PNG_DEPTH_UNIT, overwrite: bool = False,
                     extra_files: dict[str, bytes] | None = None, progress=None, lens: Lens | None = None,
                     depth_size=None) -> Path:
    """Write ``out_dir/transforms.json`` + ``images/`` + ``depth/`` atomically; returns the json path.
    ``depth_size`` (w, h): write the depth maps at that smaller size (nearest pixel centre), as a
    phone's depth sensor gives them; the reader resamples them to the colour (capture.resample).

    ``depth_format``: a :data:`DEPTH_FORMATS` name -- ``"png"`` (16-bit, ``png_depth_unit`` metres
    per unit, millimetres by default), ``"png-0.1mm"`` or ``"exr"`` (float metres).  The unit is
    written once, as the top-level ``depth_unit_scale_factor`` (module docstring).
    ``extra_files``: relative path -> bytes written inside the same atomic folder.  ``lens``: the
    images are distorted by it (written as ``camera_model`` + coefficients, capture.lens).
    """
    ext, unit = depth_format_spec(depth_format, png_depth_unit)
    out_dir = Path(out_dir)
    with atomic_folder(out_dir, overwrite) as tmp:
        frames = []
        items = list(enumerate(scanset.scans))
        for i, s in (progress(items, "writing scans") if progress else items):
            stem = Path(s.name).stem if s.name else f"frame_{i:04d}"
            rel_rgb = f"images/{stem}.png"
            rel_depth = f"depth/{stem}.{ext}"
            _write_images(s, tmp / rel_rgb, tmp / rel_depth, ext, unit, depth_size)
            frames.append({"file_path": rel_rgb, "depth_file_path": rel_depth, **s.camera.to_nerfstudio(),
                           **write_matte(s, tmp, stem)})
        meta = {**nerfstudio_keys(lens), "depth_unit_scale_factor": unit, "frames": frames,
                "furrow": {"bounds": np.asarray(scanset.bounds).tolist(),
                           "metadata": jsonable(scanset.metadata)}}
        (tmp / TRANSFORMS).write_text(json.dumps(meta, indent=1))
        for rel, data in (extra_files or {}).items():
            (tmp / rel).parent.mkdir(parents=True, exist_ok=True)
            (tmp / rel).write_bytes(data)
    return out_dir / TRANSFORMS


def write_plain_folder(scanset: ScanSet, out_dir: Path, depth_format: str = "exr", overwrite: bool = False) -> Path:
    """Write the plain folder layout atomically; returns the folder."""
    out_dir = Path(out_dir)
    with atomic_folder(out_dir, overwrite) as tmp:
        for i, s in enumerate(scanset.scans):
            stem = Path(s.name).stem if s.name else f"frame_{i:04d}"
            ext, unit = depth_format_spec(depth_format)
            _write_images(s, tmp / "rgb" / f"{stem}.png", tmp / "depth" / f"{stem}.{ext}", ext, unit)
            cam = {"K": s.camera.K.tolist(), "cam_from_world": s.camera.cam_from_world.tolist(),
                   "width": s.camera.width, "height": s.camera.height, "depth_unit_scale_factor": unit}
            (tmp / "cameras").mkdir(exist_ok=True)
            (tmp / "cameras" / f"{stem}.json").write_text(json.dumps(cam, indent=1))
            write_matte(s, tmp, stem)
        (tmp / "bounds.json").write_text(json.dumps({"bounds": np.asarray(scanset.bounds).tolist()}))
    return out_dir

"""Reading a COLMAP sparse model (via pycolmap) with a folder of depth maps as a ScanSet.

Layout: ``MODEL_DIR`` holds ``cameras.bin/images.bin/points3D.bin`` (or the .txt versions);
colour images are found under ``IMAGES_DIR/<image name>``; depth maps under
``DEPTH_DIR/<image name stem>.png|.exr|.npy`` (z-depth; 16-bit PNG needs
``depth_unit_scale_factor``).  COLMAP puts the centre of the top-left pixel at (0.5, 0.5),
like nerfstudio, so half a pixel is subtracted from the principal point (OpenCV centres).
Pinhole models are read as they are; SIMPLE_RADIAL, RADIAL, OPENCV, OPENCV_FISHEYE and FULL_OPENCV
are undistorted at read time to a pinhole camera (capture.lens; ``undistort``: keep | crop | full).
Mattes: ``masks/STEM.png`` (or COLMAP's ``masks/IMAGE_NAME.png``) beside ``images/``, read as
transforms.json's ``mask_path`` (capture.matte_io).  The model opens as a capture.sources.Source;
its frames are read by the same steps as every layout's.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from capture.camera import Camera, CameraError, cv_from_corner, make_K
from capture.imageio import ScanIOError
from capture.io_lens import pinhole_camera
from capture.lens import DEFAULT_UNDISTORT, Lens, LensError, colmap_lens
from capture.matte_io import MASK_DIR
from capture.scan import ScanSet
from capture.sources import FrameRef, Source

#: Longest a COLMAP model may take to load (seconds).  pycolmap loops forever on some truncated
#: binary files (found by tests/capture/test_fuzz_readers.py) and aborts the process on others, so
#: the model is read in a child process that is killed when it runs past this.
COLMAP_READ_TIMEOUT_S = 120.0


@dataclass(frozen=True)
class ColmapImage:
    """One registered image of a COLMAP model, as plain values.

    Attributes:
        name: image file name relative to the images folder.
        model: COLMAP camera model name (e.g. PINHOLE).
        width, height: image size in pixels.
        fx, fy, cx, cy: focal lengths and principal point in pixels (COLMAP centres: pixel (0, 0)'s
            centre at (0.5, 0.5)).
        distortion: the model's extra (distortion) parameters.
        cam_from_world: (3, 4) float64 pose, OpenCV axes, metres.
    """

    name: str
    model: str
    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    distortion: tuple[float, ...]
    cam_from_world: np.ndarray


def _extract(model_dir: str) -> tuple[list[ColmapImage], np.ndarray]:
    """(registered images sorted by name, (N, 3) 3-D points) of a COLMAP model (runs in the child)."""
    import pycolmap

    rec = pycolmap.Reconstruction(model_dir)
    out = []
    for im in sorted((im for im in rec.images.values() if im.has_pose), key=lambda im: im.name):
        cam = rec.cameras[im.camera_id]
        pose = im.cam_from_world() if callable(im.cam_from_world) else im.cam_from_world
        name = (str(cam.model_name) if hasattr(cam, "model_name") else str(cam.model)).split(".")[-1]
        extra = [cam.params[i] for i in cam.extra_params_idxs()] if hasattr(cam, "extra_params_idxs") else []
        out.append(ColmapImage(str(im.name), name, int(cam.width), int(cam.height), float(cam.focal_length_x),
                               float(cam.focal_length_y), float(cam.principal_point_x), float(cam.principal_point_y),
                               tuple(float(e) for e in extra), np.asarray(pose.matrix(), np.float64)))
    pts = np.array([p.xyz for p in rec.points3D.values()], np.float64).reshape(-1, 3)
    return out, pts


def _child(model_dir: str, conn) -> None:
    try:
        conn.send(("ok", _extract(model_dir)))
    except BaseException as e:  # everything goes back to the parent as text
        conn.send(("error", f"{type(e).__name__}: {str(e).strip()[:300]}"))
    finally:
        conn.close()


def load_colmap_model(model_dir: Path, timeout: float | None = None) -> tuple[list[ColmapImage], np.ndarray]:
    """:func:`_extract` in a child process (spawned: no GL context or thread is inherited); a hang,
    crash or pycolmap error becomes a ScanIOError naming the folder."""
    import multiprocessing as mp

    timeout = COLMAP_READ_TIMEOUT_S if timeout is None else timeout
    ctx = mp.get_context("spawn")
    recv, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(str(model_dir), send), name="furrow-colmap-reader")
    proc.start()
    send.close()
    try:
        if not recv.poll(timeout):
            raise ScanIOError(f"{model_dir}: reading the COLMAP model did not finish within {timeout:g} s "
                              "(a corrupt or truncated .bin file?)")
        try:
            status, payload = recv.recv()
        except (EOFError, OSError):
            proc.join(5)
            raise ScanIOError(f"{model_dir}: the COLMAP reader crashed (exit code {proc.exitcode}); "
                              "the model files are corrupt") from None
    finally:
        if proc.is_alive():
            proc.kill()
        proc.join(5)
        recv.close()
    if status != "ok":
        raise ScanIOError(f"{model_dir}: not a readable COLMAP model ({payload})")
    return payload


def _camera_K(im: ColmapImage, where: str) -> np.ndarray:
    return make_K(im.fx, im.fy, cv_from_corner(im.cx), cv_from_corner(im.cy))


def _lens(im: ColmapImage, where: str) -> Lens | None:
    try:
        return colmap_lens(im.model, im.distortion)
    except LensError as e:
        raise ScanIOError(f"{where}: {e}") from None


def colmap_source(model_dir: Path, images_dir: Path, depth_dir: Path | None = None,
                  depth_unit_scale_factor: float | None = None, undistort: str = DEFAULT_UNDISTORT,
                  masks_dir: Path | None = None) -> Source:
    """The Source of a COLMAP model + images (+ depth maps, + mattes): registered images sorted by
    name; cameras with lens distortion get the pinhole camera they are undistorted to (capture.lens,
    ``undistort``).  Mattes: ``masks_dir/STEM.png`` or COLMAP's ``masks_dir/IMAGE_NAME.png``."""
    model_dir = Path(model_dir)
    if not model_dir.is_dir():
        raise ScanIOError(f"{model_dir}: COLMAP model folder not found")
    images, points = load_colmap_model(model_dir)
    if not images:
        raise ScanIOError(f"{model_dir}: COLMAP model has no registered image")
    refs = tuple(_frame(model_dir, i, im, images_dir, depth_dir, depth_unit_scale_factor, undistort, masks_dir)
                 for i, im in enumerate(images))
    fallback = _bounds_from_points(points, model_dir) if depth_dir is None else None
    return Source(model_dir, "colmap", refs, None, {"source": str(model_dir), "format": "colmap"}, undistort,
                  fallback)


def _frame(model_dir: Path, i: int, im: ColmapImage, images_dir, depth_dir, unit, undistort: str,
           masks_dir) -> FrameRef:
    """One registered image as a FrameRef (its colour file must exist: named in the model)."""
    where = f"{model_dir} image {im.name!r}"
    M = np.eye(4)
    M[:3, :4] = im.cam_from_world
    try:
        camera = Camera(_camera_K(im, where), M, im.width, im.height, name=im.name)
    except CameraError as e:
        raise ScanIOError(f"{where}: {e}") from None
    lens = _lens(im, where)
    pinhole = camera if lens is None else pinhole_camera(camera, lens, undistort, where)
    rgb_path = Path(images_dir) / im.name
    if not im.name or not rgb_path.is_file():
        raise ScanIOError(f"{rgb_path}: colour image not found (named in {model_dir})")
    stem = Path(im.name).with_suffix("")
    depth = None if depth_dir is None else Path(depth_dir) / stem
    mask = None
    if masks_dir is not None:
        mask = next((m for m in (Path(masks_dir) / f"{stem}.png", Path(masks_dir) / f"{im.name}.png") if m.is_file()),
                    None)
    return FrameRef(i, im.name, pinhole, camera, lens, rgb_path, depth, None, mask, unit, "", where)


def colmap_folder_source(path: Path, model: Path, undistort: str = DEFAULT_UNDISTORT) -> Source:
    """The Source of a COLMAP folder: ``model`` (``sparse/0``) + ``images/`` + optional ``depth/``,
    ``masks/`` and ``depth_units.json`` (``{"depth_unit_scale_factor": metres per unit}``)."""
    from capture.imageio import finite_number
    from capture.io import _load_json

    path = Path(path)
    units = path / "depth_units.json"
    unit = _load_json(units).get("depth_unit_scale_factor") if units.is_file() else None
    if unit is not None and (unit := finite_number(unit, "depth_unit_scale_factor", str(units))) <= 0:
        raise ScanIOError(f"{units}: depth_unit_scale_factor must be a positive number of metres")
    depth = path / "depth" if (path / "depth").is_dir() else None
    masks = path / MASK_DIR if (path / MASK_DIR).is_dir() else None
    return colmap_source(model, path / "images", depth, unit, undistort, masks)


def read_colmap(model_dir: Path, images_dir: Path, depth_dir: Path | None = None,
                depth_unit_scale_factor: float | None = None, frames: str | None = None,
                undistort: str = DEFAULT_UNDISTORT, masks_dir: Path | None = None) -> ScanSet:
    """Read a COLMAP model + images (+ depth maps, + mattes) into a ScanSet (:func:`colmap_source`,
    every frame read by the steps of capture.sources)."""
    from capture.sources import STEP_CONFIGS, UndistortConfig, read_source

    source = colmap_source(model_dir, images_dir, depth_dir, depth_unit_scale_factor, undistort, masks_dir)
    configs = tuple(c() for c in STEP_CONFIGS[:-1]) + (UndistortConfig(undistort),)
    return read_source(source.select(frames), configs=configs)


def _bounds_from_points(pts: np.ndarray, where) -> np.ndarray:
    from capture.scan import bounds_from_points

    pts = pts[np.all(np.isfinite(pts), axis=1)]
    if len(pts) == 0:
        raise ScanIOError(f"{where}: no depth folder and no 3-D points: cannot derive bounds")
    lo, hi = np.percentile(pts, [1, 99], axis=0)
    return bounds_from_points(np.stack([lo, hi]))

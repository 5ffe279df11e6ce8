"""Reading a COLMAP sparse model (via pycolmap) with a folder of depth maps as a ScanSet.

Layout: ``MODEL_DIR`` holds ``cameras.bin/images.bin/points3D.bin`` (or the .txt versions);
colour images are found under ``IMAGES_DIR/<image name>``; depth maps under
``DEPTH_DIR/<image name stem>.png|.exr|.npy`` (z-depth; 16-bit PNG needs
``depth_unit_scale_factor``).  COLMAP puts the centre of the top-left pixel at (0.5, 0.5),
like nerfstudio, so half a pixel is subtracted from the principal point (OpenCV centres).
Pinhole models are read as they are; SIMPLE_RADIAL, RADIAL, OPENCV, OPENCV_FISHEYE and FULL_OPENCV
are undistorted at read time to a pinhole camera (capture.lens; ``undistort``: crop | full).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from capture.camera import Camera, CameraError, cv_from_corner, make_K
from capture.imageio import ScanIOError
from capture.io import _load_scan, auto_bounds, log_resampled
from capture.io_lens import note_undistorted, pinhole_camera
from capture.lens import DEFAULT_UNDISTORT, Lens, LensError, colmap_lens, undistort_scan
from capture.scan import ScanError, ScanSet, select_indices

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


def read_colmap(model_dir: Path, images_dir: Path, depth_dir: Path | None = None,
                depth_unit_scale_factor: float | None = None, frames: str | None = None,
                undistort: str = DEFAULT_UNDISTORT) -> ScanSet:
    """Read a COLMAP model + images (+ depth maps) into a ScanSet, images sorted by name; cameras
    with lens distortion are undistorted to pinhole ones (capture.lens, ``undistort``)."""
    model_dir = Path(model_dir)
    if not model_dir.is_dir():
        raise ScanIOError(f"{model_dir}: COLMAP model folder not found")
    images, points = load_colmap_model(model_dir)
    if not images:
        raise ScanIOError(f"{model_dir}: COLMAP model has no registered image")
    scans, notes, lenses = [], [], []
    for i in select_indices(frames, len(images)):
        im = images[i]
        where = f"{model_dir} image {im.name!r}"
        M = np.eye(4)
        M[:3, :4] = im.cam_from_world
        try:
            camera = Camera(_camera_K(im, where), M, im.width, im.height, name=im.name)
        except CameraError as e:
            raise ScanIOError(f"{where}: {e}") from None
        lenses.append(lens := _lens(im, where))
        pinhole = camera if lens is None else pinhole_camera(camera, lens, undistort, where)
        rgb_path = Path(images_dir) / im.name
        if not im.name or not rgb_path.is_file():
            raise ScanIOError(f"{rgb_path}: colour image not found (named in {model_dir})")
        depth_path = None
        if depth_dir is not None:
            stem = Path(im.name).with_suffix("")
            cands = [Path(depth_dir) / f"{stem}{ext}" for ext in (".png", ".exr", ".npy")]
            depth_path = next((c for c in cands if c.is_file()), None)
            if depth_path is None:
                raise ScanIOError(f"{cands[0]}: depth file not found for COLMAP image {im.name!r}")
        try:
            scan = _load_scan(camera, rgb_path, depth_path, depth_unit_scale_factor, im.name, notes=notes)
            scans.append(scan if lens is None else undistort_scan(scan, lens, camera.K, pinhole))
        except ScanIOError as e:  # the camera came from the model: name it too
            raise ScanIOError(f"{e} (camera of {where})") from None
    try:
        bounds = auto_bounds(scans, str(model_dir)) if depth_dir is not None else _bounds_from_points(points, model_dir)
        md = {"source": str(model_dir), "format": "colmap"}
        log_resampled(notes, md)
        note_undistorted(lenses, undistort, md)
        return ScanSet(tuple(scans), bounds, md)
    except ScanError as e:
        raise ScanIOError(f"{model_dir}: {e}") from None


def _bounds_from_points(pts: np.ndarray, where) -> np.ndarray:
    from capture.scan import bounds_from_points

    pts = pts[np.all(np.isfinite(pts), axis=1)]
    if len(pts) == 0:
        raise ScanIOError(f"{where}: no depth folder and no 3-D points: cannot derive bounds")
    lo, hi = np.percentile(pts, [1, 99], axis=0)
    return bounds_from_points(np.stack([lo, hi]))

"""Reading a COLMAP sparse model (via pycolmap) with a folder of depth maps as a ScanSet.

Layout: ``MODEL_DIR`` holds ``cameras.bin/images.bin/points3D.bin`` (or the .txt versions);
colour images are found under ``IMAGES_DIR/<image name>``; depth maps under
``DEPTH_DIR/<image name stem>.png|.exr|.npy`` (z-depth; 16-bit PNG needs
``depth_unit_scale_factor``).  COLMAP puts the centre of the top-left pixel at (0.5, 0.5),
like nerfstudio, so half a pixel is subtracted from the principal point (OpenCV centres).
Only undistorted pinhole models are accepted (SIMPLE_PINHOLE, PINHOLE, or a distortion model
whose distortion parameters are all zero).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from capture.camera import Camera, CameraError, cv_from_corner, make_K
from capture.imageio import ScanIOError
from capture.io import _load_scan, auto_bounds
from capture.scan import ScanSet, select_indices

#: COLMAP models with no distortion.
PINHOLE_MODELS = {"SIMPLE_PINHOLE", "PINHOLE"}


def _camera_K(cam, where: str) -> np.ndarray:
    name = str(cam.model_name) if hasattr(cam, "model_name") else str(cam.model)
    name = name.split(".")[-1]
    if name not in PINHOLE_MODELS:
        extra = [cam.params[i] for i in cam.extra_params_idxs()] if hasattr(cam, "extra_params_idxs") else []
        if any(abs(float(e)) > 0 for e in extra):
            raise ScanIOError(f"{where}: COLMAP camera model {name} has non-zero distortion {list(extra)}; "
                              "undistort first (colmap image_undistorter)")
    return make_K(cam.focal_length_x, cam.focal_length_y,
                  cv_from_corner(cam.principal_point_x), cv_from_corner(cam.principal_point_y))


def read_colmap(model_dir: Path, images_dir: Path, depth_dir: Path | None = None,
                depth_unit_scale_factor: float | None = None, frames: str | None = None) -> ScanSet:
    """Read a COLMAP model + images (+ depth maps) into a ScanSet, images sorted by name."""
    import pycolmap

    model_dir = Path(model_dir)
    if not model_dir.is_dir():
        raise ScanIOError(f"{model_dir}: COLMAP model folder not found")
    try:
        rec = pycolmap.Reconstruction(str(model_dir))
    except Exception as e:
        raise ScanIOError(f"{model_dir}: not a readable COLMAP model ({e})") from None
    images = sorted((im for im in rec.images.values() if im.has_pose), key=lambda im: im.name)
    if not images:
        raise ScanIOError(f"{model_dir}: COLMAP model has no registered image")
    scans = []
    for i in select_indices(frames, len(images)):
        im = images[i]
        where = f"{model_dir} image {im.name!r}"
        cam = rec.cameras[im.camera_id]
        pose = im.cam_from_world() if callable(im.cam_from_world) else im.cam_from_world
        M = np.eye(4)
        M[:3, :4] = np.asarray(pose.matrix())
        try:
            camera = Camera(_camera_K(cam, where), M, cam.width, cam.height, name=im.name)
        except CameraError as e:
            raise ScanIOError(f"{where}: {e}") from None
        rgb_path = Path(images_dir) / im.name
        if not rgb_path.is_file():
            raise ScanIOError(f"{rgb_path}: colour image not found (named in {model_dir})")
        depth_path = None
        if depth_dir is not None:
            stem = Path(im.name).with_suffix("")
            cands = [Path(depth_dir) / f"{stem}{ext}" for ext in (".png", ".exr", ".npy")]
            depth_path = next((c for c in cands if c.is_file()), None)
            if depth_path is None:
                raise ScanIOError(f"{cands[0]}: depth file not found for COLMAP image {im.name!r}")
        scans.append(_load_scan(camera, rgb_path, depth_path, depth_unit_scale_factor, im.name))
    bounds = auto_bounds(scans) if depth_dir is not None else _bounds_from_points(rec, model_dir)
    return ScanSet(tuple(scans), bounds, {"source": str(model_dir), "format": "colmap"})


def _bounds_from_points(rec, where) -> np.ndarray:
    from capture.scan import bounds_from_points

    pts = np.array([p.xyz for p in rec.points3D.values()])
    if len(pts) == 0:
        raise ScanIOError(f"{where}: no depth folder and no 3-D points: cannot derive bounds")
    lo, hi = np.percentile(pts, [1, 99], axis=0)
    return bounds_from_points(np.stack([lo, hi]))

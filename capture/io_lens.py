"""The readers' side of lens distortion (capture.lens): a frame's lens from transforms.json keys,
the pinhole camera it is undistorted to, and the note in the scan set's metadata."""

from __future__ import annotations

import logging

from capture.camera import Camera, CameraError
from capture.imageio import ScanIOError, finite_number
from capture.lens import Lens, LensError, nerfstudio_lens, undistorted_camera


def frame_lens(fr: dict, meta: dict, where: str) -> Lens | None:
    """The lens of a transforms.json frame: ``camera_model`` and coefficients, per frame or global
    (a per-frame key overrides the global one); None for a pinhole camera."""
    def value(k):
        v = fr.get(k, meta.get(k))
        return None if v is None else finite_number(v, f"lens distortion '{k}'", where)

    try:
        return nerfstudio_lens(fr.get("camera_model", meta.get("camera_model")), value)
    except LensError as e:
        raise ScanIOError(f"{where}: {e}") from None


def pinhole_camera(cam: Camera, lens: Lens, undistort: str, where: str) -> Camera:
    """The pinhole camera a distorted ``cam`` is undistorted to (capture.lens.undistorted_camera)."""
    import cv2

    try:
        K, w, h = undistorted_camera(cam.K, lens, cam.width, cam.height, undistort)
        return Camera(K, cam.cam_from_world, w, h, name=cam.name)
    except (LensError, CameraError) as e:
        raise ScanIOError(f"{where}: {e}") from None
    except cv2.error as e:
        msg = str(e).strip().splitlines()[-1][:160] if str(e).strip() else "OpenCV error"
        raise ScanIOError(f"{where}: cannot undistort {lens.source or lens.model} {list(lens.coeffs)}: {msg}") from None


def note_undistorted(lenses: list, undistort: str, metadata: dict) -> None:
    """Record in the scan set's metadata (and the log) that frames were undistorted at read time."""
    lenses = [x for x in lenses if x is not None]
    if not lenses:
        return
    models = sorted({x.source or x.model for x in lenses})
    metadata["undistorted"] = {"mode": undistort, "frames": len(lenses), "models": models,
                               "lens": lenses[0].record()}
    logging.getLogger("furrow.capture").info("undistorted %d frames (%s) to pinhole cameras (%s)", len(lenses),
                                             ", ".join(models), undistort)

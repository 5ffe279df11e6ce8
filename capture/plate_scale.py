"""Background plates of large captures at a working resolution (capture/plate.py holds the method).

The plate stage reads every view at once (colour, the object's depth and the capture's depth:
about 14 bytes a pixel). A phone capture of 200 views at 1920x1440 would need 7.7 GB, far over the
model's memory bound, so past :data:`PLATE_VIEW_BUDGET_BYTES` every view is shrunk by one factor
(colour by area, depths by nearest sample, the object's depth grown first so that no object pixel
is taken for background), the plates are made at that size, and each plate is brought back to its
view's size only when the matte stage reads it (:func:`grow_plate`: background bilinear, known
pixels nearest and shrunk by one working pixel, so a known pixel never borrows an unknown one).
The background is the room seen out of focus behind the object, so the working plate loses little;
the stage's record says at which scale the plates were made.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from scipy import ndimage

from capture.matting_fast import erode
from capture.plate import Plate, PlateView

#: Bytes of prepared views the plate stage may hold at once (beyond it the views are shrunk).
PLATE_VIEW_BUDGET_BYTES = 1 << 30
#: Bytes a pixel costs in the plate stage (float16 colour, float32 object depth and capture depth).
PLATE_BYTES_PER_PIXEL = 14
#: Smallest working scale (below it the plate would no longer resolve the room behind a needle).
PLATE_MIN_SCALE = 0.2
#: A working scale at or above this is taken as full size: shrinking by less than a tenth keeps at most a fifth of the
#: budget's bytes off the peak and costs every view's shrinking and every plate's growing back (72 views at 1280x960,
#: 0.93 by the budget: docs/speed.md "The plate at full size").  1.0: the budget alone (the rule before).
PLATE_FULL_SCALE = 0.9
#: :func:`shrink_scan` shrinks a view of 8-bit colour with fewer passes (the float32 colour by one
#: table lookup, the float16 cast and the object's maximum filter by OpenCV; the same view bit for bit,
#: tests/capture/test_plate_scale.py); False: :func:`shrink_view` of the float16 view, the reference.
SHRINK_FAST = True


def plate_scale(views: int, height: int, width: int, budget: int = PLATE_VIEW_BUDGET_BYTES) -> float:
    """The factor the plate stage shrinks ``views`` views of ``height`` x ``width`` by (1: full size, also where the
    budget would shrink them by less than PLATE_FULL_SCALE)."""
    need = float(views) * height * width * PLATE_BYTES_PER_PIXEL
    scale = math.sqrt(budget / need) if need > budget else 1.0
    return 1.0 if scale >= PLATE_FULL_SCALE else max(PLATE_MIN_SCALE, scale)


def shrink_view(view: PlateView, scale: float) -> PlateView:
    """``view`` at ``scale`` (its camera :meth:`Camera.scaled`); the object's depth is max-filtered
    over a working pixel's footprint before it is sampled, so the object only grows."""
    if scale >= 1.0:
        return view
    cam = view.camera.scaled(scale)
    size = (cam.width, cam.height)
    linear = cv2.resize(np.asarray(view.linear, np.float32), size, interpolation=cv2.INTER_AREA)
    foot = int(math.ceil(1.0 / scale)) + 1
    grown = ndimage.maximum_filter(np.asarray(view.object_depth, np.float32), size=foot)
    obj = cv2.resize(grown, size, interpolation=cv2.INTER_NEAREST)
    depth = cv2.resize(np.asarray(view.depth, np.float32), size, interpolation=cv2.INTER_NEAREST)
    return PlateView(cam, linear.astype(np.float16), obj, depth)


def grow_plate(plate: Plate, height: int, width: int) -> Plate:
    """``plate`` (full frame at a working size) at ``height`` x ``width``; itself when it has that size."""
    plate = plate.full()
    h, w = plate.known.shape
    if (h, w) == (height, width):
        return plate
    known = erode(plate.known, square=True)  # ndimage.binary_erosion with the 3 x 3 square, by OpenCV
    bg = cv2.resize(np.asarray(plate.background, np.float32), (width, height), interpolation=cv2.INTER_LINEAR)
    k = cv2.resize(known.astype(np.uint8), (width, height), interpolation=cv2.INTER_NEAREST) > 0
    bg[~k] = 0.0
    est = None if plate.estimated is None else \
        cv2.resize(plate.estimated.astype(np.uint8), (width, height), interpolation=cv2.INTER_NEAREST) > 0
    sig = None if plate.sigma is None else \
        cv2.resize(np.asarray(plate.sigma, np.float32), (width, height), interpolation=cv2.INTER_NEAREST)
    return Plate(bg, k, plate.noise, plate.method, plate.band_known, plate.error, plate.error_rmse,
                 plate.band_estimated, estimated=None if est is None else est & k,
                 sigma=None if sig is None else np.where(k, sig, 0.0).astype(np.float32))


def shrink_scan(camera, rgb: np.ndarray, object_depth: np.ndarray, depth: np.ndarray, scale: float) -> PlateView:
    """``shrink_view(PlateView(camera, linear16(rgb), object_depth, depth), scale)``, the same view bit for bit
    (SHRINK_FAST): for 8-bit ``rgb`` below scale 1, the float32 colour by ``cv2.LUT`` of the float16
    table's float32 values (what ``np.asarray(linear16(rgb), np.float32)`` gives), the cast back to
    float16 by OpenCV (IEEE round to nearest even, as numpy's), and the object's maximum filter by
    ``cv2.dilate`` (the maximum over the window's pixels inside the frame, as scipy's 'reflect' border
    gives for windows of at most twice the border's width), a NaN depth taking the reference."""
    from capture.scan import _SRGB8_LUT16, linear16

    rgb = np.asarray(rgb)
    obj = np.asarray(object_depth, np.float32)
    if not SHRINK_FAST or scale >= 1.0 or rgb.dtype != np.uint8 or rgb.ndim != 3 or np.isnan(obj).any():
        return shrink_view(PlateView(camera, linear16(rgb), object_depth, depth), scale)
    cam = camera.scaled(scale)
    size = (cam.width, cam.height)
    linear = cv2.resize(cv2.LUT(rgb, _SRGB8_LUT16.astype(np.float32)), size, interpolation=cv2.INTER_AREA)
    foot = int(math.ceil(1.0 / scale)) + 1
    grown = cv2.dilate(obj, np.ones((foot, foot), np.uint8))
    o = cv2.resize(grown, size, interpolation=cv2.INTER_NEAREST)
    d = cv2.resize(np.asarray(depth, np.float32), size, interpolation=cv2.INTER_NEAREST)
    return PlateView(cam, cv2.multiply(linear, 1.0, dtype=cv2.CV_16F), o, d)

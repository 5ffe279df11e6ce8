"""The fixed camera's sample weights on the object's neighbourhood only, and the need mask by one
dilation (issue 32, round 9).

``capture.plate_fixed.fixed_sample_weight`` weighs each frame's pixels by their distance to the
object's depth: 0 within the exclusion, rising to 1 at the source band (16 px at 1280 wide).  Every
pixel farther than the band from the object is 1 whatever its distance, so only the box around the
object widened by the band needs a distance at all.  :func:`near_weight_box` takes OpenCV's exact
Euclidean distance transform on that box: every object pixel lies inside it, so each distance in
it is the whole frame's (the exact transform is the minimum over the object's pixels), and outside
it every weight is 1.  The whole frame's transform (``capture.plate_fixed._near_weight``) stays as
the reference; tests/capture/test_plate_weight.py holds them equal bit for bit.

``capture.plate.need_mask`` built the float64 trimap (``capture.matting.depth_trimap``: an erosion, a
dilation, a whole-frame float64 array) only to dilate its nonzero pixels again.  Those are the
depth's pixels dilated by the trimap's band (the sure object, eroded, lies inside them), and two
dilations by the cross compose into one of their summed iterations (the diamond of radius a + b; a
pixel within it of an object pixel in the frame is reached by a path inside the frame), so
:func:`need_by_one_dilation` dilates the depth's mask once: the same mask (the trimap's path kept in
``need_mask(..., fast=False)``).
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: capture.plate_fixed.fixed_sample_weight takes its distances on the object's box
#: (:func:`near_weight_box`; False: the whole frame's, ``plate_fixed._near_weight``, the same values).
WEIGHT_BOX = True
#: capture.plate.need_mask dilates the depth's mask once (:func:`need_by_one_dilation`; False: from
#: the trimap, the reference, the same mask).
NEED_ONE_DILATION = True
#: The box around the object is widened by the source band plus this many pixels: a pixel whose
#: distance is below ``band`` + 1 (the only ones whose weight is below 1 or rounded) lies within
#: ``band`` + 1 pixels of an object pixel along each axis, so ``band`` + BOX_MARGIN_PX covers it.
BOX_MARGIN_PX = 2
#: :func:`near_weight_box` works out the weights of the box's near pixels in one compiled pass
#: (:func:`_box_weights`: numpy's float64 operations in its order, round 14; False: the numpy lines,
#: the reference, the same values bit for bit, tests/capture/test_plate_weight.py).
WEIGHT_COMPILED = True


def near_weight_box(m: np.ndarray, band: int, exclude: int) -> np.ndarray:
    """(H, W) float32 the same weights as ``capture.plate_fixed._near_weight(m, band, exclude)``
    (bit for bit), its distances taken on the object's box only (module docstring): 0 where the
    distance to ``m`` is at most ``exclude``, d / ``band`` clipped to 1 beyond, 1 where ``m`` is empty."""
    import cv2

    from capture.matting_scale import object_box

    m = np.ascontiguousarray(m, bool)
    out = np.ones(m.shape, np.float32)
    box = object_box(m, band + BOX_MARGIN_PX)
    if box is None:
        return out
    free = np.logical_not(m[box]).view(np.uint8)
    d32 = cv2.distanceTransform(free, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    sub = out[box]
    if WEIGHT_COMPILED:
        _box_weights(d32, int(band), int(exclude), sub)
        return out
    near = d32 < band + 1
    d = np.sqrt(np.rint(d32[near].astype(np.float64) ** 2))
    sub[near] = np.where(d > exclude, np.clip(d / band, 0.0, 1.0), 0.0)
    return out


@njit(cache=True, nogil=True)
def _box_weights(d32, band, exclude, out):
    """:func:`near_weight_box`'s numpy lines in one pass: where the float32 distance ``d32`` is below
    ``band`` + 1 (an integer: exact in float32 and float64 alike), ``out`` (a float32 view) gets
    sqrt(rint(float64(d)^2)) (``**2`` is numpy's square, x * x), 0 at most ``exclude``, else
    min(d / ``band``, 1) (``np.clip`` of a non-negative quotient) rounded to float32."""
    lim = band + 1
    for i in range(d32.shape[0]):
        for j in range(d32.shape[1]):
            v = d32[i, j]
            if v < lim:
                x = np.float64(v)
                d = np.sqrt(np.rint(x * x))
                if d > exclude:
                    q = d / band
                    out[i, j] = np.float32(q if q < 1.0 else 1.0)
                else:
                    out[i, j] = np.float32(0.0)


def need_by_one_dilation(object_depth: np.ndarray) -> np.ndarray:
    """``capture.plate.need_mask(object_depth)`` (the same (H, W) bool): the depth's mask dilated by the
    trimap's band and the known-background path's widening in one dilation (module docstring)."""
    from capture.matting import BAND_FRACTION, _px
    from capture.matting_fast import dilate
    from capture.matting_known import widen_px

    m = np.asarray(object_depth) > 0
    W = m.shape[1]
    return dilate(m, _px(BAND_FRACTION, W) + widen_px(W))

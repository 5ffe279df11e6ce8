"""A plate view's masks (capture.plate.prepare) dilated on the object's box only (issue 32, round 11).

``capture.plate.prepare`` dilates each view's object mask four times over the whole frame: the
source mask (the object widened by the source band), the held-back ring's reach (the source band's
complement widened by the ring, twice: once for the ring, once for the moving-camera path's band)
and the need mask (the matte's band and widening).  Every one of them is False beyond the object's
box widened by its radius, and a dilation by the 3x3 cross on a rectangle holding that widened box
gives the whole frame's values there (a pixel within the diamond of an object pixel is reached by
a staircase inside the rectangle of the two), so :func:`view_masks` dilates the box alone (about a
fifth of a phone view), the ring's reach once, and the ring's pixels are found on the box.  The same
masks and ring bit for bit (tests/capture/test_plate_masks.py); the whole frame's path is the reference.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from capture.extent_kernel import _height, _world, camera_arrays

#: capture.plate.prepare's masks by :func:`view_masks` on the object's box (False: plate.source_mask,
#: ring_pixels and need_mask over the whole frame, the reference; the same masks).
MASKS_BOX = True


def view_masks(object_depth: np.ndarray, band: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """(source (H, W) bool, ring (N, 2) int, need (H, W) bool, the moving-camera path's band (H, W)
    bool or None when not ``band``) of capture.plate.prepare: ``source_mask``, ``ring_pixels``,
    ``need_mask`` and ``source & dilate(~source, RING px)``, the same values (module docstring)."""
    from capture import plate as pl
    from capture import plate_weight as pw
    from capture.matting import BAND_FRACTION, _px
    from capture.matting_fast import dilate
    from capture.matting_known import widen_px
    from capture.matting_scale import object_box

    m = np.asarray(object_depth) > 0
    H, W = m.shape
    rb, rr = pl.px(pl.SOURCE_BAND_FRACTION, W), pl.px(pl.RING_FRACTION, W)
    rn = _px(BAND_FRACTION, W) + widen_px(W)
    box = object_box(m, max(rb + rr, rn) + 1) if MASKS_BOX and pw.NEED_ONE_DILATION else None
    if box is None:  # the reference (or no object: every mask as the whole frame's)
        src = pl.source_mask(object_depth)
        near = dilate(~src, rr)
        return src, pl.ring_pixels(object_depth, src), pl.need_mask(object_depth), (src & near) if band else None
    crop = np.ascontiguousarray(m[box])
    grown = dilate(crop, rb)
    src = np.ones((H, W), bool)
    src[box] = ~grown
    near = dilate(grown, rr)  # dilate(~source, rr) on the box: the object widened by rb + rr
    ring_box = near & ~grown
    y, x = np.nonzero(ring_box)
    if len(y) > pl.RING_SAMPLES:
        k = np.linspace(0, len(y) - 1, pl.RING_SAMPLES).round().astype(np.int64)
        y, x = y[k], x[k]
    ring = np.stack([x + box[1].start, y + box[0].start], axis=1)
    need = np.zeros((H, W), bool)
    need[box] = dilate(crop, rn)
    out_band = None
    if band:
        out_band = np.zeros((H, W), bool)
        out_band[box] = ring_box
    return src, ring, need, out_band


#: capture.plate_fixed's exposure grids test every frame's weight on the grid alone (:func:`common_grid`;
#: False: the whole frames stacked and tested, then the grid taken, the reference; the same mask).
GRID_FIRST = True


def common_grid(weights, rows: slice, cols: slice) -> np.ndarray:
    """``np.logical_and.reduce([w >= 1 for w in weights])[rows, cols]`` (the same bool grid): where every
    frame's weight is 1 on a grid, each frame tested on the grid only (GRID_FIRST) instead of stacking
    every whole frame's test (72 x 1 M pixels) before taking a 49th of them."""
    if not GRID_FIRST:
        return np.logical_and.reduce([w >= 1 for w in weights])[rows, cols]
    out = np.asarray(weights[0])[rows, cols] >= 1
    for w in weights[1:]:
        out &= np.asarray(w)[rows, cols] >= 1
    return out


#: capture.plate.prepare's off-plane test at the moving-camera band's pixels only (:func:`off_plane_at`:
#: room_depth reads it nowhere else; False: every depth pixel, plate_reproject.off_plane, the reference).
OFF_PLANE_BAND = True


def off_plane_at(cam, depth: np.ndarray, plane: np.ndarray | None, where: np.ndarray) -> np.ndarray:
    """``capture.plate_reproject.off_plane(cam, depth, plane) & where`` (the same mask): the compiled test
    (capture.extent_kernel's arithmetic, the same functions) run at the ``where`` pixels alone."""
    from capture.plate_reproject import PLANE_OFF_METRES, off_plane

    if not OFF_PLANE_BAND or plane is None:
        return off_plane(cam, depth, plane) & where
    depth, K, R, t = camera_arrays(depth, cam)
    out = np.zeros(depth.shape, np.bool_)
    _above_at(depth, K, R, t, np.asarray(plane, np.float64), float(PLANE_OFF_METRES),
              np.ascontiguousarray(where, np.bool_), out)
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _above_at(depth, K, R, t, plane, offset, where, out):
    """capture.extent_kernel._above (the same functions and arithmetic) at the ``where`` pixels."""
    H, W = depth.shape
    for v in range(H):
        for u in range(W):
            if not where[v, u]:
                continue
            d32 = depth[v, u]
            if not (np.isfinite(d32) and d32 > 0):
                continue
            x, y, z = _world(u, v, np.float64(d32), K, R, t)
            out[v, u] = _height(x, y, z, plane) > offset

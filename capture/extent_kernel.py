"""The extent's per-pixel labels (capture/extent.py) as one compiled loop over a view's depth (numba).

``capture.extent`` back-projects every depth pixel of a view to the world, labels it (support,
far, outside: ``_labels``) and, for the floater test, back-projects the kept pixels a second time
to find their cells of the floater grid (``_floater_cells``, ``floater_relabel``).  In numpy that
is some fifteen float64 temporaries of the view's pixels, twice per pass, and the extent stage
makes two such passes (the floater grid, then the removal): 54 s of a 200-view phone capture's
8 minutes (docs/speed.md).  :func:`view_labels` does the same for each pixel in one loop, without
temporaries, and the floater cells in the same loop.

The arithmetic is the numpy path's, operation for operation: the ray ``capture.camera.Camera.pixel_rays``
times the depth in float64, the rotation ``pc @ R.T + t``, the plane's height ``pts @ n + d``, the
distance ``np.linalg.norm(pts - centre)``, the cell ``floor((p - origin) / voxel)``.  numpy's two
products go through BLAS (OpenBLAS here), whose kernels sum the three terms in their own order with
fused multiply-adds; the loop follows the order this machine's OpenBLAS takes (:func:`_rotate`,
:func:`_height`; found by comparing every pixel of the phone frames and random points), which gives
the same world points bit for bit here.  Another BLAS may round the last bit otherwise, and a
label can then differ only for a pixel within one rounding of a threshold (the plane's band, the
focus radius, a cell's wall): tests/capture/test_extent.py states that tolerance; 0 pixels measured.
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: Label codes (capture.extent.REASONS, 1-based; 0 = kept or no depth).
SUPPORT, FAR, OUTSIDE, FLOATER = 1, 2, 3, 4
#: What :func:`_kernel` does besides the labels: nothing, mark the kept pixels' cells, or label the
#: kept pixels outside the object's cells as floaters.
LABELS, MARK_CELLS, FLOATERS = 0, 1, 2


@njit(cache=True, nogil=True, error_model="numpy")
def _ray(u, v, d, K):
    """Camera-frame point of pixel (u, v) at z-depth ``d`` (Camera.pixel_rays times the depth; no fused operations)."""
    y = (v - K[1, 2]) / K[1, 1]
    x = (u - K[0, 2] - K[0, 1] * y) / K[0, 0]
    return x * d, y * d, 1.0 * d


@njit(cache=True, nogil=True, fastmath={"contract"})
def _rotate(p0, p1, p2, R, t, j):
    """World coordinate ``j`` of ``pc @ R.T + t`` as OpenBLAS's dgemm kernel sums it here:
    fma(p2, r2, fma(p0, r0, p1 * r1)), then + t (module docstring)."""
    acc = p1 * R[j, 1]
    acc = acc + p0 * R[j, 0]
    acc = acc + p2 * R[j, 2]
    return acc + t[j]


@njit(cache=True, nogil=True, fastmath={"contract"})
def _height(x, y, z, plane):
    """``pts @ plane[:3] + plane[3]`` as OpenBLAS's dgemv kernel sums it here:
    fma(z, n2, fma(y, n1, x * n0)), then + d."""
    acc = x * plane[0]
    acc = acc + y * plane[1]
    acc = acc + z * plane[2]
    return acc + plane[3]


@njit(cache=True, nogil=True, error_model="numpy")
def _distance(x, y, z, c):
    """``np.linalg.norm(p - c)``: sqrt((dx^2 + dy^2) + dz^2), no fused operations."""
    dx = x - c[0]
    dy = y - c[1]
    dz = z - c[2]
    return np.sqrt((dx * dx + dy * dy) + dz * dz)


@njit(cache=True, nogil=True, error_model="numpy")
def _world(u, v, d, K, R, t):
    """World point (x, y, z) of pixel (u, v) at z-depth ``d`` (float64): its ray, then the pose."""
    p0, p1, p2 = _ray(np.float64(u), np.float64(v), d, K)
    return _rotate(p0, p1, p2, R, t, 0), _rotate(p0, p1, p2, R, t, 1), _rotate(p0, p1, p2, R, t, 2)


@njit(cache=True, nogil=True, error_model="numpy")
def _cell(x, y, z, origin, voxel, n):
    """Flat index of the floater grid's cell of a world point (capture.sampling.cell_index, clipped)."""
    i = min(max(np.int64(np.floor((x - origin[0]) / voxel)), 0), n - 1)
    j = min(max(np.int64(np.floor((y - origin[1]) / voxel)), 0), n - 1)
    k = min(max(np.int64(np.floor((z - origin[2]) / voxel)), 0), n - 1)
    return (i * n + j) * n + k


@njit(cache=True, nogil=True, error_model="numpy")
def _kernel(depth, K, R, t, center, radius, has_plane, plane, band, z_center, origin, voxel, n, obj, mode,
            lab, seen):
    H, W = depth.shape
    for v in range(H):
        for u in range(W):
            d32 = depth[v, u]
            if not (np.isfinite(d32) and d32 > 0):
                continue
            d = np.float64(d32)
            x, y, z = _world(u, v, d, K, R, t)
            if has_plane and _height(x, y, z, plane) < band:
                lab[v, u] = SUPPORT
            elif _distance(x, y, z, center) > radius:
                lab[v, u] = FAR if d > z_center else OUTSIDE
            elif mode == MARK_CELLS:
                seen[_cell(x, y, z, origin, voxel, n)] = True
            elif mode == FLOATERS and not obj[_cell(x, y, z, origin, voxel, n)]:
                lab[v, u] = FLOATER


def view_labels(depth: np.ndarray, camera, center: np.ndarray, radius: float, plane: np.ndarray | None,
                band: float, cells=None, obj: np.ndarray | None = None):
    """(labels (H, W) int8 as ``capture.extent._labels``, the sorted flat floater cells of the kept
    pixels or None) of one view's ``depth`` (module docstring).

    ``cells`` = (origin (3,), voxel, n): with ``obj`` None, the kept pixels' cells are returned (as
    ``np.unique(capture.extent._floater_cells(...)[1])``); with ``obj`` ((n^3,) bool, the object's
    cells), the kept pixels outside them are labelled floaters instead (``floater_relabel``).
    """
    depth = np.asarray(depth)
    if depth.dtype not in (np.float32, np.float64):
        depth = depth.astype(np.float64)
    depth = np.ascontiguousarray(depth)
    lab = np.zeros(depth.shape, np.int8)
    wfc = camera.world_from_cam
    z_center = float(camera.world_to_cam(center)[2])
    mode = LABELS if cells is None else (MARK_CELLS if obj is None else FLOATERS)
    origin, voxel, n = cells if cells is not None else (np.zeros(3), 1.0, 1)
    seen = np.zeros(n ** 3 if mode == MARK_CELLS else 1, np.bool_)
    obj_arr = np.ascontiguousarray(obj, np.bool_) if obj is not None else np.zeros(1, np.bool_)
    has_plane = plane is not None
    _kernel(depth, np.ascontiguousarray(camera.K, np.float64), np.ascontiguousarray(wfc[:3, :3], np.float64),
            np.ascontiguousarray(wfc[:3, 3], np.float64), np.asarray(center, np.float64), float(radius), has_plane,
            np.asarray(plane if has_plane else np.zeros(4), np.float64), float(band), z_center,
            np.asarray(origin, np.float64), float(voxel), int(n), obj_arr, mode, lab, seen)
    return lab, (np.flatnonzero(seen) if mode == MARK_CELLS else None)


@njit(cache=True, nogil=True, error_model="numpy")
def _above(depth, K, R, t, plane, offset, out):
    H, W = depth.shape
    for v in range(H):
        for u in range(W):
            d32 = depth[v, u]
            if not (np.isfinite(d32) and d32 > 0):
                continue
            x, y, z = _world(u, v, np.float64(d32), K, R, t)
            out[v, u] = _height(x, y, z, plane) > offset


def above_plane(depth: np.ndarray, camera, plane: np.ndarray, offset: float) -> np.ndarray:
    """(H, W) bool: the depth pixels whose world point lies more than ``offset`` above ``plane``
    (``pts @ plane[:3] + plane[3] > offset`` of ``camera.depth_to_points(depth)``, in the loop's
    arithmetic: module docstring); False where there is no depth."""
    depth, K, R, t = camera_arrays(depth, camera)
    out = np.zeros(depth.shape, np.bool_)
    _above(depth, K, R, t, np.asarray(plane, np.float64), float(offset), out)
    return out


def camera_arrays(depth: np.ndarray, camera) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(the depth contiguous, float32 or else float64; K (3, 3), R (3, 3), t (3,) of the camera-to-world
    transform, contiguous float64): what the compiled loops here take of a view."""
    depth = np.ascontiguousarray(depth)
    if depth.dtype not in (np.float32, np.float64):
        depth = depth.astype(np.float64)
    wfc = camera.world_from_cam
    return (depth, np.ascontiguousarray(camera.K, np.float64), np.ascontiguousarray(wfc[:3, :3], np.float64),
            np.ascontiguousarray(wfc[:3, 3], np.float64))

"""Compiled back-projection of pixels with z-depth to world points (capture.camera.Camera.unproject's fast
path; the numpy lines there are its reference).

One loop per point: the pixel's ray as Camera.pixel_rays computes it, times the depth, then the pose
``pc @ R.T + t`` summed in the order this machine's OpenBLAS dgemm kernel takes (capture.extent_kernel's
``_world``, found by comparing every pixel of the phone frames).  Here the points are the reference's bit for
bit; another BLAS may round the last bit otherwise (tests/capture/test_camera_kernel.py states the tolerance).
numpy's version builds five (N, 3) float64 temporaries and a BLAS call for a 3 x 3 product: 7.9 ms for
300,000 points against 0.87 ms here (`furrow model` of 72 phone views calls it about 800 times: extent,
bounds, the matte's lines).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from capture.extent_kernel import _world


@njit(cache=True, nogil=True, error_model="numpy")
def _unproject(u, v, d, K, R, t, out):
    for i in range(u.shape[0]):
        x, y, z = _world(u[i], v[i], d[i], K, R, t)
        out[i, 0] = x
        out[i, 1] = y
        out[i, 2] = z


def unproject(K: np.ndarray, world_from_cam: np.ndarray, uv: np.ndarray, depth: np.ndarray) -> np.ndarray:
    """(N, 3) float64 world points of pixels ``uv`` (N, 2) at z-depth ``depth`` (N,), metres; ``K`` (3, 3),
    ``world_from_cam`` (4, 4) as capture.camera.Camera holds them."""
    uv = np.asarray(uv, np.float64)
    u = np.ascontiguousarray(uv[:, 0])
    v = np.ascontiguousarray(uv[:, 1])
    d = np.ascontiguousarray(depth, np.float64)
    wfc = np.asarray(world_from_cam, np.float64)
    out = np.empty((len(u), 3))
    _unproject(u, v, d, np.ascontiguousarray(K, np.float64), np.ascontiguousarray(wfc[:3, :3]),
               np.ascontiguousarray(wfc[:3, 3]), out)
    return out

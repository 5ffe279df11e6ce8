"""The colour guided filter's per-pixel 3x3 solves as one compiled loop (issue 32, round 5).

capture.matting_scale.guided_coefficients solves, at every working pixel, the guide's regularised
3x3 window covariance against the C targets' covariances with the guide: ``np.linalg.solve(cov[:, :,
None], cIp[..., None])``, a batched LAPACK LU per pixel and target (0.17 s of a 1920x1440 phone
view's 1.6 s matte, docs/speed.md round 5).  :func:`solve_spd3` factors each pixel's covariance
once (Cholesky: it is symmetric and, with the filter's epsilon on its diagonal, positive definite)
and solves the C targets with it.  Not bit for bit: the rounding of a Cholesky and of an LU with
pivoting differ, by about 1e-14 relative here.  The LAPACK path stays as the reference
(``guided_coefficients(..., fast=False)``) and tests/capture/test_matting_scale.py holds the two
within :data:`SOLVE_RTOL`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: Largest difference of :func:`solve_spd3` from ``np.linalg.solve`` allowed by the tests, relative to
#: the largest coefficient of the view (measured 1e-14-1e-13 on phone views and the tests' scenes).
SOLVE_RTOL = 1e-9


@njit(cache=True, nogil=True)
def _solve_spd3(cov, rhs, out):
    h, w, nc = rhs.shape[0], rhs.shape[1], rhs.shape[2]
    for i in range(h):
        for j in range(w):
            l00 = np.sqrt(cov[i, j, 0, 0])
            l10 = cov[i, j, 1, 0] / l00
            l20 = cov[i, j, 2, 0] / l00
            l11 = np.sqrt(cov[i, j, 1, 1] - l10 * l10)
            l21 = (cov[i, j, 2, 1] - l20 * l10) / l11
            l22 = np.sqrt(cov[i, j, 2, 2] - l20 * l20 - l21 * l21)
            for c in range(nc):
                y0 = rhs[i, j, c, 0] / l00
                y1 = (rhs[i, j, c, 1] - l10 * y0) / l11
                y2 = (rhs[i, j, c, 2] - l20 * y0 - l21 * y1) / l22
                x2 = y2 / l22
                x1 = (y1 - l21 * x2) / l11
                out[i, j, c, 2] = x2
                out[i, j, c, 1] = x1
                out[i, j, c, 0] = (y0 - l10 * x1 - l20 * x2) / l00


def solve_spd3(cov: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """(h, w, C, 3) float64 x with cov[i, j] @ x[i, j, c] = rhs[i, j, c] for (h, w, 3, 3) symmetric
    positive definite ``cov`` (its lower triangle is read) and (h, w, C, 3) ``rhs`` (module docstring)."""
    cov = np.ascontiguousarray(cov, np.float64)
    rhs = np.ascontiguousarray(rhs, np.float64)
    if cov.shape[-2:] != (3, 3) or rhs.shape[-1] != 3 or cov.shape[:2] != rhs.shape[:2] or rhs.ndim != 4:
        raise ValueError(f"solve_spd3 takes (h, w, 3, 3) and (h, w, C, 3), got {cov.shape} and {rhs.shape}")
    out = np.empty(rhs.shape, np.float64)
    _solve_spd3(cov, rhs, out)
    return out

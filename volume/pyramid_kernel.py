"""Eq. 1's discontinuity count (volume.pyramid.discontinuity_fraction) as one compiled pass (issue 32, round 6).

The numpy mask (volume.pyramid.discontinuity_mask, the reference) takes about twelve passes over an
L^3 volume (a float32 difference, its absolute value, the comparison, the valid pairs and two ors
per axis): at 256^3 that was about 1.3 s of the 72-view phone capture's "fuse consensus 256^3" row.
:func:`count_flagged` visits every voxel once and flags it when one of its six face neighbours
differs from it by more than the limit (both valid): the same pairs and the same float32 arithmetic
(``|a - b|`` equals numpy's ``|b - a|`` exactly; NaN compares false either way), so the same count
(tests/volume/test_pyramid.py).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _count(v, valid, use_valid, lim):
    n0, n1, n2 = v.shape
    count = 0
    for i in range(n0):
        for j in range(n1):
            for k in range(n2):
                if use_valid and not valid[i, j, k]:
                    continue
                c = v[i, j, k]
                hit = False
                for di, dj, dk in ((-1, 0, 0), (1, 0, 0), (0, -1, 0), (0, 1, 0), (0, 0, -1), (0, 0, 1)):
                    a, b, e = i + di, j + dj, k + dk
                    if a < 0 or b < 0 or e < 0 or a >= n0 or b >= n1 or e >= n2:
                        continue
                    if use_valid and not valid[a, b, e]:
                        continue
                    if abs(v[a, b, e] - c) > lim:
                        hit = True
                        break
                if hit:
                    count += 1
    return count


def count_flagged(values: np.ndarray, lim: np.float32, valid: np.ndarray | None = None) -> int:
    """``volume.pyramid.discontinuity_mask(values, ...).sum()`` of a 3-D float32 volume with the
    float32 limit ``lim`` (alpha x voxel size) and optional ``valid`` (same shape, bool)."""
    v = np.ascontiguousarray(values, np.float32)
    use = valid is not None
    m = np.ascontiguousarray(valid, np.bool_) if use else np.zeros((1, 1, 1), np.bool_)
    return int(_count(v, m, use, np.float32(lim)))

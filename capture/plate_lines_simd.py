"""The frames' lines' vertex (capture/plate_lines.py, step 2) with each candidate's distances vectorised
(issue 32, round 11).

``capture.plate_lines_kernel.vertex_costs`` scores a pixel's candidates one sample at a time: per sample
a loop over the palette's segments with a division and a square root each, the sum stopping once the
candidate cannot win.  The stop saved only about 30 % of the samples on the 72-view phone capture's
chunks (2.5-3.4 M of 4.1 M), so :func:`vertex_costs_simd` works out all of a candidate's distances first
over the pixel's samples gathered side by side (the palette outside, the samples inside: a loop the
compiler vectorises, float32 lanes, the same operations in the same order and no fused multiply-add,
so each distance is the same float32), takes one square root of the least squared distance (the
square root is monotone and correctly rounded: the root of the least is the least of the roots), then
sums the capped squares in frame order with the same stop.  The winners and costs equal
``vertex_costs``' (and so the numpy reference's) bit for bit (tests/capture/test_plate_lines.py); 13 ms
a chunk of 32 frames x 4000 pixels against 56-64 ms.
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: capture.plate_lines' compiled vertex by :func:`vertex_costs_simd` (False: plate_lines_kernel.vertex_costs,
#: one sample at a time; the same winners and costs).
LINES_SIMD = True


@njit(cache=True, nogil=True)
def _candidate(sx, sy, sz, m, bx, by, bz, pal, ex_, ey_, ez_, e2, q):
    """q[:m] = each sample's least squared distance (float32) to the segments from (bx, by, bz) to the
    palette colours (plate_lines_kernel._segment's arithmetic, before its square root)."""
    P = pal.shape[0]
    for p in range(P):
        ex, ey, ez = pal[p, 0] - bx, pal[p, 1] - by, pal[p, 2] - bz
        ex_[p], ey_[p], ez_[p] = ex, ey, ez
        e2[p] = max(ex * ex + ey * ey + ez * ez, np.float32(1e-12))
    for b in range(m):
        q[b] = np.float32(np.inf)
    for p in range(P):
        ex, ey, ez, ee = ex_[p], ey_[p], ez_[p], e2[p]
        for b in range(m):
            vx, vy, vz = sx[b] - bx, sy[b] - by, sz[b] - bz
            t = (vx * ex + vy * ey + vz * ez) / ee
            t = min(max(t, np.float32(0.0)), np.float32(1.0))
            dx, dy, dz = vx - t * ex, vy - t * ey, vz - t * ez
            qq = dx * dx + dy * dy + dz * dz
            q[b] = qq if qq < q[b] else q[b]


@njit(cache=True, nogil=True)
def _pixel(s, have, j, pal, cap, sx, sy, sz, fr, q, dd, ex_, ey_, ez_, e2):
    """(winning candidate frame, its cost) of pixel ``j``; (-1, inf) when no frame has a sample."""
    m = 0
    for k in range(s.shape[0]):
        if have[k, j]:
            sx[m], sy[m], sz[m] = s[k, j, 0], s[k, j, 1], s[k, j, 2]
            fr[m] = k
            m += 1
    best_c, best = -1, np.inf
    for a in range(m):  # candidates in frame order: the first of equal costs wins
        _candidate(sx, sy, sz, m, sx[a], sy[a], sz[a], pal, ex_, ey_, ez_, e2, q)
        for b in range(m):
            d = min(np.float64(np.sqrt(q[b])), cap)
            dd[b] = d * d
        cost = 0.0
        for b in range(m):  # in frame order, stopping once it cannot win
            cost += dd[b]
            if cost >= best:
                break
        if cost < best:
            best, best_c = cost, fr[a]
    return best_c, best


@njit(cache=True, nogil=True)
def vertex_costs_simd(s, have, pal, cap):
    """``capture.plate_lines_kernel.vertex_costs(s, have, pal, cap)``: the same (best (n,) int64, cost
    (n,) float64) bit for bit (module docstring)."""
    K, n = have.shape
    P = pal.shape[0]
    best = np.full(n, -1, np.int64)
    cost = np.full(n, np.inf)
    sx, sy = np.empty(K, np.float32), np.empty(K, np.float32)
    sz, q = np.empty(K, np.float32), np.empty(K, np.float32)
    dd = np.empty(K, np.float64)
    fr = np.empty(K, np.int64)
    ex_, ey_ = np.empty(P, np.float32), np.empty(P, np.float32)
    ez_, e2 = np.empty(P, np.float32), np.empty(P, np.float32)
    for j in range(n):
        best[j], cost[j] = _pixel(s, have, j, pal, cap, sx, sy, sz, fr, q, dd, ex_, ey_, ez_, e2)
    return best, cost

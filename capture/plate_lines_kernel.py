"""The line vertex of capture/plate_lines.py as one compiled loop over the pixels (numba).

:func:`vertex_costs` gives, per pixel, the winning candidate of ``plate_lines.line_vertex``'s step 2
and its cost: every frame's sample is a candidate for the background B, its cost the summed capped
squared distance of the pixel's other samples to the segments from it to the palette colours.  The
numpy path (``plate_lines._vertex_chunk``) builds about ten K x n float32 temporaries for each
candidate and palette colour; with FIXED_RING_FRAMES = 32 frames that was 66 s of a 24-view
1280x960 capture's 100-s plate stage (docs/speed.md).  Here each pixel's costs are summed in
registers, and a candidate's sum stops as soon as it can no longer win, which does not change the
winner: the candidates go in frame order, the first of equal costs wins (numpy's argmin), so a later
one must be strictly smaller, and a partial sum only grows.  The arithmetic is numpy's: float32
samples, palette, projections and distances (dot products and norms summed x, y, z), each distance
capped and squared in float64 and summed over the frames in frame order.  The winners and costs
equal the numpy path's bit for bit on the tests' scenes (tests/capture/test_plate_lines.py).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _segment(sx, sy, sz, bx, by, bz, pal, e2):
    """Distance (float32) of sample (sx, sy, sz) to the nearest segment from candidate (bx, by, bz)
    to a palette colour (pal (P, 3); e2 (P,): each segment's squared length, at least 1e-12)."""
    vx, vy, vz = sx - bx, sy - by, sz - bz
    best = np.float32(np.inf)
    for p in range(pal.shape[0]):
        ex, ey, ez = pal[p, 0] - bx, pal[p, 1] - by, pal[p, 2] - bz
        t = (vx * ex + vy * ey + vz * ez) / e2[p]
        t = min(max(t, np.float32(0.0)), np.float32(1.0))
        dx, dy, dz = vx - t * ex, vy - t * ey, vz - t * ez
        d = np.sqrt(dx * dx + dy * dy + dz * dz)
        if d < best:
            best = d
    return best


@njit(cache=True, nogil=True)
def _pixel(s, have, j, pal, cap, e2):
    """(winning candidate, its cost) of pixel ``j``; (-1, inf) when no frame has a sample."""
    K = s.shape[0]
    best_c = -1
    best = np.inf
    for c in range(K):
        if not have[c, j]:
            continue
        bx, by, bz = s[c, j, 0], s[c, j, 1], s[c, j, 2]
        for p in range(pal.shape[0]):
            ex, ey, ez = pal[p, 0] - bx, pal[p, 1] - by, pal[p, 2] - bz
            e2[p] = max(ex * ex + ey * ey + ez * ez, np.float32(1e-12))
        cost = 0.0
        for k in range(K):
            if have[k, j]:
                d = min(np.float64(_segment(s[k, j, 0], s[k, j, 1], s[k, j, 2], bx, by, bz, pal, e2)), cap)
                cost += d * d
                if cost >= best:  # it can only grow, and a later candidate must be strictly smaller
                    break
        if cost < best:
            best, best_c = cost, c
    return best_c, best


@njit(cache=True, nogil=True)
def vertex_costs(s, have, pal, cap):
    """(best (n,) int64: each pixel's winning candidate frame, -1 when it has no sample; cost (n,)
    float64: that candidate's summed capped squared distances) of samples ``s`` (K, n, 3) float32,
    ``have`` (K, n) bool (where False the sample is not read), palette ``pal`` (P, 3) float32 and the
    cap (float64, as numpy's float64 minimum with the float32 distances)."""
    n = s.shape[1]
    best = np.full(n, -1, np.int64)
    cost = np.full(n, np.inf)
    e2 = np.empty(pal.shape[0], np.float32)
    for j in range(n):
        c, v = _pixel(s, have, j, pal, cap, e2)
        best[j] = c
        cost[j] = v
    return best, cost

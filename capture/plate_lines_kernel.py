"""The candidates' costs of capture.plate_lines.line_vertex as one compiled loop (numba).

``plate_lines._vertex_chunk`` scores every frame's sample at a pixel as the background vertex:
for each candidate c, each sample k's distance to the nearest segment from c to a palette colour
(``segment_distance``), capped at LINE_CAP, squared and summed over the frames.  In numpy that is
K x K x n x P float32 temporaries per chunk; at 20 phone frames it was 60 % of the plate stage
(docs/speed.md, round 4).  :func:`vertex_costs` is the same arithmetic pixel by pixel: float32
differences, products and the channel sums in numpy's order ((x0 + x1) + x2), the clip, the norm's
float32 square root; the minimum over the palette and the cap in float64 (numpy's ``best`` array);
the squared distances summed over the frames in order (numpy's reduction over the first axis).
The costs equal the numpy path's bit for bit (tests/capture/test_plate_lines.py).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _costs(s0, have, pal, cap):
    K, n, _ = s0.shape
    P = pal.shape[0]
    zero = np.float32(0.0)
    one = np.float32(1.0)
    tiny = np.float32(1e-12)
    cost = np.full((K, n), np.inf)
    dist = np.empty(K, np.float64)
    for j in range(n):
        for c in range(K):
            if not have[c, j]:
                continue
            s0c0, s0c1, s0c2 = s0[c, j, 0], s0[c, j, 1], s0[c, j, 2]
            for k in range(K):
                dist[k] = np.inf
            for p in range(P):
                e0 = pal[p, 0] - s0c0
                e1 = pal[p, 1] - s0c1
                e2 = pal[p, 2] - s0c2
                ee = (e0 * e0 + e1 * e1) + e2 * e2
                if ee < tiny:
                    ee = tiny
                for k in range(K):
                    v0 = s0[k, j, 0] - s0c0
                    v1 = s0[k, j, 1] - s0c1
                    v2 = s0[k, j, 2] - s0c2
                    t = ((v0 * e0 + v1 * e1) + v2 * e2) / ee
                    t = min(max(t, zero), one)
                    d0 = v0 - t * e0
                    d1 = v1 - t * e1
                    d2 = v2 - t * e2
                    d = np.float64(np.sqrt((d0 * d0 + d1 * d1) + d2 * d2))
                    if d < dist[k]:
                        dist[k] = d
            total = 0.0
            first = True
            for k in range(K):
                dk = min(dist[k], cap)
                term = dk * dk if have[k, j] else 0.0
                if first:
                    total = term
                    first = False
                else:
                    total = total + term
            cost[c, j] = total
    return cost


def vertex_costs(s0: np.ndarray, have: np.ndarray, pal: np.ndarray, cap: float) -> np.ndarray:
    """(K, n) float64 cost of each frame's sample as a pixel's vertex (module docstring): ``s0``
    (K, n, 3) float32 samples (NaN already 0), ``have`` (K, n) bool, ``pal`` (P, 3) float32 object
    colours, ``cap`` the distance cap; inf where the candidate has no sample."""
    return _costs(np.ascontiguousarray(s0, np.float32), np.ascontiguousarray(have, np.bool_),
                  np.ascontiguousarray(pal, np.float32), float(cap))

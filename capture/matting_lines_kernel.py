"""The Gauss-Newton pass of capture.matting_lines.group_fit over every sample, compiled (numba), for
groups summed by ``np.bincount`` (the 3D cubes of capture.matting_cells.fit_cells).

Each of group_fit's GN_ITERATIONS + 1 passes computes, for every sample, its implied alpha against the
group's colour, its residual and eleven products, and sums them per group: in numpy some thirty
temporaries of the N samples a pass (a 72-view phone capture: N = 1.5 million, 8.3 s of the matte's
colour across views, docs/speed.md round 17).  :func:`gn_pass` does each sample once, without
temporaries, and adds its products to its group's totals in sample order, as ``np.bincount`` adds
them, so the totals are the same numbers.

The arithmetic is numpy's, operation for operation: a sum over the three channels left to right (as
numpy sums a row of three), ``x ** 2`` as ``x * x``, the clip, the square root, and ``(i == j) - v_i v_j``
as ``1.0 - v_i v_j`` or ``0.0 - v_i v_j``.  tests/capture/test_matting_lines_kernel.py compares the
totals and the implied alphas with numpy's, bit for bit.
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: The six entries of a symmetric 3 x 3 matrix (capture.matting_lines._PAIRS).
_I = (0, 0, 0, 1, 1, 2)
_J = (0, 1, 2, 1, 2, 2)


@njit(cache=True, nogil=True, error_model="numpy")
def gn_pass(C, B, w, F, group, K, T, imp_out):
    """One pass: ``T`` (K, 11) float64 zeroed, filled with the group totals of group_fit's columns (the
    six of Q, (w a) r (3), w |r|^2, w a^2) for samples ``C``, ``B`` (N, 3), weights ``w`` (N,) and the
    groups' colours ``F`` (K, 3), ``group`` (N,) int64; ``imp_out`` (N,) the implied alphas."""
    d = np.empty(3)
    fb = np.empty(3)
    r = np.empty(3)
    v = np.empty(3)
    for n in range(C.shape[0]):
        g = group[n]
        for c in range(3):
            d[c] = C[n, c] - B[n, c]
            fb[c] = F[g, c] - B[n, c]
        n2 = fb[0] * fb[0] + fb[1] * fb[1]
        n2 = n2 + fb[2] * fb[2]
        n2 = max(n2, 1e-12)
        dot = d[0] * fb[0] + d[1] * fb[1]
        dot = dot + d[2] * fb[2]
        imp = dot / n2
        imp_out[n] = imp
        a = min(max(imp, 0.0), 1.0)
        sq = np.sqrt(n2)
        for c in range(3):
            r[c] = d[c] - a * fb[c]
            v[c] = fb[c] / sq
        wn = w[n]
        wa2 = wn * (a * a)
        for k in range(6):
            i, j = _I[k], _J[k]
            e = (1.0 if i == j else 0.0) - v[i] * v[j]
            T[g, k] += wa2 * e
        wa = wn * a
        for c in range(3):
            T[g, 6 + c] += wa * r[c]
        rr = r[0] * r[0] + r[1] * r[1]
        rr = rr + r[2] * r[2]
        T[g, 9] += wn * rr
        T[g, 10] += wa2

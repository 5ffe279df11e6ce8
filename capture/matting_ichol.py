"""The known-background matte's preconditioner without an allocation per column (issue 32, round 14).

capture.matting_known solves its working-resolution system by pymatting's conjugate gradient with
pymatting's thresholded incomplete Cholesky factor (``pymatting.ichol``).  That factor's compiled loop
sorts each column's row indices with ``np.sort(c[:c_n])``, a new array per column (about 30,000 columns
a phone view): a quarter to a third of the factor's time (docs/speed.md round 14).  :func:`_ichol` is
pymatting 1.1.16's ``_ichol`` (MIT licence, Copyright (c) 2020 Thomas Germer and Tobias Uelwer),
copied line for line but for that sort, done in place by insertion (a column holds a few dozen rows):
the same integers in the same order, so the same factor bit for bit.  :func:`ichol` is
``pymatting.ichol`` with its defaults (the shifts tried in turn, the same ``max_nnz``, the same errors)
around it, returning pymatting's own ``CholeskyDecomposition``.

Switch ``ICHOL_IN_PLACE`` (False: ``pymatting.ichol``, the reference; tests/capture/test_matting_ichol.py
holds the two factors equal bit for bit).
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: capture.matting_known's preconditioner by :func:`ichol` (the column's rows sorted in place, the same
#: factor); False: ``pymatting.ichol``, the reference.
ICHOL_IN_PLACE = True
#: pymatting.ichol's defaults.
SHIFTS = (0.0, 1e-4, 1e-3, 1e-2, 0.1, 0.5, 1.0, 10.0, 100, 1e3, 1e4, 1e5)
MAX_NNZ = int(4e9 / 16)


@njit(cache=True, nogil=True)
def _ichol_start(n, Av, Ar, Ap, shift):
    """pymatting's ``_ichol``'s first loop: (t: first subdiagonal index in column j of A, r[j] =
    sum(abs(A[j:, j])) for the relative threshold, d: the diagonal of A plus ``shift``)."""
    t = np.zeros(n, np.int64)
    r = np.zeros(n, np.float64)
    d = np.full(n, shift, np.float64)
    for j in range(n):
        for idx in range(Ap[j], Ap[j + 1]):
            i = Ar[idx]
            if i == j:
                d[j] += Av[idx]
                t[j] = idx + 1
            if i >= j:
                r[j] += abs(Av[idx])
    return t, r, d


@njit("i8(i8, f8[:], i8[:], i8[:], f8[:], i8[:], i8[:], f8, f8, i8, f8, b1)", cache=True, nogil=True)
def _ichol(n, Av, Ar, Ap, Lv, Lr, Lp, discard_threshold, shift, max_nnz, relative_discard_threshold,
           diag_keep_discarded):
    """pymatting's ``_ichol`` (its comments kept short; its first loop in :func:`_ichol_start`), the
    column's rows sorted in place."""
    nnz = 0
    c_n = 0
    s = np.zeros(n, np.int64)  # next non-zero row index i in column j of L
    l = np.zeros(n, np.int64) - 1  # linked list of non-zero columns in row k of L
    a = np.zeros(n, np.float64)  # values of column j
    b = np.zeros(n, np.bool_)  # b[i]: the i-th element of column j is non-zero
    c = np.empty(n, np.int64)  # row indices of the non-zero elements in column j
    t, r, d = _ichol_start(n, Av, Ar, Ap, shift)
    for j in range(n):
        for idx in range(t[j], Ap[j + 1]):
            i = Ar[idx]
            L_ij = Av[idx]
            if L_ij != 0.0 and i > j:
                a[i] += L_ij
                if not b[i]:
                    b[i] = True
                    c[c_n] = i
                    c_n += 1
        k = l[j]
        while k != -1:
            k0 = s[k]
            k1 = Lp[k + 1]
            k2 = l[k]
            L_jk = Lv[k0]
            k0 += 1
            if k0 < k1:
                s[k] = k0
                i = Lr[k0]
                l[k] = l[i]
                l[i] = k
                for idx in range(k0, k1):
                    i = Lr[idx]
                    L_ik = Lv[idx]
                    a[i] -= L_ik * L_jk
                    if not b[i]:
                        b[i] = True
                        c[c_n] = i
                        c_n += 1
            k = k2
        if d[j] <= 0.0:
            return -1
        if nnz + 1 + c_n > max_nnz:
            return -2
        d[j] = np.sqrt(d[j])
        Lv[nnz] = d[j]
        Lr[nnz] = j
        nnz += 1
        s[j] = nnz
        for p in range(1, c_n):  # the rows in increasing order, in place (pymatting: np.sort(c[:c_n]))
            v = c[p]
            q = p - 1
            while q >= 0 and c[q] > v:
                c[q + 1] = c[q]
                q -= 1
            c[q + 1] = v
        for ci in range(c_n):
            i = c[ci]
            L_ij = a[i] / d[j]
            if diag_keep_discarded:
                d[i] -= L_ij * L_ij
            rel = relative_discard_threshold * r[j]
            if abs(L_ij) > discard_threshold and abs(a[i]) > rel:
                if not diag_keep_discarded:
                    d[i] -= L_ij * L_ij
                Lv[nnz] = L_ij
                Lr[nnz] = i
                nnz += 1
            a[i] = 0.0
            b[i] = False
        c_n = 0
        Lp[j + 1] = nnz
        if Lp[j] + 1 < Lp[j + 1]:
            i = Lr[Lp[j] + 1]
            l[j] = l[i]
            l[i] = j
    return nnz


def ichol(A, discard_threshold: float = 1e-4):
    """``pymatting.ichol(A, discard_threshold=...)`` (its other arguments at their defaults) by
    :func:`_ichol`: pymatting's ``CholeskyDecomposition`` of the same factor; pymatting itself with
    ICHOL_IN_PLACE off."""
    import scipy.sparse
    from pymatting import ichol as reference
    from pymatting.preconditioner.ichol import CholeskyDecomposition

    if not ICHOL_IN_PLACE:
        return reference(A, discard_threshold=discard_threshold)
    if isinstance(A, scipy.sparse.csr_matrix):
        A = A.T
    if not isinstance(A, scipy.sparse.csc_matrix):
        raise ValueError("Matrix A must be a scipy.sparse.csc_matrix")
    if not A.has_canonical_format:
        A.sum_duplicates()
    m, n = A.shape
    assert m == n
    Lv = np.empty(MAX_NNZ, dtype=np.float64)
    Lr = np.empty(MAX_NNZ, dtype=np.int64)
    Lp = np.zeros(n + 1, dtype=np.int64)
    nnz = -1
    for shift in SHIFTS:
        nnz = _ichol(n, A.data, A.indices.astype(np.int64), A.indptr.astype(np.int64), Lv, Lr, Lp,
                     discard_threshold, shift, MAX_NNZ, 0.0, True)
        if nnz >= 0:
            break
        if nnz == -1:  # pymatting's words (matting_known sends its stdout nowhere)
            print("PERFORMANCE WARNING:")
            print("Thresholded incomplete Cholesky decomposition failed due to insufficient positive-definiteness "
                  "of matrix A with parameters:")
            print(f"    discard_threshold = {discard_threshold:e}")
            print(f"    shift = {shift:e}")
            print("Try decreasing discard_threshold or start with a larger shift")
            print("")
        if nnz == -2:
            raise ValueError("Thresholded incomplete Cholesky decomposition failed because more than max_nnz "
                             "non-zero elements were created. Try increasing max_nnz or discard_threshold.")
    if nnz < 0:
        raise ValueError("Thresholded incomplete Cholesky decomposition failed due to insufficient "
                         "positive-definiteness of matrix A and diagonal shifts did not help.")
    return CholeskyDecomposition((Lv[:nnz], Lr[:nnz], Lp))

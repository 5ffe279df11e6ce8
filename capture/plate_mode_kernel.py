"""The fixed camera's robust mode (capture.plate_fixed.robust_mode) as one compiled loop a pixel
(issue 32, round 5).

The numpy path builds, per chunk of pixels, a K x K x n agreement array of the K frames' samples
(three channel comparisons, two weighted sums over it, the members' masked median): at 72 views of
1280x960 it was 21 s of the plate stage's 72 (docs/speed.md, round 5).  :func:`mode_members` does the
same a pixel at a time over the frames that have a sample there (the agreement of those in a small
scratch array, each pair compared once: it is symmetric), and
:func:`mode_median` the members' median by an insertion sort.

The arithmetic is numpy's, so the results are **equal bit for bit** (tests/capture/test_plate.py holds
``robust_mode(..., fast=True)`` against ``fast=False``): the sRGB values are numpy's (computed before
the loop), a difference and its comparison with MODE_TOL in float32 (numpy casts the Python float
to float32 before comparing), each cluster's weight a float32 sum in frame order (numpy's reduction
over the middle axis of a (K, K, n) array adds frame after frame; adding the zero of a sample that
does not agree changes nothing), the first of equal weights wins (argmax), and the median is
0.5 x (lo + hi) in float32 of the sorted finite member values, as capture.plate_reproject.nan_median.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _members(e, have, w, tol, ambiguous, out):
    K, n = have.shape
    close = np.zeros((K, K), np.bool_)  # among the pixel's present samples only
    idx = np.empty(K, np.int64)
    for p in range(n):
        m = 0
        for k in range(K):
            if have[k, p]:
                idx[m] = k
                m += 1
        for a in range(m):
            ka = idx[a]
            close[a, a] = True
            for b in range(a):
                kb = idx[b]
                ok = True
                for c in range(3):
                    if not (np.abs(e[ka, p, c] - e[kb, p, c]) <= tol):
                        ok = False
                        break
                close[a, b] = ok
                close[b, a] = ok
        # numpy's argmax runs over every frame, those without a sample weighing 0; where one of those
        # wins (the largest weight <= 0) no cluster is kept either way (rival >= 0 >= ambiguous x top)
        best, top = -1, np.float32(0.0)
        for a in range(m):
            acc = np.float32(0.0)
            for b in range(m):
                if close[a, b]:
                    acc += w[idx[b], p]
            if best < 0 or acc > top:
                best, top = a, acc
        if best < 0:
            continue
        rival = np.float32(0.0)
        for a in range(m):
            if close[best, a]:
                continue
            acc = np.float32(0.0)
            for b in range(m):
                if close[a, b] and not close[best, b]:
                    acc += w[idx[b], p]
            if acc > rival:
                rival = acc
        if rival < ambiguous * top:
            for a in range(m):
                out[idx[a], p] = close[best, a]


def mode_members(e: np.ndarray, have: np.ndarray, w: np.ndarray, tol: float, ambiguous: float) -> np.ndarray:
    """(K, n) bool: the samples of each pixel's heaviest agreeing cluster, none where a rival cluster
    weighs ``ambiguous`` of it (capture.plate_fixed.robust_mode); ``e`` (K, n, 3) float32 sRGB,
    ``have`` (K, n) bool, ``w`` (K, n) float32 (0 where not ``have``; not NaN)."""
    e = np.ascontiguousarray(e, np.float32)
    out = np.zeros(have.shape, np.bool_)
    _members(e, np.ascontiguousarray(have, np.bool_), np.ascontiguousarray(w, np.float32), np.float32(tol),
             np.float32(ambiguous), out)
    return out


@njit(cache=True, nogil=True)
def sorted_insert(buf, m, v):
    """Put ``v`` into the ascending ``buf[:m]`` (one step of an insertion sort, equal values kept in their
    order of arrival); the new count, m + 1."""
    i = m
    while i > 0 and buf[i - 1] > v:
        buf[i] = buf[i - 1]
        i -= 1
    buf[i] = v
    return m + 1


@njit(cache=True, nogil=True)
def sorted_median(buf, m):
    """The median of the ascending float32 ``buf[:m]`` (m >= 1): 0.5 x (lo + hi) in float32, as
    capture.plate_reproject.nan_median takes it."""
    return np.float32(0.5) * (buf[(m - 1) // 2] + buf[m // 2])


@njit(cache=True, nogil=True)
def _median(s, members, out):
    K, n, C = s.shape
    buf = np.empty(K, np.float32)
    for p in range(n):
        for c in range(C):
            m = 0
            for k in range(K):
                v = s[k, p, c]
                if members[k, p] and np.isfinite(v):
                    m = sorted_insert(buf, m, v)
            out[p, c] = np.nan if m == 0 else sorted_median(buf, m)


def mode_median(s: np.ndarray, members: np.ndarray) -> np.ndarray:
    """(n, 3) float32 median of the ``members`` (K, n) samples of ``s`` (K, n, 3) float32, per channel
    (capture.plate_reproject.nan_median of the samples masked by ``members``); NaN without any."""
    out = np.empty(s.shape[1:], np.float32)
    _median(np.ascontiguousarray(s, np.float32), np.ascontiguousarray(members, np.bool_), out)
    return out

"""The fixed camera's prediction at a set of pixels as two compiled passes (issue 32, round 11).

``capture.plate_fixed.fixed_prediction`` gathers each frame's samples with four numpy passes a frame
(weights, colours x gain, blown-out flags), then ``censored_mode`` copies them twice, the robust mode
copies a chunk again, takes a power per sample for its sRGB values (``capture.scan.linear_to_srgb``)
and hands (K, n) arrays to ``capture.plate_mode_kernel``.  Here:

1. :func:`gather_frame` (a call a frame) reads a frame's weight and float16 colour codes at the
   pixels and writes, pixel-major, what the robust mode reads: the sample in the common exposure
   (``float32(float64(colour) x gain)``, numpy's product of a float16 by a float64 gain, then the
   cast), its sRGB value from a table of the frame's 0x7C01 non-negative float16 codes (made by
   numpy's own ``linear_to_srgb(np.fmax(sample, 0))``, so the same float32 values; a negative or NaN
   code's sample clips to 0 there, as code 0's does), its weight, and whether it is free (a
   measurement), blown out (a lower bound) or no sample.
2. :func:`censored_pixels` does ``censored_mode`` a pixel at a time: the heaviest agreeing cluster of
   the free samples with ``plate_mode_kernel._members``'s arithmetic and order (float32 weights summed
   in frame order, the first of equal weights wins, MODE_TOL compared in float32), the members' median
   per channel (0.5 x (lo + hi) in float32), then the blown-out samples' largest value as the bound.
   The rival cluster's weight is summed only when it can matter: it is at most the float32 sum (in frame
   order) of every sample outside the heaviest cluster, since a float32 sum of non-negative terms in a
   fixed order never exceeds that of a superset in the same order (rounding is monotone), so when that
   sum is already below MODE_AMBIGUOUS x the cluster's weight the rival cannot be heavier.

The results equal the numpy path's bit for bit (tests/capture/test_plate_predict.py).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from capture.plate_mode_kernel import sorted_insert, sorted_median

#: gather_frame's flags: no sample, a free sample (a measurement), a blown-out sample (a lower bound).
NONE, FREE, HOT = 0, 1, 2
#: Float16 codes the sRGB tables hold: 0 .. +inf (0x7C00); every other code (negative, NaN) is read as 0.
TABLE_CODES = 0x7C01


@njit(cache=True, nogil=True)
def _nan16(c):
    return (c & 0x7C00) == 0x7C00 and (c & 0x03FF) != 0


@njit(cache=True, nogil=True)
def gather_frame(lin16, weight, ys, xs, gain, dec, srgb, hot_code, k, S, E, W, F):
    """Frame ``k``'s samples at pixels (``ys``, ``xs``) into row ``k`` of the pixel-major buffers
    ``S`` (n, K, 3) float32 sample x gain, ``E`` (n, K, 3) float32 its sRGB, ``W`` (n, K) float32
    weight and ``F`` (n, K) uint8 flag (module docstring; ``F`` must start as NONE).  ``lin16``
    (H, W, 3) uint16 the frame's float16 codes, ``weight`` (H, W) float32, ``gain`` (3,) float64,
    ``dec`` (65536,) float64 each code's value, ``srgb`` (3, TABLE_CODES) float32 the frame's table,
    ``hot_code`` (65536,) bool each code at or above the clip level (as float16)."""
    for p in range(ys.shape[0]):
        y, x = ys[p], xs[p]
        w = weight[y, x]
        if not (w > 0):
            continue
        c0, c1, c2 = lin16[y, x, 0], lin16[y, x, 1], lin16[y, x, 2]
        s0 = np.float32(dec[c0] * gain[0])
        s1 = np.float32(dec[c1] * gain[1])
        s2 = np.float32(dec[c2] * gain[2])
        if not np.isfinite(s0):
            continue  # neither a measurement nor a bound (censored_mode: hot &= finite)
        S[p, k, 0], S[p, k, 1], S[p, k, 2] = s0, s1, s2
        nan = _nan16(c0) or _nan16(c1) or _nan16(c2)  # channel_max of a NaN is NaN: not blown out
        if not nan and (hot_code[c0] or hot_code[c1] or hot_code[c2]):
            F[p, k] = 2
            continue
        F[p, k] = 1
        W[p, k] = w
        E[p, k, 0] = srgb[0, c0 if c0 < 0x7C01 else 0]
        E[p, k, 1] = srgb[1, c1 if c1 < 0x7C01 else 0]
        E[p, k, 2] = srgb[2, c2 if c2 < 0x7C01 else 0]


@njit(cache=True, nogil=True)
def _cluster(e0, e1, e2, w, m, tol, ambiguous, close, score):
    """The centre of the heaviest cluster among the first ``m`` samples (sRGB ``e0``, ``e1``, ``e2`` (m,),
    weights ``w`` (m,), all > 0); -1 where none is kept.  ``close`` (K, K) is left with the agreement
    (symmetric), ``score`` with each sample's cluster weight."""
    for a in range(m):  # every pair (vectorised over b; |x - y| is |y - x| bit for bit)
        for b in range(m):
            close[a, b] = (np.abs(e0[a] - e0[b]) <= tol) & (np.abs(e1[a] - e1[b]) <= tol) \
                & (np.abs(e2[a] - e2[b]) <= tol)
    for a in range(m):
        score[a] = 0.0
    for b in range(m):  # each row's sum in frame order (b), the rows side by side (vectorised over a)
        wb = w[b]
        for a in range(m):
            score[a] += wb if close[b, a] else np.float32(0.0)  # + 0 leaves a non-negative sum as it is
    best, top = -1, np.float32(0.0)
    for a in range(m):
        if best < 0 or score[a] > top:
            best, top = a, score[a]
    if best < 0:
        return -1
    outside = np.float32(0.0)  # an upper bound of the rival's weight (module docstring)
    for b in range(m):
        if not close[best, b]:
            outside += w[b]
    limit = ambiguous * top
    if not (outside < limit):
        rival = np.float32(0.0)
        for a in range(m):
            if close[best, a]:
                continue
            acc = np.float32(0.0)
            for b in range(m):
                if close[a, b] and not close[best, b]:
                    acc += w[b]
            if acc > rival:
                rival = acc
        if not (rival < limit):
            return -1
    return best


@njit(cache=True, nogil=True)
def censored_pixels(S, E, W, F, tol, ambiguous, min_frames, col, bound):
    """Per pixel of the buffers (:func:`gather_frame`), ``capture.plate_fixed.censored_mode``'s colour
    ``col`` (n, 3) float32 and ``bound`` (n,) bool (module docstring)."""
    n, K = F.shape
    close = np.zeros((K, K), np.bool_)
    score = np.empty(K, np.float32)
    e0, e1, e2 = np.empty(K, np.float32), np.empty(K, np.float32), np.empty(K, np.float32)
    w = np.empty(K, np.float32)
    idx = np.empty(K, np.int64)
    buf = np.empty(K, np.float32)
    for p in range(n):
        m, n_hot = 0, 0
        lb0 = lb1 = lb2 = np.float32(-np.inf)
        for k in range(K):
            f = F[p, k]
            if f == 1:
                idx[m] = k
                e0[m], e1[m], e2[m] = E[p, k, 0], E[p, k, 1], E[p, k, 2]
                w[m] = W[p, k]
                m += 1
            elif f == 2:
                n_hot += 1
                lb0, lb1, lb2 = _nan_max(lb0, S[p, k, 0]), _nan_max(lb1, S[p, k, 1]), _nan_max(lb2, S[p, k, 2])
        best = _cluster(e0, e1, e2, w, m, tol, ambiguous, close, score)
        support = 0
        if best >= 0:
            for a in range(m):
                if close[best, a]:
                    support += 1
        if support >= min_frames:
            for c in range(3):
                v = _member_median(S, p, idx, close, best, m, c, buf)
                lb = lb0 if c == 0 else (lb1 if c == 1 else lb2)
                col[p, c] = _max(v, lb)
        elif n_hot >= min_frames:
            bound[p] = True
            col[p, 0], col[p, 1], col[p, 2] = lb0, lb1, lb2
        else:
            col[p, 0] = col[p, 1] = col[p, 2] = np.nan


@njit(cache=True, nogil=True)
def _nan_max(a, b):
    """numpy's max reduction of two values (NaN propagates)."""
    if np.isnan(a) or np.isnan(b):
        return np.float32(np.nan)
    return a if a >= b else b


@njit(cache=True, nogil=True)
def _max(a, b):
    """np.maximum(a, b) of float32 (NaN propagates; the first of equal values)."""
    if np.isnan(a) or np.isnan(b):
        return np.float32(np.nan)
    return a if a >= b else b


@njit(cache=True, nogil=True)
def _member_median(S, p, idx, close, best, m, c, buf):
    """Median of channel ``c`` of the cluster's finite samples (plate_mode_kernel._median's)."""
    cnt = 0
    for a in range(m):
        if not close[best, a]:
            continue
        v = S[p, idx[a], c]
        if np.isfinite(v):
            cnt = sorted_insert(buf, cnt, v)
    if cnt == 0:
        return np.float32(np.nan)
    return sorted_median(buf, cnt)

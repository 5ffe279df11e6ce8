"""The edge-aware depth resampling of capture/resample.py as one compiled loop over the colour pixels (numba).

:func:`upsample_depth_kernel` is the rule of ``capture.resample`` (module docstring there) pixel by
pixel, in the same arithmetic as the vectorised numpy path (``capture.resample.upsample_depth_numpy``):
float64 taps, weights and depths, the colour term of the joint-bilateral score in float32, the first
of equal scores.  The numpy path builds some ten float64 temporaries per colour pixel; a
phone capture's 200 views of 1920x1440 spent 58 s of its 8 minutes there (docs/speed.md).  The
depth it gives equals the numpy path's bit for bit on the tests' scenes and the phone frames; the
one place the two may part is the float32 exponential of the colour term (numpy's own SIMD exp
against the C library's), which decides only between nearly equal scores (tests/capture/test_resample.py
states the tolerance).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _edge_choice(depth, glo, guide, v, u, y, x, jj, ii, b, d, rel, two_ss2, two_sr2):
    """An edge pixel's joint-bilateral choice (capture.resample): (its depth, 0 for a hole; the
    winning tap; the nearest tap), the first of equal scores as numpy's argmax / argmin."""
    best = -1.0
    win = 0
    near = 0
    dnear = np.inf
    for k in range(4):
        dy = y - jj[k]
        dx = x - ii[k]
        dist2 = dy * dy + dx * dx
        c = np.float32(0.0)
        for ch in range(3):
            e = guide[v, u, ch] - glo[jj[k], ii[k], ch]
            c = c + e * e
        s = np.exp(-dist2 / two_ss2) * np.float64(np.exp(-c / two_sr2))
        if s > best:
            best = s
            win = k
        if dist2 < dnear:
            dnear = dist2
            near = k
    dw = d[win]
    if dw <= 0:
        return 0.0, win, near
    num = 0.0
    den = 0.0
    for k in range(4):
        if d[k] > 0 and abs(d[k] - dw) <= rel * dw:
            bw = b[k] + 1e-9
            num += bw * d[k]
            den += bw
    return num / max(den, 1e-30), win, near


@njit(cache=True, nogil=True)
def _taps(c, f, n):
    """(lower tap, upper tap, both clamped to [0, n); the weight of the upper; the position) of
    colour pixel ``c`` on an axis of ``n`` depth samples, ``f`` depth samples a colour pixel (pixel
    centres aligned)."""
    p = f * (c + 0.5) - 0.5
    lp = np.floor(p)
    return min(max(int(lp), 0), n - 1), min(max(int(lp) + 1, 0), n - 1), p - lp, p


@njit(cache=True, nogil=True)
def _kernel(depth, glo, guide, fy, fx, rel, two_ss2, two_sr2):
    h, w = depth.shape
    H, W = guide.shape[0], guide.shape[1]
    out = np.zeros((H, W), np.float32)
    n_edge = 0
    n_colour = 0
    n_holes = 0
    jj = np.empty(4, np.int64)
    ii = np.empty(4, np.int64)
    b = np.empty(4, np.float64)
    d = np.empty(4, np.float64)
    for v in range(H):
        j0, j1, ty, y = _taps(v, fy, h)
        for u in range(W):
            i0, i1, tx, x = _taps(u, fx, w)
            jj[0], jj[1], jj[2], jj[3] = j0, j0, j1, j1
            ii[0], ii[1], ii[2], ii[3] = i0, i1, i0, i1
            b[0] = (1.0 * (1.0 - ty)) * (1.0 - tx)
            b[1] = (1.0 * (1.0 - ty)) * tx
            b[2] = (1.0 * ty) * (1.0 - tx)
            b[3] = (1.0 * ty) * tx
            nvalid = 0
            dmin = np.inf
            dmax = -np.inf
            for k in range(4):
                d[k] = depth[jj[k], ii[k]]
                if d[k] > 0:
                    nvalid += 1
                    dmin = min(dmin, d[k])
                dmax = max(dmax, d[k])
            if nvalid == 0:  # no measured tap: an edge pixel whose every choice is a hole
                n_edge += 1
                n_holes += 1
                continue
            if nvalid == 4 and dmax - dmin <= rel * dmin:
                out[v, u] = (((b[0] * d[0]) + b[1] * d[1]) + b[2] * d[2]) + b[3] * d[3]
                continue
            n_edge += 1
            val, win, near = _edge_choice(depth, glo, guide, v, u, y, x, jj, ii, b, d, rel, two_ss2, two_sr2)
            if val <= 0:
                n_holes += 1
                continue
            out[v, u] = val
            if win != near:
                n_colour += 1
    return out, n_edge, n_colour, n_holes


def upsample_depth_kernel(depth: np.ndarray, glo: np.ndarray, guide: np.ndarray, sx: float, sy: float,
                          rel: float, sigma_spatial: float, sigma_colour: float) -> tuple[np.ndarray, int, int, int]:
    """(H, W) float32 depth, edge pixels, colour-decided pixels, holes: ``depth`` (h, w) float64
    (0 = none) at the colour ``guide`` (H, W, 3) float32 sRGB, ``glo`` (h, w, 3) float32 the guide
    averaged over each depth pixel; ``sx``, ``sy`` colour pixels per depth pixel; ``rel`` the
    discontinuity fraction, ``sigma_spatial`` (depth pixels) and ``sigma_colour`` the score's sigmas
    (the colour one's 2 sigma^2 rounded to float32, as the numpy path divides by it)."""
    out, e, c, o = _kernel(np.ascontiguousarray(depth, np.float64), np.ascontiguousarray(glo, np.float32),
                           np.ascontiguousarray(guide, np.float32), 1 / sy, 1 / sx, float(rel),
                           float(2 * sigma_spatial**2), np.float32(2 * sigma_colour**2))
    return out, int(e), int(c), int(o)

"""The push-pull fill's levels compiled (capture.fill; issue 32, docs/speed.md round 10).

The numpy fill (``capture.fill._push_pull``) makes about ten full-size temporaries per level (the
padded premultiplied values and weights, the four strided sums, the division, two ``where``\\ s and
the 2x zoom); a 1280x960 view's matte called it 11 times, a fifth of the matte's time in the pool's
workers.  Here each level is two passes, with the same float64 operations in the same order:

* :func:`down_level`: the 2 x 2 box sums of the premultiplied values ``v * w`` and of the weights
  (the odd row / column padded with 0.0, as the numpy fill's zero padding), in the order
  ``capture.fill._down`` adds them (pairwise ``(a00 + a01) + (a10 + a11)`` for the weights and for one
  channel, in turn ``((a00 + a01) + a10) + a11`` over several); the coarse value ``vs / max(ws, 1e-12)``
  where ``ws > 0``, else 0; the coarse weight ``min(ws, 1)`` (NaN kept, as ``np.minimum``); and whether
  any / every coarse weight is non-zero (numpy's truth of a float).
* :func:`up_select`: ``capture.matting_fast.zoom2``'s bilinear 2x step (its four taps in its order, each
  tap value x row weight x column weight) where the fine weight is not above 0, the fine value where it is.

The same values bit for bit as the numpy fill (tests/capture/test_fill.py).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _tap(v, w, i, j, k, h, wd):
    """The premultiplied value ``v[i, j, k] * w[i, j]`` of a fine pixel, 0.0 in the padding."""
    if i < h and j < wd:
        return v[i, j, k] * w[i, j]
    return 0.0


@njit(cache=True, nogil=True)
def _weight(w, i, j, h, wd):
    """The fine weight ``w[i, j]``, 0.0 in the padding."""
    if i < h and j < wd:
        return w[i, j]
    return 0.0


@njit(cache=True, nogil=True)
def down_level(v, w):
    """(coarse values (h2, w2, C), coarse weights (h2, w2), any weight non-zero, every weight
    non-zero) of float64 (h, wd, C) ``v`` and (h, wd) ``w`` (module docstring)."""
    h, wd, nc = v.shape
    h2, w2 = (h + 1) // 2, (wd + 1) // 2
    cv = np.empty((h2, w2, nc), np.float64)
    cw = np.empty((h2, w2), np.float64)
    any_w, all_w = False, True
    for I in range(h2):
        i0, i1 = 2 * I, 2 * I + 1
        for J in range(w2):
            j0, j1 = 2 * J, 2 * J + 1
            ws = (_weight(w, i0, j0, h, wd) + _weight(w, i0, j1, h, wd)) + \
                (_weight(w, i1, j0, h, wd) + _weight(w, i1, j1, h, wd))
            d = ws if ws > 1e-12 else 1e-12
            for k in range(nc):
                if nc == 1:
                    vs = (_tap(v, w, i0, j0, k, h, wd) + _tap(v, w, i0, j1, k, h, wd)) + \
                        (_tap(v, w, i1, j0, k, h, wd) + _tap(v, w, i1, j1, k, h, wd))
                else:
                    vs = ((_tap(v, w, i0, j0, k, h, wd) + _tap(v, w, i0, j1, k, h, wd)) +
                          _tap(v, w, i1, j0, k, h, wd)) + _tap(v, w, i1, j1, k, h, wd)
                cv[I, J, k] = vs / d if ws > 0 else 0.0
            c = 1.0 if ws >= 1.0 else ws
            cw[I, J] = c
            if c != 0:
                any_w = True
            else:
                all_w = False
    return cv, cw, any_w, all_w


@njit(cache=True, nogil=True)
def up_select(c, v, w):
    """(h, wd, C): ``v`` where ``w > 0``, else ``zoom2(c, h, wd)`` at that pixel (module docstring)."""
    n0, n1, nc = c.shape
    h, wd = w.shape
    out = np.empty((h, wd, nc), np.float64)
    for i in range(h):
        y0 = (i - 1) // 2 if i % 2 == 0 else i // 2
        wy1 = 0.75 if i % 2 == 0 else 0.25
        wy0 = 1.0 - wy1
        a0 = min(max(y0, 0), n0 - 1)
        a1 = min(max(y0 + 1, 0), n0 - 1)
        for j in range(wd):
            if w[i, j] > 0:
                for k in range(nc):
                    out[i, j, k] = v[i, j, k]
                continue
            x0 = (j - 1) // 2 if j % 2 == 0 else j // 2
            wx1 = 0.75 if j % 2 == 0 else 0.25
            wx0 = 1.0 - wx1
            b0 = min(max(x0, 0), n1 - 1)
            b1 = min(max(x0 + 1, 0), n1 - 1)
            for k in range(nc):
                t = 0.0
                t += c[a0, b0, k] * wy0 * wx0
                t += c[a0, b1, k] * wy0 * wx1
                t += c[a1, b0, k] * wy1 * wx0
                t += c[a1, b1, k] * wy1 * wx1
                out[i, j, k] = t
    return out

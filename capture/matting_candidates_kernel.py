"""Step 2's choice of candidate colours (capture.matting_known.candidate_alpha through fit_candidates) in
one compiled pass over the pixels (issue 32, docs/speed.md round 12).

candidate_alpha made, per candidate, about fifteen float64 temporaries of the (..., 3) colour and
four ``np.where`` over the pixels: 0.03 s of a phone view's matte for two calls.  Here each pixel
runs the candidates in candidate_alpha's order (the nearest sure colour, the palette's colours, the
extra candidates) with numpy's arithmetic on the same float64 values: E = P - B, the channel sums
in capture.matting_fast.channel_sum's order ((x0 + x1) + x2), alpha = clip(de / maximum(e2, 1e-9),
lower, 1) with ``np.clip``'s rule (a NaN value stays, a tie keeps the bound: clip(-0.0, 0.0) is 0.0),
the residual's square root, the margin added after the first, the strict ``cost < best`` (a NaN cost
never wins); then the confidence with the squares as products (numpy's ``x ** 2``) and 0 where the
best residual is not finite.

The numpy path stays the reference (``FUSED_CANDIDATES`` False); tests/capture/test_matting_bound.py
holds them against each other bit for bit.
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: fit_candidates by the compiled pass (the same values bit for bit); False: candidate_alpha's numpy.
FUSED_CANDIDATES = True


@njit(cache=True, inline="always")
def _clip(x, lo, hi):
    """``np.clip(x, lo, hi)`` of floats: max then min, each keeping a NaN first operand and taking the
    second unless the first is strictly beyond it."""
    if x != x:
        return x
    m = x if x > lo else lo
    if m != m:
        return m
    return m if m < hi else hi


@njit(cache=True, inline="always")
def _alpha_res(d0, d1, d2, e0, e1, e2_, lower):
    e2 = (e0 * e0 + e1 * e1) + e2_ * e2_
    de = (d0 * e0 + d1 * e1) + d2 * e2_
    den = e2 if (e2 != e2 or e2 > 1e-9) else 1e-9
    a = _clip(de / den, lower, 1.0)
    r0, r1, r2 = d0 - a * e0, d1 - a * e1, d2 - a * e2_
    return a, np.sqrt((r0 * r0 + r1 * r1) + r2 * r2), e2


@njit(cache=True)
def _fit(C, B, pix, consts, lower, margin, sep2_ref, res2_ref):  # pragma: no cover - compiled
    n = C.shape[0]
    kp, kc = pix.shape[0], consts.shape[0]
    a_out = np.empty(n, np.float64)
    conf = np.empty(n, np.float64)
    for i in range(n):
        b0, b1, b2 = B[i, 0], B[i, 1], B[i, 2]
        d0, d1, d2 = C[i, 0] - b0, C[i, 1] - b1, C[i, 2] - b2
        best_cost, best_res, a_hat, sep = np.inf, np.inf, 0.0, 0.0
        for k in range(kp + kc):
            if k == 0:
                p0, p1, p2 = pix[0, i, 0], pix[0, i, 1], pix[0, i, 2]
            elif k <= kc:
                p0, p1, p2 = consts[k - 1, 0], consts[k - 1, 1], consts[k - 1, 2]
            else:
                j = k - kc
                p0, p1, p2 = pix[j, i, 0], pix[j, i, 1], pix[j, i, 2]
            a, res, e2 = _alpha_res(d0, d1, d2, p0 - b0, p1 - b1, p2 - b2, lower[i])
            cost = res + (margin if k else 0.0)
            if cost < best_cost:
                best_cost, best_res, a_hat, sep = cost, res, a, np.sqrt(e2)
        s2 = sep * sep
        c = (s2 / (s2 + sep2_ref)) * (res2_ref / (best_res * best_res + res2_ref))
        a_out[i] = a_hat
        conf[i] = c if np.isfinite(best_res) else 0.0
    return a_out, conf


def _takes(image, arrays) -> bool:
    return (FUSED_CANDIDATES and isinstance(image, np.ndarray) and image.ndim >= 1 and image.shape[-1] == 3
            and all(isinstance(a, np.ndarray) and a.shape == image.shape and a.dtype in (np.float32, np.float64)
                    for a in [image, *arrays]))


def fit_fused(image, background, nearest, palette_colours, extra, lower, margin: float, separation: float,
              residual: float):
    """capture.matting_known.fit_candidates' (alpha_hat, confidence) by the compiled pass (module
    docstring), or None when the arrays are not its (per-pixel candidates of the image's shape) or
    FUSED_CANDIDATES is off.  ``palette_colours`` (K, 3): the palette."""
    extra = list(extra)
    if not isinstance(lower, np.ndarray) or lower.ndim == 0 or not _takes(image, [background, nearest, *extra]):
        return None
    shape = image.shape[:-1]
    try:
        lo = np.ascontiguousarray(np.broadcast_to(np.asarray(lower, np.float64), shape)).reshape(-1)
    except ValueError:
        return None
    pix = np.stack([np.asarray(p, np.float64).reshape(-1, 3) for p in [nearest, *extra]])
    consts = np.ascontiguousarray(np.asarray(palette_colours, np.float64).reshape(-1, 3))
    rows = [np.ascontiguousarray(np.asarray(x, np.float64)).reshape(-1, 3) for x in (image, background)]
    a, conf = _fit(*rows, pix, consts, lo, float(margin), float(separation) ** 2, float(residual) ** 2)
    return a.reshape(shape), conf.reshape(shape)

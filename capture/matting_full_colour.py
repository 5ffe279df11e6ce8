"""The working-resolution matte's full-resolution colour (capture.matting_scale._full_colour) in one
compiled pass (issue 32, docs/speed.md round 12).

_full_colour made the blown-out test, three masks, F = clip(B + (C - B) / maximum(alpha, 1e-6), 0, 1)
over every pixel of the crop in float64 and two ``np.where``: about ten full-size temporaries.  Here
each pixel does the same in numpy's arithmetic for the pipeline's dtypes (photo, plate and upsampled
colour float32, alpha float64, known bool): the blown-out test as capture.matting_bound's, C - B in
float32 then the quotient and the sum in float64, the clip to [0, 1] as numpy's with scalar bounds
(a NaN stays, -0.0 stays), the photo's or the upsampled colour widened to float64 where F is not
taken.  Other dtypes take the numpy reference (``FUSED_FULL_COLOUR`` False: always);
tests/capture/test_matting_bound.py holds the two against each other bit for bit.
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: capture.matting_scale._full_colour by the compiled pass (the same values bit for bit); False: numpy.
FUSED_FULL_COLOUR = True


@njit(cache=True, inline="always")
def _max3(x0, x1, x2):
    """``x.max(-1)`` of three values (NaN if any is)."""
    if x0 != x0 or x1 != x1 or x2 != x2:
        return np.nan
    m = x0 if x0 >= x1 else x1
    return m if m >= x2 else x2


@njit(cache=True)
def _colour(C, B, A, K, F_up, clip32, opaque):  # pragma: no cover - compiled
    n = C.shape[0]
    out = np.empty((n, 3), np.float64)
    for i in range(n):
        a = A[i]
        hot = (_max3(np.float64(C[i, 0]), np.float64(C[i, 1]), np.float64(C[i, 2])) >= clip32) or \
            (_max3(np.float64(B[i, 0]), np.float64(B[i, 1]), np.float64(B[i, 2])) >= clip32)
        pos = a > 0
        blown = K[i] and hot and pos
        ok = K[i] and not blown and pos
        if ok:
            m = a if (a != a or a > 1e-6) else 1e-6
            for k in range(3):
                v = np.float64(B[i, k]) + np.float64(C[i, k] - B[i, k]) / m
                if v == v:
                    v = 0.0 if v < 0.0 else (1.0 if v > 1.0 else v)
                out[i, k] = v
        elif a >= opaque and not blown:
            for k in range(3):
                out[i, k] = C[i, k]
        else:
            for k in range(3):
                out[i, k] = F_up[i, k]
    return out


def full_colour(image, a, background, known, f_up, clip_level: float, opaque_alpha: float):
    """capture.matting_scale._full_colour's (h, w, 3) float64, or None when the arrays are not the
    pipeline's dtypes and shapes (module docstring) or FUSED_FULL_COLOUR is off."""
    arrays = (image, a, background, known, f_up)
    if not FUSED_FULL_COLOUR or not all(isinstance(x, np.ndarray) for x in arrays):
        return None
    shape = image.shape
    if not (image.ndim == 3 and shape[-1] == 3 and background.shape == shape and f_up.shape == shape
            and a.shape == shape[:2] and known.shape == shape[:2] and image.dtype == np.float32
            and background.dtype == np.float32 and f_up.dtype == np.float32 and a.dtype == np.float64
            and known.dtype == np.bool_):
        return None
    rows = [np.ascontiguousarray(x).reshape(-1, 3) for x in (image, background)]
    out = _colour(*rows, np.ascontiguousarray(a).reshape(-1), np.ascontiguousarray(known).reshape(-1),
                  np.ascontiguousarray(f_up).reshape(-1, 3), float(np.float32(clip_level)), float(opaque_alpha))
    return out.reshape(shape)

"""The known-background matte's per-pixel bound and blown-out test in one compiled pass each (issue 32,
docs/speed.md round 12).

capture.matting_known.alpha_lower_bound made six float64 temporaries of the (..., 3) colour (the
difference, the slack, the room, the ratio and two ``np.where``) and a channel maximum, and
capture.matting_known.clipped two channel maxima and their comparisons: about 0.045 s of a phone
view's 0.45 s matte (docs/speed.md round 12).  Here each is one loop over the pixels doing numpy's
arithmetic in numpy's order on the same float64 values:

* :func:`lower_bound`: per channel d = C - B, slack = |d| - (noise + rel B), room = 1 - B where d > 0
  else B, the ratio slack / maximum(room, 1e-6) where slack > 0 else 0; the channels' maximum and the
  clip to [0, 1], NaN propagating as ``np.maximum`` / ``np.clip`` do.
* :func:`clipped_mask`: the channel maximum (NaN propagating) of the photo and of the plate compared
  with the level, each in its own array's precision (numpy 2 compares a float32 array with a Python
  float in float32: the level is given rounded to each array's dtype).

The numpy expressions stay the reference (``FUSED_BOUND`` False); tests/capture/test_matting_bound.py
holds the two against each other bit for bit.
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: Use the compiled passes for alpha_lower_bound and clipped (same values bit for bit); False: numpy.
FUSED_BOUND = True


@njit(cache=True, inline="always")
def _nanmax(a, b):
    """``np.maximum(a, b)`` of two floats: NaN if either is."""
    if a != a:
        return a
    if b != b:
        return b
    return a if a >= b else b


@njit(cache=True)
def _lower_bound(C, B, noise, rel):  # pragma: no cover - compiled
    n = C.shape[0]
    out = np.empty(n, np.float64)
    for i in range(n):
        m = 0.0
        for k in range(3):
            c = np.float64(C[i, k])
            b = np.float64(B[i, k])
            d = c - b
            slack = abs(d) - (noise + rel * b)
            room = 1.0 - b if d > 0 else b
            room = _nanmax(room, 1e-6)
            lo = slack / room if slack > 0 else 0.0
            m = lo if k == 0 else _nanmax(m, lo)
        if m == m:
            m = 1.0 if m > 1.0 else (0.0 if m < 0.0 else m)
        out[i] = m
    return out


@njit(cache=True)
def _clipped(C, B, level_c, level_b):  # pragma: no cover - compiled
    n = C.shape[0]
    out = np.empty(n, np.bool_)
    for i in range(n):
        mc = _nanmax(_nanmax(np.float64(C[i, 0]), np.float64(C[i, 1])), np.float64(C[i, 2]))
        mb = _nanmax(_nanmax(np.float64(B[i, 0]), np.float64(B[i, 1])), np.float64(B[i, 2]))
        out[i] = (mc >= level_c) or (mb >= level_b)
    return out


def _fits(image, background) -> bool:
    """Whether the compiled passes take these arrays: the same shape (..., 3), float32 or float64."""
    return (FUSED_BOUND and isinstance(image, np.ndarray) and isinstance(background, np.ndarray)
            and image.shape == background.shape and image.ndim >= 1 and image.shape[-1] == 3
            and image.dtype in (np.float32, np.float64) and background.dtype in (np.float32, np.float64))


def _rows(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a).reshape(-1, 3)


def lower_bound(image, background, noise: float, rel: float) -> np.ndarray | None:
    """capture.matting_known.alpha_lower_bound's (...) float64 values, or None when the arrays are not
    the compiled pass's (module docstring) or FUSED_BOUND is off."""
    if not _fits(image, background):
        return None
    return _lower_bound(_rows(image), _rows(background), float(noise), float(rel)).reshape(image.shape[:-1])


def clipped_mask(image, background, level: float) -> np.ndarray | None:
    """capture.matting_known.clipped's (...) bool, or None as :func:`lower_bound`."""
    if not _fits(image, background):
        return None
    lc = float(image.dtype.type(level))
    lb = float(background.dtype.type(level))
    return _clipped(_rows(image), _rows(background), lc, lb).reshape(image.shape[:-1])

"""The plain-backdrop test of an 8-bit view counted on its codes (capture.matting.detect_backdrop;
issue 32, docs/speed.md round 10).

``detect_backdrop`` takes the median of the certain-background pixels' linear colour (a partition
of about a million float32 values a channel on a 1280x960 view) and then each pixel's largest
channel distance from it: 0.066 s of a 1.2 s matte in the pool's workers.  A view read from an
8-bit image has linear colour ``capture.scan._SRGB8_LUT[code]``, a non-decreasing table, so

* the median of a channel is the table at the median code (an odd count), or, for an even count,
  numpy's mean of the two middle values: ``(lut[a] + lut[b]) / 2`` in float32, a and b the two
  middle codes (found from the codes' histogram);
* a pixel is within ``BACKDROP_TOL`` of the median when each channel's code is, by a table of the
  256 codes made with the same float32 ``abs(value - median) <= BACKDROP_TOL`` as the full test.

The same colour (or None) bit for bit (tests/capture/test_matting_backdrop.py).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from capture.scan import _SRGB8_LUT

#: Codes of an 8-bit channel.
CODES = 256


def _median_of_codes(counts: np.ndarray, n: int) -> np.float32:
    """numpy's float32 median of ``_SRGB8_LUT[codes]`` for codes with histogram ``counts`` (n of them)."""
    cum = np.cumsum(counts)
    hi = int(np.searchsorted(cum, n // 2, side="right"))  # the code at sorted position n // 2
    if n % 2:
        return _SRGB8_LUT[hi]
    lo = int(np.searchsorted(cum, n // 2 - 1, side="right"))  # at position n // 2 - 1
    return np.mean(_SRGB8_LUT[[lo, hi]])  # numpy's median: the mean of the two middle values (float32)


@njit(cache=True, nogil=True)
def _histograms(rgb8, background):
    """(3, CODES) int64 counts of each channel's codes over the ``background`` pixels."""
    h, w = background.shape
    counts = np.zeros((3, CODES), np.int64)
    for i in range(h):
        for j in range(w):
            if background[i, j]:
                for k in range(3):
                    counts[k, rgb8[i, j, k]] += 1
    return counts


@njit(cache=True, nogil=True)
def _close_count(rgb8, background, ok):
    """The ``background`` pixels whose three codes are each within the tolerance (``ok`` (3, CODES))."""
    h, w = background.shape
    n = 0
    for i in range(h):
        for j in range(w):
            if background[i, j] and ok[0, rgb8[i, j, 0]] and ok[1, rgb8[i, j, 1]] and ok[2, rgb8[i, j, 2]]:
                n += 1
    return n


def backdrop_from_codes(rgb8: np.ndarray, background: np.ndarray, tol: float, plain: float):
    """``capture.matting.detect_backdrop`` of the linear colour of uint8 sRGB ``rgb8`` (H, W, 3) with
    ``background`` (H, W) its certain-background pixels (``trimap == BG``), ``tol`` and ``plain`` its
    BACKDROP_TOL and BACKDROP_PLAIN: the (3,) float32 median colour or None (module docstring)."""
    rgb8 = np.ascontiguousarray(rgb8, np.uint8)
    background = np.ascontiguousarray(background, bool)
    counts = _histograms(rgb8, background)
    n = int(counts[0].sum())
    if n < 16:
        return None
    med = np.array([_median_of_codes(counts[k], n) for k in range(3)], np.float32)
    ok = np.abs(_SRGB8_LUT[None, :] - med[:, None]) <= tol
    close = np.float64(_close_count(rgb8, background, ok)) / n  # numpy's mean of the bools: count / n
    return med if close >= plain else None

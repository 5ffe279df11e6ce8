"""pymatting's multilevel foreground estimate (Germer et al. 2020, ``estimate_foreground_ml``) compiled
again, the same values bit for bit (issue 32: it was a fifth of a phone view's matte).

pymatting's ``_estimate_fb_ml`` keeps each pixel's two right-hand sides in a small float32 array and
the four neighbour offsets in lists, and resizes every level with two ``parallel=True`` kernels (a
thread pool started inside each matte worker).  :func:`estimate_foreground_ml` does the same sweeps in
the same order with the same float32 / float64 arithmetic (each array store rounded to float32 as
pymatting's is: ``np.float32(...)`` where pymatting stores into its float32 array), the right-hand
sides in scalars and the resizes serial.  ``pymatting.estimate_foreground_ml`` is the reference
(tests/capture/test_foreground_ml.py: equal bit for bit).
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: pymatting's defaults (``estimate_foreground_ml``): regularisation, iterations on the levels of at
#: most SMALL_SIZE pixels a side and on the larger ones, and the weight of alpha's gradient.
REGULARIZATION = 1e-5
SMALL_ITERATIONS = 10
BIG_ITERATIONS = 2
SMALL_SIZE = 32
GRADIENT_WEIGHT = 1.0
#: The matte's foreground colours by :func:`estimate_foreground_ml` (False: pymatting's, the reference;
#: the same values bit for bit).
COMPILED = True


@njit(cache=True, nogil=True)
def _resize_nearest(dst, src):
    """pymatting's nearest-neighbour resize of (h, w, d) ``src`` into ``dst``, serial."""
    h_src, w_src = src.shape[0], src.shape[1]
    h_dst, w_dst = dst.shape[0], dst.shape[1]
    for y_dst in range(h_dst):
        y_src = max(0, min(h_src - 1, y_dst * h_src // h_dst))
        for x_dst in range(w_dst):
            x_src = max(0, min(w_src - 1, x_dst * w_src // w_dst))
            for c in range(dst.shape[2]):
                dst[y_dst, x_dst, c] = src[y_src, x_src, c]


@njit(cache=True, nogil=True, inline="always")
def _weight(alpha, a0, y2, x2, regularization, gradient_weight):
    """pymatting's neighbour weight: regularisation + the weighted |alpha step| (float32)."""
    return regularization + gradient_weight * abs(a0 - alpha[y2, x2, 0])


@njit(cache=True, nogil=True)
def _sweep(image, alpha, F, B, regularization, gradient_weight):
    """One in-place sweep over a level (pymatting's inner loop: the same arithmetic and order; its
    neighbours left, right, up, down, clamped at the border)."""
    h, w, depth = image.shape
    for y in range(h):
        yu, yd = max(0, y - 1), min(h - 1, y + 1)
        for x in range(w):
            xl, xr = max(0, x - 1), min(w - 1, x + 1)
            a0 = alpha[y, x, 0]
            a1 = 1.0 - a0  # float64, as pymatting's
            a01 = a0 * a1
            d0 = _weight(alpha, a0, y, xl, regularization, gradient_weight)
            d1 = _weight(alpha, a0, y, xr, regularization, gradient_weight)
            d2 = _weight(alpha, a0, yu, x, regularization, gradient_weight)
            d3 = _weight(alpha, a0, yd, x, regularization, gradient_weight)
            a00 = a0 * a0
            a00 += d0
            a00 += d1
            a00 += d2
            a00 += d3
            a11 = a1 * a1
            a11 += d0
            a11 += d1
            a11 += d2
            a11 += d3
            determinant = a00 * a11 - a01 * a01
            inv_det = 1.0 / determinant
            b00 = inv_det * a11
            b01 = inv_det * -a01
            b11 = inv_det * a00
            for c in range(depth):
                r0 = np.float32(a0 * image[y, x, c])
                r1 = np.float32(a1 * image[y, x, c])
                r0 = np.float32(r0 + d0 * F[y, xl, c])
                r1 = np.float32(r1 + d0 * B[y, xl, c])
                r0 = np.float32(r0 + d1 * F[y, xr, c])
                r1 = np.float32(r1 + d1 * B[y, xr, c])
                r0 = np.float32(r0 + d2 * F[yu, x, c])
                r1 = np.float32(r1 + d2 * B[yu, x, c])
                r0 = np.float32(r0 + d3 * F[yd, x, c])
                r1 = np.float32(r1 + d3 * B[yd, x, c])
                F[y, x, c] = max(0.0, min(1.0, b00 * r0 + b01 * r1))
                B[y, x, c] = max(0.0, min(1.0, b01 * r0 + b11 * r1))


@njit(cache=True, nogil=True)
def _fb_ml(input_image, input_alpha, regularization, n_small_iterations, n_big_iterations, small_size,
           gradient_weight):
    """(F, B) float32 of pymatting's ``_estimate_fb_ml`` (``input_alpha`` (h, w, 1))."""
    h0, w0, depth = input_image.shape
    F_mean = np.zeros(depth, np.float32)
    B_mean = np.zeros(depth, np.float32)
    F_count = 0
    B_count = 0
    for y in range(h0):
        for x in range(w0):
            if input_alpha[y, x, 0] > 0.9:
                for c in range(depth):
                    F_mean[c] += input_image[y, x, c]
                F_count += 1
            if input_alpha[y, x, 0] < 0.1:
                for c in range(depth):
                    B_mean[c] += input_image[y, x, c]
                B_count += 1
    F_mean /= F_count + 1e-5
    B_mean /= B_count + 1e-5
    F_prev = np.zeros((1, 1, depth), np.float32) + F_mean
    B_prev = np.zeros((1, 1, depth), np.float32) + B_mean
    n_levels = int(np.ceil(np.log2(max(w0, h0))))
    for i_level in range(n_levels + 1):
        w = round(w0 ** (i_level / n_levels))
        h = round(h0 ** (i_level / n_levels))
        image = np.empty((h, w, depth), np.float32)
        alpha = np.empty((h, w, 1), np.float32)
        _resize_nearest(image, input_image)
        _resize_nearest(alpha, input_alpha)
        F = np.empty((h, w, depth), np.float32)
        B = np.empty((h, w, depth), np.float32)
        _resize_nearest(F, F_prev)
        _resize_nearest(B, B_prev)
        n_iter = n_small_iterations if (w <= small_size and h <= small_size) else n_big_iterations
        for _ in range(n_iter):
            _sweep(image, alpha, F, B, regularization, gradient_weight)
        F_prev = F
        B_prev = B
    return F_prev, B_prev


def estimate_foreground_ml(image: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """(h, w, 3) float32 foreground of ``image`` (h, w, 3) under ``alpha`` (h, w): pymatting's
    ``estimate_foreground_ml(image, alpha)`` with its defaults, the same values bit for bit
    (pymatting's own with COMPILED off)."""
    if not COMPILED:
        from pymatting import estimate_foreground_ml as reference

        return reference(image, alpha)
    img = np.ascontiguousarray(image, np.float32)
    a = np.ascontiguousarray(alpha, np.float32)[..., None]
    F, _ = _fb_ml(img, a, np.float32(REGULARIZATION), SMALL_ITERATIONS, BIG_ITERATIONS, SMALL_SIZE,
                  np.float32(GRADIENT_WEIGHT))
    return F


def ml_foreground_in(image: np.ndarray, alpha: np.ndarray, need: np.ndarray | None = None) -> np.ndarray:
    """:func:`estimate_foreground_ml` of ``image`` under ``alpha``, computed on the box around the
    ``need`` (h, w) pixels only (the image elsewhere); None: everywhere (capture.matting_known's colour
    where the background is not known)."""
    from capture.matting import BG, UNKNOWN, _crop

    F = np.asarray(image, np.float64).copy()
    box = _crop(np.where(need, UNKNOWN, BG)) if need is not None else (slice(None), slice(None))
    if box is not None:
        F[box] = estimate_foreground_ml(np.asarray(image, np.float64)[box], np.asarray(alpha, np.float64)[box])
    return F

"""Filling an image's empty pixels from its nearest filled ones: the push-pull pyramid (the known-
background matte's colour fill, capture.matting_known; the working-resolution matte's nearest sure
colour, capture.matting_scale; the panorama plate's room depth, capture.plate_reproject)."""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from capture.matting_fast import zoom2

#: :func:`push_pull` of (h, w, C) values by the compiled levels of capture.fill_kernel (the same values
#: bit for bit, about 3x faster on a matte's crops: docs/speed.md round 10); False: the numpy levels.
COMPILED = True


def push_pull(values: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """(h, w, C) ``values`` filled where ``weights`` (h, w) is 0 by a push-pull pyramid: each empty
    pixel gets the weighted mean of the nearest non-empty ones at the coarsest scale that has any
    (normalised convolution: 2x2 box down, bilinear up).  A map without any weight comes back as zeros.
    The 2 x 2 sums by strided adds in the order numpy's reduction takes (:func:`_down`; 1.5x faster on a
    1920 x 1440 colour image): the same values as :func:`push_pull_reference` bit for bit
    (tests/capture/test_fill.py).  With :data:`COMPILED` each level of (h, w, C) values is
    capture.fill_kernel's two passes, the same operations in the same order (:func:`_push_pull_compiled`)."""
    if COMPILED and np.ndim(values) == 3:
        return _push_pull_compiled(values, weights)
    return _push_pull(values, weights, _down)


def _push_pull_compiled(values: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """:func:`_push_pull` of (h, w, C) ``values`` with each level down and up compiled (capture.fill_kernel):
    the same checks at each level (no weight: zeros; one row or column, or every weight: the mean)."""
    from capture.fill_kernel import down_level, up_select

    v = np.ascontiguousarray(values, np.float64)
    w = np.ascontiguousarray(weights, np.float64)
    has, every = bool(w.any()), bool(w.all())
    levels = []
    while True:
        if not has:
            out = np.zeros_like(v)
            break
        if min(w.shape) <= 1 or every:
            out = np.where(w[..., None] > 0, v, (v * w[..., None]).sum((0, 1)) / w.sum())
            break
        levels.append((v, w))
        v, w, has, every = down_level(v, w)
    for v, w in reversed(levels):
        out = up_select(out, v, w)
    return out


def push_pull_reference(values: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """The reference of :func:`push_pull`, its 2 x 2 sums numpy's reshaped ones (:func:`_down_reshaped`)."""
    return _push_pull(values, weights, _down_reshaped)


def _push_pull(values: np.ndarray, weights: np.ndarray, down) -> np.ndarray:
    """:func:`push_pull` with ``down`` the 2 x 2 box sums of an even-sized (2h, 2w[, C]) array."""
    v = np.asarray(values, np.float64)
    w = np.asarray(weights, np.float64)
    if not w.any():
        return np.zeros_like(v)
    if min(w.shape) <= 1 or w.all():
        return np.where(w[..., None] > 0, v, (v * w[..., None]).sum((0, 1)) / w.sum())
    h, wd = w.shape
    H2, W2 = h + h % 2, wd + wd % 2
    vp = np.zeros((H2, W2) + v.shape[2:])
    wp = np.zeros((H2, W2))
    np.multiply(v, w[..., None], out=vp[:h, :wd])
    wp[:h, :wd] = w
    ws, vs = down(wp), down(vp)
    coarse = _push_pull(np.where(ws[..., None] > 0, vs / np.maximum(ws, 1e-12)[..., None], 0.0),
                        np.minimum(ws, 1.0), down)
    up = zoom2(coarse, h, wd) if coarse.ndim == 3 else \
        ndimage.zoom(coarse, (2, 2) + (1,) * (coarse.ndim - 2), order=1, mode="nearest", grid_mode=True)[:h, :wd]
    return np.where(w[..., None] > 0, v, up)


def _down(x: np.ndarray) -> np.ndarray:
    """2 x 2 box sums of (2h, 2w[, C]) ``x``, added in the order of numpy's
    ``x.reshape(h, 2, w, 2, ...).sum((1, 3))``: pairwise over one channel, in turn over several."""
    a00, a01, a10, a11 = x[0::2, 0::2], x[0::2, 1::2], x[1::2, 0::2], x[1::2, 1::2]
    if x.ndim == 2 or x.shape[2] == 1:
        return (a00 + a01) + (a10 + a11)
    return ((a00 + a01) + a10) + a11


def _down_reshaped(x: np.ndarray) -> np.ndarray:
    """2 x 2 box sums of (2h, 2w[, C]) ``x`` by numpy's reshaped reduction (the reference)."""
    h, w = x.shape[0] // 2, x.shape[1] // 2
    return x.reshape((h, 2, w, 2) + x.shape[2:]).sum((1, 3))

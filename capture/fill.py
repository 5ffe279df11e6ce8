"""Filling an image's empty pixels from its nearest filled ones: the push-pull pyramid (the known-
background matte's colour fill, capture.matting_known; the working-resolution matte's nearest sure
colour, capture.matting_scale; the panorama plate's room depth, capture.plate_reproject)."""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from capture.matting_fast import zoom2


def push_pull(values: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """(h, w, C) ``values`` filled where ``weights`` (h, w) is 0 by a push-pull pyramid: each empty
    pixel gets the weighted mean of the nearest non-empty ones at the coarsest scale that has any
    (normalised convolution: 2x2 box down, bilinear up).  A map without any weight comes back as zeros."""
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
    vp[:h, :wd] = v * w[..., None]
    wp[:h, :wd] = w
    ws = wp.reshape(H2 // 2, 2, W2 // 2, 2).sum((1, 3))
    vs = vp.reshape(H2 // 2, 2, W2 // 2, 2, -1).sum((1, 3))
    coarse = push_pull(np.where(ws[..., None] > 0, vs / np.maximum(ws, 1e-12)[..., None], 0.0), np.minimum(ws, 1.0))
    up = zoom2(coarse, h, wd) if coarse.ndim == 3 else \
        ndimage.zoom(coarse, (2, 2) + (1,) * (coarse.ndim - 2), order=1, mode="nearest", grid_mode=True)[:h, :wd]
    return np.where(w[..., None] > 0, v, up)

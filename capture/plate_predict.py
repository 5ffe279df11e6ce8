"""The fixed camera's ring predictions and drawing by capture.plate_predict_kernel (issue 32, round 11).

``capture.plate_fixed.fixed_predict`` (every view's held-back ring from 32 other frames, three times:
the first gains and the refit's two) and ``fixed_draw``'s robust mode over the union of the need masks
(64 frames) call ``fixed_prediction``: numpy gathers, copies, a power per sample and the compiled
mode.  Their twins here gather each frame's samples in one compiled pass into pixel-major buffers and
do the censored robust mode a pixel at a time (capture/plate_predict_kernel.py); each frame's sRGB
table is made once a call (by numpy's ``linear_to_srgb``, so the same values) instead of a power per
sample.  The same plates bit for bit (tests/capture/test_plate_predict.py); they apply when the
views' colour is float16 (the pipeline's plate views) and the gains float64, the blown-out samples
censored and the mode compiled (else the reference, ``plate_fixed``'s own path).
"""

from __future__ import annotations

import numpy as np

#: capture.plate_fixed's ring predictions and drawing by :func:`fused_prediction` (False: the reference,
#: ``plate_fixed.fixed_prediction``'s numpy gathering and censored mode; the same values).
FUSED_PREDICTION = True
#: Pixels a compiled prediction takes at a time (its buffers: about 33 bytes a pixel and frame).
FUSED_CHUNK = 8000

_CODES = np.arange(1 << 16, dtype=np.uint32).astype(np.uint16)
_DEC16 = _CODES.view(np.float16)
#: Each float16 code's value, exactly (float64).
DECODED = _DEC16.astype(np.float64)


def hot_codes() -> np.ndarray:
    """(65536,) bool: the float16 codes at or above the clip level, compared as plate_fixed compares
    a float16 colour's largest channel (``channel_max(c) >= CLIP_LEVEL``: in float16)."""
    from capture.matting_known import CLIP_LEVEL

    with np.errstate(invalid="ignore"):
        return np.asarray(_DEC16 >= CLIP_LEVEL)


def srgb_table(gain: np.ndarray) -> np.ndarray:
    """(3, TABLE_CODES) float32: per channel, the sRGB value the robust mode takes of each
    non-negative float16 code's sample in the common exposure: ``linear_to_srgb(np.fmax(float32(code x
    gain), 0))`` (numpy's own, so the same values as on the samples)."""
    from capture.plate_predict_kernel import TABLE_CODES
    from capture.scan import linear_to_srgb

    s = (DECODED[:TABLE_CODES, None] * np.asarray(gain, np.float64)[None]).astype(np.float32)
    with np.errstate(invalid="ignore", over="ignore"):
        return np.ascontiguousarray(linear_to_srgb(np.fmax(s, 0.0)).T)


def applies(views, gains, weights) -> bool:
    """Whether the fused path gives plate_fixed's values here: float16 colour, float64 gains, weights
    given as float32 images, the blown-out samples censored and the mode compiled."""
    from capture import plate_fixed as pf

    return (FUSED_PREDICTION and pf.FIXED_CENSOR_CLIPPED and pf.MODE_COMPILED and weights is not None
            and np.asarray(gains).dtype == np.float64
            and all(v.linear.dtype == np.float16 for v in views)
            and all(np.asarray(w).dtype == np.float32 for w in weights))


def fused_prediction(views, pix: np.ndarray, gains: np.ndarray, weights, frames,
                     tables: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``plate_fixed.fixed_prediction(views, pix, None, gains, weights, frames)`` (the same (colour (N, 3)
    float32, bound (N,) bool)) by the compiled passes; ``tables``: frame -> :func:`srgb_table` of its gain
    (made here when missing)."""
    from capture import plate_fixed as pf
    from capture.plate_predict_kernel import censored_pixels, gather_frame

    tables = {} if tables is None else tables
    hot = hot_codes()
    n, K = len(pix), len(frames)
    ys = np.ascontiguousarray(pix[:, 1], np.int64)
    xs = np.ascontiguousarray(pix[:, 0], np.int64)
    col = np.empty((n, 3), np.float32)
    bound = np.zeros(n, bool)
    for lo in range(0, n, FUSED_CHUNK):
        hi = min(n, lo + FUSED_CHUNK)
        S = np.empty((hi - lo, K, 3), np.float32)
        E = np.empty((hi - lo, K, 3), np.float32)
        W = np.empty((hi - lo, K), np.float32)
        F = np.zeros((hi - lo, K), np.uint8)
        for k, j in enumerate(frames):
            if j not in tables:
                tables[j] = srgb_table(gains[j])
            gather_frame(views[j].linear.view(np.uint16), weights[j], ys[lo:hi], xs[lo:hi],
                         np.ascontiguousarray(gains[j], np.float64), DECODED, tables[j], hot, k, S, E, W, F)
        censored_pixels(S, E, W, F, np.float32(pf.MODE_TOL), np.float32(pf.MODE_AMBIGUOUS),
                        pf.FIXED_MIN_FRAMES, col[lo:hi], bound[lo:hi])
    return col, bound


def fused_tables(gains: np.ndarray, frames) -> dict:
    """frame -> :func:`srgb_table` of its gain, for every frame in ``frames``, side by side."""
    from capture.plate_threads import thread_map

    frames = sorted(set(frames))
    return dict(zip(frames, thread_map(lambda j: srgb_table(gains[j]), frames), strict=True))


def fused_ring_predict(ps, gains: np.ndarray) -> list[np.ndarray]:
    """``plate_fixed.fixed_predict(ps, gains)`` (the same rings) by :func:`fused_prediction`, the
    frames' tables made once for every view's ring."""
    from capture.plate_fixed import FIXED_RING_FRAMES, in_view, mode_frames
    from capture.plate_threads import thread_map

    views, weights = [p.view for p in ps.views], [p.weight for p in ps.views]
    tables = fused_tables(gains, range(len(views)))

    def one(i):
        frames = mode_frames(len(views), i, FIXED_RING_FRAMES)
        return in_view(*fused_prediction(views, ps.views[i].ring, gains, weights, frames, tables), gains[i])

    return list(thread_map(one, range(len(views))))


def fused_draw_prediction(views, pix: np.ndarray, gains: np.ndarray, weights, frames) -> tuple[np.ndarray, np.ndarray]:
    """``plate_fixed._draw_prediction`` (the same values) by :func:`fused_prediction`, FUSED_CHUNK pixels
    a task, the tasks side by side (capture.plate_threads)."""
    from capture.plate_threads import chunked_prediction

    tables = fused_tables(gains, frames)
    return chunked_prediction(lambda lo, hi: fused_prediction(views, pix[lo:hi], gains, weights, frames, tables),
                              len(pix), FUSED_CHUNK)

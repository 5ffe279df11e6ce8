"""Whole-array passes of the fixed camera's drawing done without their big temporaries (issue 32, round 14).

The plate stage runs in the main process, and on this machine a fresh large array costs more in page
faults than in arithmetic (a 1280x960 float32 ``np.ones`` about 10 ms).  Two of the drawing's passes
made one they did not need:

* :func:`union`: ``np.logical_or.reduce(masks)`` of the views' need masks stacks the 72 (H, W) masks
  into one (72, H, W) array first (88 MB at 1280x960, 0.38 s); here the masks are or-ed into one
  mask in turn (a set operation: the same mask).
* :func:`scaled_samples`: ``np.stack([(own[k] * gains[frames[k]]).astype(np.float32) ...])`` of the
  frames' lines (capture.plate_fixed.unseen_fill: 32 frames x 322 k pixels x 3, 123 MB) made each
  frame's float32 rows and then copied them all (0.57 s); here each frame's product is written into
  its row of the one result, by the same float64 product and the same float64 -> float32 rounding.

Switch ``DRAW_IN_PLACE`` (False: the numpy expressions, the reference); the same values bit for bit
(tests/capture/test_plate_fast.py).
"""

from __future__ import annotations

import numpy as np

#: capture.plate_fixed's union of the need masks and the lines' samples without the stacked
#: temporaries (module docstring); False: the numpy expressions (the reference, the same values).
DRAW_IN_PLACE = True


def union(masks) -> np.ndarray:
    """``np.logical_or.reduce(masks)`` of a sequence of same-shaped bool masks (the same mask)."""
    if not DRAW_IN_PLACE or len(masks) == 0:
        return np.logical_or.reduce(masks)
    out = np.array(masks[0], bool, copy=True)
    for m in masks[1:]:
        np.logical_or(out, m, out=out)
    return out


def scaled_samples(own: np.ndarray, gains: np.ndarray, frames, thread_map) -> np.ndarray:
    """(K, N, 3) float32 ``own[k] * gains[frames[k]]`` for each of the K frames (``own`` (K, N, 3), the
    frames' colour at the pixels; ``gains`` (V, 3) float64), the frames side by side by ``thread_map``:
    numpy's float64 product rounded to float32 (the same values as the stacked ``astype``)."""
    if not DRAW_IN_PLACE:
        return np.stack(list(thread_map(lambda k: (own[k] * gains[frames[k]]).astype(np.float32),
                                        range(len(frames)))))
    out = np.empty(own.shape, np.float32)

    def one(k):
        out[k] = own[k] * gains[frames[k]]

    for _ in thread_map(one, range(len(frames))):
        pass
    return out

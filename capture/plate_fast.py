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

* :func:`unseen_at`: the lines' chunks take their unknown pixels' columns themselves, instead of one
  copy of every unknown pixel's samples (``samples[:, todo]``: 32 x 238 k x 3 float32, 91 MB) sliced.
* :func:`room_counts`: capture.plate_reproject.room_depth's test (enough of the ring off the plane with
  depth) counted in one compiled pass before any of its whole-frame masks is made; on the phone
  capture every view fails it.

Switch ``DRAW_IN_PLACE`` (False: the numpy expressions, the reference); the same values bit for bit
(tests/capture/test_plate_fast.py).
"""

from __future__ import annotations

import numpy as np
from numba import njit

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


def unseen_at(samples, idx, pal, opaque, covered, hot, bound, sigma, chunk: int) -> np.ndarray:
    """capture.plate_fixed._unseen_chunks of the pixels (columns) ``idx`` of ``samples`` (K, N, 3),
    ``opaque``, ``covered`` and ``hot`` (K, N; ``hot`` may be None): each chunk of ``chunk`` of them takes
    its columns itself (the same values as ``_unseen_chunks(samples[:, idx], ...)``, whose column copy of
    every unknown pixel's samples was 91 MB at 72 views); ``bound``, ``sigma`` (len(idx),) set in place."""
    from capture.plate_lines import unseen_background
    from capture.plate_threads import chunks, thread_map

    out = np.full((len(idx), 3), np.nan)

    def one(span):
        sl = slice(*span)
        cols = idx[sl]
        out[sl] = unseen_background(samples[:, cols], pal, opaque[:, cols], covered[:, cols],
                                    None if hot is None else hot[:, cols], bound[sl], sigma[sl])

    for _ in thread_map(one, chunks(len(idx), chunk)):
        pass
    return out


@njit(cache=True, nogil=True)
def _room_counts(ring, off_plane, depth):
    """(ring pixels, ring pixels off the plane with depth > 0) of (H, W) arrays, without the masks."""
    n_ring = 0
    n_have = 0
    for i in range(ring.shape[0]):
        for j in range(ring.shape[1]):
            if ring[i, j]:
                n_ring += 1
                if off_plane[i, j] and depth[i, j] > 0:
                    n_have += 1
    return n_ring, n_have


def room_counts(ring: np.ndarray, off_plane: np.ndarray, depth: np.ndarray) -> tuple[int, int] | None:
    """(``ring.sum()``, ``(ring & off_plane & (depth > 0)).sum()``) by one compiled pass (capture.plate_reproject
    .room_depth's test before it fills; 2-D bool masks and a float depth), None for other arrays or with
    DRAW_IN_PLACE off (the numpy masks, the reference)."""
    if not DRAW_IN_PLACE or ring.dtype != bool or off_plane.dtype != bool or depth.dtype.kind != "f":
        return None
    if not (ring.ndim == 2 and ring.shape == off_plane.shape == depth.shape):
        return None
    n_ring, n_have = _room_counts(ring, off_plane, depth)
    return int(n_ring), int(n_have)

"""The fixed-camera prediction's gathering of one frame's samples (capture.plate_fixed.fixed_prediction),
compiled: one pass over the pixels without the GIL, so that the views' predictions run side by side
on the threads capture.plate_threads gives them (the numpy gathering holds the GIL between its four
fancy-indexing passes; it was the largest single-core part of the plate stage: docs/speed.md).

:func:`gather_frame` writes, at the pixels ``y``, ``x``, a frame's sample weights, its colours times
its gain where the weight is positive, and where a channel of the colour is at the clip level; the
numpy version (:func:`gather_frame_reference`, GATHER_COMPILED off) is the reference, equal bit for
bit (tests/capture/test_plate_gather.py): the same float32 colour times the same gain rounded to
float32 on the store, and ``channel_max(c) >= clip`` (NaN in any channel: not hot, as
``np.maximum`` carries the NaN).
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: The gathering by :func:`_gather` (False: :func:`gather_frame_reference`, the numpy passes).
GATHER_COMPILED = True


@njit(cache=True, nogil=True)
def _gather(linear, weight, y, x, gain, clip, s, w, hot):
    """Compiled :func:`gather_frame_reference` (the same values)."""
    for n in range(y.shape[0]):
        yy, xx = y[n], x[n]
        wt = weight[yy, xx]
        w[n] = wt
        if wt > 0:
            v0, v1, v2 = linear[yy, xx, 0], linear[yy, xx, 1], linear[yy, xx, 2]
            s[n, 0] = v0 * gain[0]
            s[n, 1] = v1 * gain[1]
            s[n, 2] = v2 * gain[2]
            finite = v0 == v0 and v1 == v1 and v2 == v2
            hot[n] = finite and (v0 >= clip or v1 >= clip or v2 >= clip)


def gather_frame_reference(linear: np.ndarray, weight: np.ndarray, y: np.ndarray, x: np.ndarray,
                           gain: np.ndarray, clip: float, s: np.ndarray, w: np.ndarray, hot: np.ndarray) -> None:
    """Into ``w`` (N,) the frame's ``weight`` (H, W) at the pixels ``y``, ``x``; where it is positive,
    into ``s`` (N, 3) its ``linear`` (H, W, 3) colour times ``gain`` (3,) and into ``hot`` (N,) whether
    a channel reaches ``clip``; elsewhere ``s`` and ``hot`` are left as they are."""
    from capture.matting_fast import channel_max

    w[:] = weight[y, x]
    ok = w > 0
    c = linear[y[ok], x[ok]]
    s[ok] = c * gain
    hot[ok] = channel_max(c) >= clip  # c.max(axis=-1)


def gather_frame(linear: np.ndarray, weight: np.ndarray, y: np.ndarray, x: np.ndarray, gain: np.ndarray,
                 clip: float, s: np.ndarray, w: np.ndarray, hot: np.ndarray) -> None:
    """:func:`gather_frame_reference`, compiled with GATHER_COMPILED (the same values bit for bit) for
    float32 colours and C-ordered outputs; the reference otherwise."""
    ok = (GATHER_COMPILED and linear.dtype == np.float32 and linear.ndim == 3 and linear.shape[2] == 3
          and s.dtype == np.float32 and s.flags.c_contiguous and w.flags.c_contiguous and hot.flags.c_contiguous)
    if not ok:
        return gather_frame_reference(linear, weight, y, x, gain, clip, s, w, hot)
    _gather(linear, weight, np.ascontiguousarray(y), np.ascontiguousarray(x), np.asarray(gain), float(clip), s, w, hot)

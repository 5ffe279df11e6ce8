"""The fixed camera's plate of one view put into its frame with fewer whole-array passes (issue 32, round 9).

``capture.plate_fixed._fixed_view`` scatters the drawn pixels' plate (N, 3), known, estimated and
uncertainty into four (H, W) arrays by four 2-D fancy indexings, after ``in_view`` and
``np.nan_to_num`` have each copied the (N, 3) plate once more.  :func:`fixed_view_flat` does the same
with one flat index computed once, ``nan_to_num`` in place on ``in_view``'s own fresh array (after
reading where it is finite), and :func:`in_view_bound` tests the clip level at the lower bounds'
pixels only.  The values are the same bit for bit (tests/capture/test_plate_draw.py); the reference
(``_fixed_view``, ``in_view``) stays in capture/plate_fixed.py.
"""

from __future__ import annotations

import numpy as np

#: capture.plate_fixed.fixed_draw puts each view's plate in its frame by :func:`fixed_view_flat`
#: (False: ``plate_fixed._fixed_view``, the reference, the same values).
DRAW_FLAT = True


def in_view_bound(col: np.ndarray, bound: np.ndarray, gain: np.ndarray) -> np.ndarray:
    """``capture.plate_fixed.in_view(col, bound, gain)`` (the same values): ``col`` / ``gain``, NaN
    where it is only a lower ``bound`` below the clip level; the test read at the bound's pixels only."""
    from capture.matting_known import CLIP_LEVEL

    out = col / gain
    b = np.flatnonzero(bound)
    if len(b):
        out[b[np.nan_to_num(out[b]).max(axis=-1) < CLIP_LEVEL]] = np.nan
    return out


def fixed_view_flat(p, gain, need, shape, y, x, med, est, bound, sigma):
    """``capture.plate_fixed._fixed_view``'s (colour (H, W, 3) float32, known, estimated, uncertainty
    (H, W) float32), the same values: one flat index for the four scatters (module docstring)."""
    here = in_view_bound(med, bound, gain)
    H, W = shape
    idx = np.asarray(y, np.intp) * W + np.asarray(x, np.intp)
    finite = np.isfinite(here[:, 0])
    col = np.zeros(p.view.linear.shape, np.float32)
    col.reshape(-1, 3)[idx] = np.nan_to_num(here, copy=False)
    known = np.zeros(H * W, bool)
    known[idx] = finite
    known = known.reshape(shape) & need
    estimated = np.zeros(H * W, bool)
    estimated[idx] = est
    unc = np.zeros(H * W, np.float32)
    unc[idx] = np.where(est, sigma / float(np.mean(gain)), 0.0)
    return col, known, estimated.reshape(shape) & need, np.where(known, unc.reshape(shape), 0.0)

"""The 8-bit picture a viewer client is sent, made fast: linear float colour -> 8-bit sRGB through a
lookup table.

The reference is ``capture.scan.to_uint8_srgb`` (clip to [0, 1], the IEC 61966-2-1 curve, round):
a power and a select on every float of the frame, 15-45 ms of CPU for a 960x720 frame on this
machine's llvmpipe-loaded cores (docs/viewer.md).  :func:`srgb8` quantises the linear value to
LUT_SIZE steps instead and reads the 8-bit code from a table of the reference's own output at
those steps: four cheap passes over the floats and one gather, about 4x less CPU.  The table
holds ``to_uint8_srgb(i / (LUT_SIZE - 1))``, so a linear value on a step gives exactly the
reference's code and one between two steps the code of the nearer one: at most
SRGB8_TOLERANCE code off, and only where the reference's rounding threshold falls between the two
steps (0.2 % of uniformly spread values; tests/render/viewer/test_viewer_present.py).  NaN reads
as 0 (black), like the reference's cast.
"""

from __future__ import annotations

import numpy as np

#: Steps of the linear value in the table: 2^16, so that one step near black (1.5e-5 linear, 0.05
#: of an 8-bit sRGB code where the curve is steepest) never moves a value by more than one code.
LUT_SIZE = 1 << 16
#: Largest difference (8-bit codes) from capture.scan.to_uint8_srgb.
SRGB8_TOLERANCE = 1

_LUT: np.ndarray | None = None


def srgb8_table() -> np.ndarray:
    """(LUT_SIZE,) uint8: the reference's 8-bit sRGB code of each step ``i / (LUT_SIZE - 1)``
    (computed once)."""
    global _LUT
    if _LUT is None:
        from capture.scan import to_uint8_srgb

        steps = (np.arange(LUT_SIZE, dtype=np.float64) / (LUT_SIZE - 1)).astype(np.float32)
        _LUT = to_uint8_srgb(steps)
    return _LUT


def srgb8(linear: np.ndarray) -> np.ndarray:
    """Linear float colour (any shape; values clipped to [0, 1], NaN as 0) -> uint8 sRGB of the
    same shape: capture.scan.to_uint8_srgb within SRGB8_TOLERANCE."""
    t = np.multiply(np.asarray(linear, np.float32), np.float32(LUT_SIZE - 1))
    np.fmax(t, np.float32(0.0), out=t)  # also NaN -> 0
    np.fmin(t, np.float32(LUT_SIZE - 1), out=t)
    t += np.float32(0.5)
    return srgb8_table()[t.astype(np.uint16)]

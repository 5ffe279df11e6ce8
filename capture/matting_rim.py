"""The depth's opaque pixels of thin branches, opened where the other views saw behind them (issue 30).

The depth trimap (capture.matting.depth_trimap) calls the object's depth mask, eroded by two pixels at 640,
opaque, and the matte keeps alpha 1 there.  On a conifer those pixels are no core: the depth sees the trunk
and dense bunches of needles at every pixel centre, yet the room shows through them (true alpha 0.6-0.95).
Where the moving camera's plate (capture.plate's panorama) knows the background behind such a pixel from
the other views, the compositing equation can say how opaque it is: :func:`open_rim` hands those pixels to
the known-background matte (capture.matting_known) as unknown, which reads alpha off C - B against the
object's colours.  Only

* in a view whose opaque pixels are mostly thin (less than ``THICK_SHARE`` of them survive an opening by
  ``RIM_FRACTION`` of the width): branches, not a body (a fur ball's opaque disc keeps the depth's word);
* where the background was seen (not the frames' lines' estimate), not blown out
  (capture.matting_known.clipped), and the photo differs from it by ``RIM_SEPARATION``;
* before a moving camera's plate (``RIM_METHODS``).

Measured held out (docs/matting.md "The depth's opaque rim"): every conifer orbit +0.06 to +0.24 dB.
"""

from __future__ import annotations

import numpy as np

from capture.matting_fast import dilate, erode
from capture.matting_known import FG, UNKNOWN, clipped
from capture.sampling import mask_box

#: Open the rim (False: the trimap's opaque pixels as the depth gives them).
OPEN_RIM = True
#: The plates whose seen background opens the rim: the moving camera's (capture.plate's panorama).  On the fixed
#: camera's (turntables) its rows moved by -0.63 to +0.18 dB: the colour across the views' brightness fit
#: (capture.matting_global.view_brightness) moved its level 1.02 -> 1.21 when 975 of a capture's 790,000 partial
#: pixels changed (docs/matting.md "The depth's opaque rim").
RIM_METHODS = ("panorama",)
#: Width of the opening that tells a view's thin opaque pixels from a body, a fraction of the image width (8 px at 640).
RIM_FRACTION = 8 / 640
#: Only in a view whose opaque pixels are mostly thin (less than this share of them in their opening by the
#: rim's width: branches and needles; path-traced conifers 0.0, fur balls 0.85-0.89).
THICK_SHARE = 0.5
#: ... and whose photo differs from the plate by at least this (linear, Euclidean): where C is near B the
#: compositing equation cannot tell an opaque pixel of the background's colour from a faint one.
RIM_SEPARATION = 0.1


def _opening(fg: np.ndarray, r: int, box: bool = True) -> np.ndarray:
    """The opening of ``fg`` (H, W) bool by ``r`` pixels within ``fg``: dilate(erode(fg, r), r) & fg, on the box
    around ``fg`` widened by one pixel (``box``; the same mask: outside the box both are empty)."""
    b = mask_box(fg) if box else None
    if b is None:
        return dilate(erode(fg, r), r) & fg
    H, W = fg.shape
    sl = (slice(max(b[0] - 1, 0), min(b[1] + 1, H)), slice(max(b[2] - 1, 0), min(b[3] + 1, W)))
    out = np.zeros_like(fg)
    out[sl] = dilate(erode(fg[sl], r), r) & fg[sl]
    return out


def rim_mask(trimap: np.ndarray, image: np.ndarray, plate) -> np.ndarray | None:
    """(H, W) bool: the opaque pixels of ``trimap`` that :func:`open_rim` opens (module docstring); None when none."""
    if not OPEN_RIM or plate is None or plate.method not in RIM_METHODS:
        return None
    fg = trimap >= FG
    if not fg.any():
        return None
    if plate.frame is not None:
        plate = plate.full()
    r = max(1, int(round(RIM_FRACTION * trimap.shape[1])))
    thick = _opening(fg, r)
    if np.count_nonzero(thick) >= THICK_SHARE * np.count_nonzero(fg):  # a solid body (fur): as the depth says
        return None
    seen = plate.known if plate.estimated is None else plate.known & ~plate.estimated
    rim = fg & ~thick & seen
    if not rim.any():
        return None
    rim &= ~clipped(image, plate.background)
    d = np.asarray(image, np.float32) - np.asarray(plate.background, np.float32)
    rim &= np.einsum("...c,...c->...", d, d) >= RIM_SEPARATION ** 2
    return rim if rim.any() else None


def open_rim(trimap: np.ndarray, image: np.ndarray, plate) -> tuple[np.ndarray, int]:
    """(``trimap`` (H, W) with the pixels of :func:`rim_mask` set to unknown, how many); the same array and 0
    when none."""
    rim = rim_mask(trimap, image, plate)
    if rim is None:
        return trimap, 0
    out = np.array(trimap, copy=True)
    out[rim] = UNKNOWN
    return out, int(np.count_nonzero(rim))

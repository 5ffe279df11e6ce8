"""A detected plain backdrop against the view's background plate (issue 30, stop 76; docs/matting.md "A dark room
is not a backdrop").

capture.matting.detect_backdrop calls a background plain when 98 % of the certain-background pixels lie within
BACKDROP_TOL (0.02, linear) of their median.  That tolerance is absolute: a dark, textured room passes it.  A conifer
turning before a night park (grass at a linear 0.03) took the backdrop path in all 18 kept views: one colour for a
background whose pixels differ from it by 23 % RMS.  Behind the crown that colour was 12 % darker than the grass, and
the needles' premultiplied colour came out 17 % too bright (the room's light left in it).  The background plate
(capture.plate), which the backdrop path had skipped, knew the grass pixel by pixel.

So where the auto matte detects a backdrop, the backdrop must predict the view's held-back background ring
(capture.plate.ring_pixels) no worse than the plate predicts it (Plate.error_rmse, the plate's own held-back RMS):
where the plate is better, the view is matted against the plate and the record says so.  The plate stage is skipped
for a capture of backdrops only where every view's backdrop is exact (:func:`exact_backdrop`): its ring's median error
at most EXACT_ERROR, which no plate can beat (a path-traced black backdrop: 0).
"""

from __future__ import annotations

import numpy as np

#: Switch: a detected backdrop must predict the view's background ring no worse than its plate (False: the backdrop
#: wherever it is detected, the rule before stop 76).
AGAINST_PLATE = True
#: A backdrop whose ring median error (linear, the largest channel's) is at most this needs no plate to be compared
#: with: one 8-bit sRGB step at black (capture.matting.NOISE_FLOOR).
EXACT_ERROR = 1.0 / 255 / 12.92


def backdrop_error(image: np.ndarray, object_depth: np.ndarray, backdrop: np.ndarray,
                   median: bool = False) -> float:
    """RMS over channels (linear) of ``image`` (H, W, 3) less the ``backdrop`` colour (3,) on the view's held-back
    ring (capture.plate.ring_pixels of ``object_depth`` (H, W)); ``median``: the median of the largest channel's
    |difference| instead (Plate.error's measure); NaN where the ring is empty."""
    from capture.plate import ring_pixels

    xy = ring_pixels(object_depth)
    if not len(xy):
        return float("nan")
    d = np.asarray(image, np.float64)[xy[:, 1], xy[:, 0]] - np.asarray(backdrop, np.float64)
    return float(np.median(np.abs(d).max(axis=1))) if median else float(np.sqrt(np.mean(d * d)))


def exact_backdrop(image: np.ndarray, object_depth: np.ndarray, backdrop: np.ndarray | None) -> bool:
    """Whether ``backdrop`` (None: none detected) predicts the view's ring to within EXACT_ERROR, by the median
    (the ring's partial needles beyond the depth, which no plate predicts either, do not count)."""
    if backdrop is None:
        return False
    if not AGAINST_PLATE:
        return True
    e = backdrop_error(image, object_depth, backdrop, median=True)
    return not np.isfinite(e) or e <= EXACT_ERROR


def plate_beats_backdrop(image: np.ndarray, object_depth: np.ndarray, backdrop: np.ndarray, plate) -> dict | None:
    """The record ({'backdrop_rmse', 'plate_rmse'}) when the view's ``plate`` (capture.plate.Plate or None) predicts
    its held-back ring better than the ``backdrop`` colour does (AGAINST_PLATE); None when the backdrop stands."""
    if not AGAINST_PLATE or plate is None or not plate.known.any() or not np.isfinite(plate.error_rmse):
        return None
    e = backdrop_error(image, object_depth, backdrop)
    if not np.isfinite(e) or e <= plate.error_rmse:
        return None
    return {"backdrop_rmse": round(e, 6), "plate_rmse": round(float(plate.error_rmse), 6)}

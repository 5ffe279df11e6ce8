"""The matte stage's measure of the depth-opaque colour sources' coverage over the capture's views
(capture.matting_sources; off by default: ``ESTIMATE_COVERAGE``, docs/matting.md "A conifer at 320 x 240 in a room"):
each view's slope of its photo on its plate, in the per-view map, before the views are matted."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from capture.plate_scale import grow_plate
from capture.view_map import PerView


def sources_coverage(cfg, work, plates: dict, ctx):
    """(``cfg`` with the capture's measured ``source_coverage``, its record or None): each view's slope of its photo
    on its plate over its depth-opaque pixels (:func:`slope_one`), their median (capture.matting_sources); ``cfg``
    as it is, None, without plates or with the measure off."""
    from capture.matting_sources import ESTIMATE_COVERAGE, capture_coverage

    if not plates or not ESTIMATE_COVERAGE or cfg.mode not in ("auto", "plate"):
        return cfg, None
    with ctx.row("matte sources' coverage"):
        _, slopes = ctx.map_views(slope_one, work, PerView([plates.get(ref.index) for ref in work.refs]),
                                  "sources' coverage")
    cov, med = capture_coverage(slopes)
    rec = {"coverage": cov, "median_slope": None if med is None else round(med, 4),
           "slopes": [None if k is None else round(k, 4) for k in slopes]}
    return replace(cfg, source_coverage=cov), rec


def slope_one(view, ref, plate):
    """(None, the view's slope of its photo on its ``plate`` over its depth-opaque pixels before the seen background:
    capture.matting_sources.view_slope; None without a plate or depth)."""
    if plate is None or view.depth is None:
        return None, None
    from capture.matting import FG, depth_trimap
    from capture.matting_known import CLIP_LEVEL
    from capture.matting_sources import view_slope

    plate = grow_plate(plate, *view.depth.shape[:2])
    seen = np.asarray(plate.seen(), bool)
    return None, view_slope(view.linear_rgb, plate.background, (depth_trimap(view.depth) >= FG) & seen, CLIP_LEVEL)

"""The object apart from its surroundings, before fusion: the extent and matte stages of the
pipeline (volume/pipeline/stages.py; issue 20).

* **extent** (``capture.extent.remove_surroundings``): depth of the support plane, far depth and
  clutter set to 0, so that fusion, RGBz and every method see the object alone; the bounds shrink
  to what is left.  A whole-set stage: the plane and the floater grid need every view.
* **matte** (``capture.matting.matte_scan``): each view gets a soft straight alpha matte and the
  object's straight colour under it; the scan's colour becomes that foreground colour (float32
  linear) and its ``alpha`` the matte, which ``volume.rgbz.build_rgbz`` stores in the model
  (``RgbzImages.rgb`` / ``RgbzImages.alpha``).  A per-view stage (:func:`matte_view`, picklable);
  pymatting's numba kernels are compiled once before the views (:func:`matte_warm_up`, the
  "matte warm-up" row) so that the matte row's time is the matting's.  Mode 'off' keeps the
  binary depth mask as the only one: a capture's own matte is dropped.

Each reports its own numbers (the model report's ``surroundings``).
"""

from __future__ import annotations

import time

import numpy as np

from capture.extent import remove_surroundings
from capture.matting import matte_scan, warm_up
from capture.scan import Scan
from capture.scan_store import scan_has_alpha


def extent_stage(work, cfg, ctx):
    """The extent stage (cfg: capture.extent.ExtentConfig): the surroundings out of the depth (module docstring)."""
    ss, rep = remove_surroundings(work.scanset, cfg, ctx.keep)
    return work.with_scanset(ss).record("extent", rep.record())


def matte_warm_up(cfg) -> None:
    """Before the matte stage's views: pymatting's kernels compiled (nothing for mode 'off')."""
    if cfg.mode != "off":
        warm_up()


def matte_view(view, ref, cfg):
    """The matte stage for one view (cfg: capture.matting.MatteConfig): (the scan with its
    foreground colour and matte, note: method, seconds, unknown and partial fractions); mode 'off':
    the scan without a matte, no note."""
    if cfg.mode == "off":
        return (Scan(view.rgb, view.depth, view.camera, view.name) if scan_has_alpha(view) else view), None
    t0 = time.perf_counter()
    m = matte_scan(view, view.depth, cfg)
    note = {"method": m.method, "seconds": time.perf_counter() - t0, "unknown": m.unknown_fraction,
            "partial": float(np.mean((m.alpha > 0) & (m.alpha < 1)))}
    return Scan(m.foreground, view.depth, view.camera, view.name, m.alpha), note


def matte_record(work, notes: dict, cfg):
    """The matte stage's record from its views' notes (``notes["matte"]``)."""
    if cfg.mode == "off":
        return work.record("matte", {"mode": "off"})
    n = [x for x in notes["matte"] if x is not None]
    methods = [x["method"] for x in n]
    sec = [x["seconds"] for x in n]
    return work.record("matte", {
        "mode": cfg.mode, "backdrop": cfg.backdrop, "methods": {k: methods.count(k) for k in sorted(set(methods))},
        "seconds_per_view": round(float(np.mean(sec)), 4), "seconds_per_view_max": round(float(np.max(sec)), 4),
        "unknown_fraction_mean": round(float(np.mean([x["unknown"] for x in n])), 5),
        "partial_fraction_mean": round(float(np.mean([x["partial"] for x in n])), 5)})

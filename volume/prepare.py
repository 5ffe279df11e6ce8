"""The object apart from its surroundings, before fusion: the extent stage, then the matte stage (issue 20).

* **extent** (``capture.extent.remove_surroundings``): depth of the support plane, far depth and
  clutter set to 0, so that fusion, RGBz and every method see the object alone; the bounds shrink
  to what is left.
* **matte** (``capture.matting.matte_scan``): each kept view gets a soft straight alpha matte and
  the object's straight colour under it; the scan's colour becomes that foreground colour (float32
  linear) and its ``alpha`` the matte, which ``volume.rgbz.build_rgbz`` stores in the model
  (``RgbzImages.rgb`` / ``RgbzImages.alpha``).  pymatting's numba kernels are compiled in a stage
  of their own ("matte warm-up") so that the matte stage's time is the matting's.

Each stage can be switched off (``PrepareConfig``) and reports its own numbers (``record``).
"""

from __future__ import annotations

import contextlib
import time
from dataclasses import dataclass, field

import numpy as np

from capture.extent import ExtentConfig, remove_surroundings
from capture.matting import MatteConfig, matte_scan, warm_up
from capture.scan import Scan, ScanSet
from capture.scan_store import keep_in_memory


@dataclass(frozen=True)
class PrepareConfig:
    """Settings of :func:`prepare_scans`."""

    #: Remove the support, far depth and clutter from the depth (False: the depth as captured).
    extent: bool = True
    #: Extent settings (``keep_support``).
    extent_cfg: ExtentConfig = field(default_factory=ExtentConfig)
    #: Matting settings (``mode`` 'off' = no matte: the binary depth mask stays the only one).
    matte: MatteConfig = field(default_factory=MatteConfig)


def prepare_scans(scanset: ScanSet, cfg: PrepareConfig | None = None, stage=None,
                  progress=None, keep=None) -> tuple[ScanSet, dict]:
    """(scan set ready for fusion, record for model.json / the console) (module docstring).
    Views are worked on one at a time; ``keep`` takes each new scan (capture.scan_store)."""
    cfg = cfg or PrepareConfig()
    keep = keep or keep_in_memory
    stage = stage or (lambda name: contextlib.nullcontext())
    record: dict = {}
    if cfg.extent:
        with stage("extent"):
            scanset, rep = remove_surroundings(scanset, cfg.extent_cfg, keep)
        record["extent"] = rep.record()
    if cfg.matte.mode == "off":
        if any(s.alpha is not None for s in scanset.scans):
            scanset = ScanSet(tuple(keep(Scan(s.rgb, s.depth, s.camera, s.name)) for s in scanset.scans),
                              scanset.bounds, scanset.metadata)
        record["matte"] = {"mode": "off"}
        return scanset, record
    with stage("matte warm-up"):
        warm_up()
    scans, methods, seconds, unknown, partial = [], [], [], [], []
    with stage(f"matte ({len(scanset)} views)"):
        items = list(scanset.scans)
        for s in (progress(items, "matting") if progress else items):
            t0 = time.perf_counter()
            m = matte_scan(s, s.depth, cfg.matte)
            seconds.append(time.perf_counter() - t0)
            methods.append(m.method)
            unknown.append(m.unknown_fraction)
            partial.append(float(np.mean((m.alpha > 0) & (m.alpha < 1))))
            scans.append(keep(Scan(m.foreground, s.depth, s.camera, s.name, m.alpha)))
    scanset = ScanSet(tuple(scans), scanset.bounds, scanset.metadata)
    record["matte"] = {"mode": cfg.matte.mode, "backdrop": cfg.matte.backdrop,
                       "methods": {k: methods.count(k) for k in sorted(set(methods))},
                       "seconds_per_view": round(float(np.mean(seconds)), 4),
                       "seconds_per_view_max": round(float(np.max(seconds)), 4),
                       "unknown_fraction_mean": round(float(np.mean(unknown)), 5),
                       "partial_fraction_mean": round(float(np.mean(partial)), 5)}
    return scanset, record

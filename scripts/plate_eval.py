"""Held-out scores of gather and points with a chosen matte / plate setting, as ``furrow eval SCANS
--holdout 2`` scores them (issue 30 measurements; ``furrow eval`` takes --matte / --plate too but
uses a given matte: for the default command line on a capture without mattes run it on the copy
scripts/hide_mattes.py makes).

    PYTHONPATH=. .venv/bin/python scripts/plate_eval.py CAPTURE [MATTE [PLATE [EXTENT]]] [--plates DIR] [--out DIR]

MATTE: auto (default) | given | backdrop | plate | estimate | off; PLATE: auto (default) | fixed |
panorama | user | off; EXTENT: 1 (default) | 0.  The kept views' given matte is hidden unless MATTE
is 'given' (the evaluation captures supply none).  Prints one JSON line: per renderer the masked
PSNR / SSIM / sharpness, holes, composite over white and alpha MSE (against the held-out views'
true mattes), the plate's record and the CPU and wall seconds of the plate and matte stages.
``--out DIR`` also writes the side-by-side sheets of the held-out views.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import time
from pathlib import Path

from capture.extent import ExtentConfig
from capture.io import read_scanset
from capture.matting import MatteConfig
from capture.plate import PlateConfig
from capture.scan import Scan, ScanSet
from render import evaluate as ev
from render.gl import gl_context
from render.methods import RenderOptions
from volume.pipeline import build_model
from volume.pipeline.config import PipelineConfig
from volume.pipeline.work import Hooks

KEYS = ("psnr_masked", "ssim_masked", "sharpness", "hole_fraction", "psnr_white", "alpha_mse", "psnr")


def timed():
    """(stage context manager, {name: (wall, cpu)})."""
    out = {}

    @contextlib.contextmanager
    def stage(name):
        t0, c0 = time.perf_counter(), time.process_time()
        try:
            yield
        finally:
            out[name] = (round(time.perf_counter() - t0, 3), round(time.process_time() - c0, 3))
    return stage, out


def main(argv=None) -> dict:
    p = argparse.ArgumentParser()
    p.add_argument("capture")
    p.add_argument("matte", nargs="?", default="auto")
    p.add_argument("plate", nargs="?", default="auto")
    p.add_argument("extent", nargs="?", default="1")
    p.add_argument("--plates", default=None, help="user plates folder (capture.plate_io)")
    p.add_argument("--out", default=None)
    a = p.parse_args(argv)
    split = ev.holdout_split(read_scanset(a.capture), 2, None)
    kept = split.kept
    if a.matte != "given":
        kept = ScanSet(tuple(Scan(s.rgb, s.depth, s.camera, s.name) for s in kept.scans), kept.bounds, kept.metadata)
    cfg = PipelineConfig(extent=ExtentConfig() if a.extent == "1" else None, matte=MatteConfig(mode=a.matte),
                         plate=PlateConfig(mode=a.plate, plates_dir=a.plates))
    stage, times = timed()
    t = time.perf_counter()
    model, summ = build_model(kept, cfg, Hooks(row=stage))
    build_s = time.perf_counter() - t
    with gl_context() as ctx:
        res = ev.evaluate(ctx, model, split.held, RenderOptions(), ("gather", "points"),
                          Path(a.out) if a.out else None, None)
    sur = summ["surroundings"]
    plate = sur.get("plate", {})
    out = {"scans": a.capture, "matte": a.matte, "plate": a.plate, "extent": a.extent == "1",
           "methods": sur.get("matte", {}).get("methods"), "l_opt": summ["l_opt"],
           "plate_mode": plate.get("mode"), "plate_tried": plate.get("tried_error"),
           "band_known": plate.get("band_known_mean"), "plate_error": plate.get("error_median"),
           "stages": {k: v for k, v in times.items() if "plate" in k or "matte" in k or k == "extent"},
           "views": len(kept), "build_s": round(build_s, 1)}
    for k in ("gather", "points"):
        out[k] = {m: round(res[k][m], 4) for m in KEYS}
    print(json.dumps(out))
    return out


if __name__ == "__main__":
    main()

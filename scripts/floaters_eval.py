"""Held-out scores of gather (as ``furrow eval SCANS --holdout 2``) with the extent stage's floater
filter on or off (issue 20, floaters).

    PYTHONPATH=. .venv/bin/python scripts/floaters_eval.py CAPTURE [FLOATERS 0|1]

The kept views' given matte is hidden (the evaluation captures supply none), so the matte is estimated.
"""

from __future__ import annotations

import json
import sys
import time

from capture.extent import ExtentConfig
from capture.io import read_scanset
from capture.scan import Scan, ScanSet
from render import evaluate as ev
from render.gl import gl_context
from render.methods import RenderOptions
from volume.pipeline import build_model
from volume.pipeline.config import PipelineConfig


def main(path: str, floaters: str = "1") -> dict:
    split = ev.holdout_split(read_scanset(path), 2, None)
    kept = ScanSet(tuple(Scan(s.rgb, s.depth, s.camera, s.name) for s in split.kept.scans), split.kept.bounds,
                   split.kept.metadata)
    t = time.perf_counter()
    cfg = PipelineConfig(extent=ExtentConfig(floaters=floaters == "1"))
    model, summ = build_model(kept, cfg)
    build_s = time.perf_counter() - t
    with gl_context() as ctx:
        res = ev.evaluate(ctx, model, split.held, RenderOptions(), ("gather",), None, None)
    out = {"scans": path, "floaters": floaters == "1", "l_opt": summ["l_opt"],
           "surface_voxels": summ["surface_voxels"], "surroundings": summ["surroundings"], "build_s": round(build_s, 1),
           "gather": {m: round(res["gather"][m], 3) for m in ("psnr_masked", "ssim_masked", "sharpness", "psnr")}}
    print(json.dumps(out))
    return out


if __name__ == "__main__":
    main(*sys.argv[1:])

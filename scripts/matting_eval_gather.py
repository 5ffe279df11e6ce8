"""Held-out masked PSNR (over black) of gather and points with a chosen matte mode, as
``furrow eval SCANS --holdout 2`` scores them (issue 20 measurements).

    PYTHONPATH=. .venv/bin/python scripts/matting_eval_gather.py CAPTURE MODE [EXTENT 0|1] [premul]

The kept views' given matte is hidden unless MODE is 'given' (the evaluation captures supply none).
``premul`` replaces the model's RGBz colour by alpha x colour before rendering: a proxy for a
renderer that blends premultiplied colour, while the renderers ignore alpha.
"""

from __future__ import annotations

import dataclasses
import json
import sys
import time

import numpy as np

from capture.extent import ExtentConfig
from capture.io import read_scanset
from capture.matting import MatteConfig
from capture.scan import Scan, ScanSet
from render import evaluate as ev
from render.gl import gl_context
from render.methods import RenderOptions
from volume.model import RgbzImages
from volume.pipeline import build_model
from volume.pipeline.config import PipelineConfig


def main(path: str, mode: str, extent: str = "1", premul: str = "") -> dict:
    split = ev.holdout_split(read_scanset(path), 2, None)
    kept = split.kept
    if mode != "given":
        kept = ScanSet(tuple(Scan(s.rgb, s.depth, s.camera, s.name) for s in kept.scans), kept.bounds, kept.metadata)
    t = time.perf_counter()
    cfg = PipelineConfig(extent=ExtentConfig() if extent == "1" else None, matte=MatteConfig(mode=mode))
    model, summ = build_model(kept, cfg)
    build_s = time.perf_counter() - t
    if premul == "premul":
        r = model.rgbz
        a = np.asarray(r.alpha, np.float32)
        rgb = np.asarray(r.rgb, np.float32) * a[..., None]
        model = dataclasses.replace(model, rgbz=RgbzImages(rgb, np.asarray(r.depth, np.float32), r.cameras, a))
    with gl_context() as ctx:
        res = ev.evaluate(ctx, model, split.held, RenderOptions(), ("gather", "points"), None, None)
    out = {"scans": path, "mode": mode, "extent": extent == "1", "premul": premul == "premul",
           "l_opt": summ["l_opt"], "surface_voxels": summ["surface_voxels"],
           "surroundings": summ["surroundings"], "build_s": round(build_s, 1)}
    for k in ("gather", "points"):
        out[k] = {m: round(res[k][m], 3) for m in ("psnr_masked", "ssim_masked", "sharpness", "psnr")}
    print(json.dumps(out))
    return out


if __name__ == "__main__":
    main(*sys.argv[1:])

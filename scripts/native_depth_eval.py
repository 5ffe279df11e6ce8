"""Held-out quality of fusion maps at the depth's measured size against the colour's (issue 24).

A phone's 256x192 depth is resampled up to its 1920x1440 colour when read (capture.resample); the
fusion's per-view maps can be computed at either size, or between (FusionConfig.map_oversample,
volume.stream.native_scale).  This builds the model of the kept views (i % 2 == 0) at the colour's
size, at 2x and at 1x the measured size, and
scores every method on the held-out views, as ``furrow eval SCANS --holdout 2`` does.

    furrow synth plant --views 24 --size 640x480 --depth-size 160x120 -o out/plant_phone24
    PYTHONPATH=. .venv/bin/python scripts/native_depth_eval.py out/plant_phone24
"""

from __future__ import annotations

import json
import sys
import time
from dataclasses import replace

from capture.io import read_scanset
from render import evaluate as ev
from render.gl import gl_context
from render.methods import RenderOptions
from volume.fusion import FusionConfig
from volume.pipeline import build_model
from volume.pipeline.config import FuseConfig, PipelineConfig

METHODS = ("gather", "microfacet", "points")
KEYS = ("psnr_masked", "ssim_masked", "sharpness", "psnr")


def main(path: str) -> dict:
    split = ev.holdout_split(read_scanset(path), 2, None)
    out = {"scans": path, "depth_size": split.kept.metadata.get("depth_size")}
    for over in (0.0, 2.0, 1.0):
        name = "colour_size" if over == 0 else f"measured_x{over:g}"
        cfg = PipelineConfig(fuse=FuseConfig(fusion=replace(FusionConfig(), map_oversample=over)))
        t = time.perf_counter()
        model, summ = build_model(split.kept, cfg)
        rec = {"build_s": round(time.perf_counter() - t, 1), "l_opt": summ["l_opt"],
               "surface_voxels": summ["surface_voxels"]}
        with gl_context() as ctx:
            res = ev.evaluate(ctx, model, split.held, RenderOptions(), METHODS, None, None)
        for k in METHODS:
            rec[k] = {m: round(res[k][m], 3) for m in KEYS}
        out[name] = rec
        print(json.dumps({name: rec}), flush=True)
    print(json.dumps(out))
    return out


if __name__ == "__main__":
    main(*sys.argv[1:])

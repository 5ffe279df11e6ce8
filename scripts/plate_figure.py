"""The picture of issue 30: a kept view of a capture in a room, its background plate, its matte, and a
held-out view (the reference over black, gather before: the matte estimated without a plate, and
after: the plate and the matte that knows it).

    PYTHONPATH=. .venv/bin/python scripts/plate_figure.py CAPTURE OUT.png [--kept I] [--held J] [--crop]

Both models are built from the kept views (i % 2 == 0) with their given matte hidden, as
scripts/plate_eval.py builds them; the held-out panels are gather frames over black.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from capture.extent import remove_surroundings
from capture.io import read_scanset
from capture.matting import MatteConfig, matte_scan
from capture.plate import PlateConfig, PlateView, background_plates
from capture.scan import Scan, ScanSet, to_uint8_srgb
from render import evaluate as ev
from render.gl import gl_context
from render.methods import RenderOptions, create_renderer
from volume.pipeline import build_model
from volume.pipeline.config import PipelineConfig


def _panel(img, label: str) -> np.ndarray:
    x = img if img.dtype == np.uint8 else to_uint8_srgb(np.repeat(img[..., None], 3, -1) if img.ndim == 2 else img)
    return ev.labelled(np.ascontiguousarray(x), label)


def _frame(ctx, model, cam):
    with create_renderer("gather", ctx, model, RenderOptions()) as r:
        return r.render(cam).rgb


def main(argv=None) -> None:
    p = argparse.ArgumentParser()
    p.add_argument("capture")
    p.add_argument("out")
    p.add_argument("--kept", type=int, default=0, help="index among the kept views")
    p.add_argument("--held", type=int, default=0, help="index among the held-out views")
    p.add_argument("--crop", action="store_true", help="crop every panel to the object's box")
    a = p.parse_args(argv)
    split = ev.holdout_split(read_scanset(a.capture), 2, None)
    kept = ScanSet(tuple(Scan(s.rgb, s.depth, s.camera, s.name) for s in split.kept.scans), split.kept.bounds,
                   split.kept.metadata)
    ex, rep = remove_surroundings(kept)
    views = [PlateView(s.camera, s.linear_rgb, s.depth, c.depth) for s, c in zip(ex.scans, kept.scans, strict=True)]
    plates, _ = background_plates(views, PlateConfig(), rep.plane, (rep.focus_center, rep.focus_radius))
    k = a.kept
    s = ex.scans[k]
    m = matte_scan(s, s.depth, MatteConfig(), plates[k])
    plate_img = np.where(plates[k].known[..., None], plates[k].background, 0.0)
    models = {name: build_model(kept, PipelineConfig(matte=MatteConfig(mode=mode), plate=PlateConfig(mode=plate)))[0]
              for name, mode, plate in (("before", "estimate", "off"), ("after", "auto", "auto"))}
    held = split.held[a.held]
    with gl_context() as ctx:
        frames = {n: _frame(ctx, mdl, held.camera) for n, mdl in models.items()}
    top = [_panel(kept.scans[k].srgb8, "kept view"), _panel(plate_img.astype(np.float32), "its plate"),
           _panel(np.clip(m.alpha, 0, 1) ** (1 / 2.2), "its matte")]
    bottom = [_panel(held.srgb8, "held out (truth)"), _panel(frames["before"], "before (no plate)"),
              _panel(frames["after"], "after (plate + matte)")]
    sheet = np.concatenate([np.concatenate(top, 1), np.concatenate(bottom, 1)], 0)
    if a.crop:
        obj = np.concatenate([np.concatenate([kept.scans[k].depth > 0] * 3, 1)] * 2, 0)
        ys, xs = np.nonzero(obj)
        H, W = kept.scans[k].depth.shape
        y0, y1 = max(0, ys.min() % H - 10), min(H, ys.max() % H + 10)
        rows = [sheet[r * H + y0:r * H + y1] for r in range(2)]
        sheet = np.concatenate(rows, 0)
    from capture.imageio import write_png

    write_png(Path(a.out), sheet)
    print(a.out)


if __name__ == "__main__":
    main()

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

#: Margin (px) around the object's box when cropping, the sheet's largest width (px), and the low bits
#: of each 8-bit channel dropped so that the README's PNG stays under 300 KB (6 bits: no visible banding
#: on the path-traced frames' noise).
CROP_MARGIN = 12
MAX_WIDTH = 720
DROP_BITS = 2


def _u8(img) -> np.ndarray:
    """8-bit sRGB (H, W, 3) of a uint8 image, a linear colour image or a linear grey one."""
    if img.dtype == np.uint8:
        return img
    return to_uint8_srgb(np.repeat(img[..., None], 3, -1) if img.ndim == 2 else img)


def _frame(ctx, model, cam):
    with create_renderer("gather", ctx, model, RenderOptions()) as r:
        return r.render(cam).rgb


def _box(masks, shape) -> tuple[slice, slice]:
    """The union box of ``masks`` (H, W) bool, CROP_MARGIN wider, inside ``shape``."""
    ys, xs = np.nonzero(np.any(masks, axis=0))
    H, W = shape
    return (slice(max(0, ys.min() - CROP_MARGIN), min(H, ys.max() + CROP_MARGIN + 1)),
            slice(max(0, xs.min() - CROP_MARGIN), min(W, xs.max() + CROP_MARGIN + 1)))


def _sheet(rows, labels, box) -> np.ndarray:
    """Two rows of panels, each cropped to ``box`` and labelled, at most MAX_WIDTH wide."""
    import cv2

    sheet = np.concatenate([np.concatenate([ev.labelled(np.ascontiguousarray(_u8(x)[box]), t)
                                            for x, t in zip(r, lab, strict=True)], 1)
                            for r, lab in zip(rows, labels, strict=True)], 0)
    if sheet.shape[1] > MAX_WIDTH:
        h = round(sheet.shape[0] * MAX_WIDTH / sheet.shape[1])
        sheet = cv2.resize(sheet, (MAX_WIDTH, h), interpolation=cv2.INTER_AREA)
    return (sheet >> DROP_BITS) << DROP_BITS


def _write(path: Path, sheet: np.ndarray) -> None:
    """``sheet`` (H, W, 3) uint8 RGB as a PNG at the highest compression, written atomically."""
    import cv2

    from capture.atomic import atomic_write

    ok, buf = cv2.imencode(".png", np.ascontiguousarray(sheet[..., ::-1]), [cv2.IMWRITE_PNG_COMPRESSION, 9])
    if not ok:
        raise SystemExit(f"{path}: could not encode the PNG")
    with atomic_write(path) as tmp:
        Path(tmp).write_bytes(buf.tobytes())


def main(argv=None) -> None:
    p = argparse.ArgumentParser()
    p.add_argument("capture")
    p.add_argument("out")
    p.add_argument("--kept", type=int, default=0, help="index among the kept views")
    p.add_argument("--held", type=int, default=0, help="index among the held-out views")
    p.add_argument("--crop", action="store_true", help="crop every panel to the object's box (kept and held-out view)")
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
    plate_img = np.where(plates[k].known[..., None], plates[k].background, 0.0).astype(np.float32)
    models = {name: build_model(kept, PipelineConfig(matte=MatteConfig(mode=mode), plate=PlateConfig(mode=plate)))[0]
              for name, mode, plate in (("before", "estimate", "off"), ("after", "auto", "auto"))}
    held = split.held[a.held]
    with gl_context() as ctx:
        frames = {n: _frame(ctx, mdl, held.camera) for n, mdl in models.items()}
    H, W = s.depth.shape
    box = _box([kept.scans[k].depth > 0, held.depth > 0], (H, W)) if a.crop else (slice(0, H), slice(0, W))
    rows = [[kept.scans[k].srgb8, plate_img, np.clip(m.alpha, 0, 1).astype(np.float32) ** 2.2],
            [held.srgb8, frames["before"], frames["after"]]]
    labels = [["kept view (room)", "its plate (black: unknown)", "its matte"],
              ["held out (truth)", "before: no plate", "after: plate + matte"]]
    _write(Path(a.out), _sheet(rows, labels, box))
    print(a.out)


if __name__ == "__main__":
    main()

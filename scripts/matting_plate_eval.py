"""The known-background (plate) matte at the working resolution against the full-size solve (issue 32), per view.

The capture goes through the pipeline's stages up to the background plate (default flags, one
process), so each view has its plate as ``furrow model`` gives it; then, for the views picked by
``--eval``, the plate path (capture.matting.solve_known) at full size (the reference) and at the
working resolution (capture.matting_scale.known_matte_at_scale) at the rule's scale or each of
``--scales``.  Per (view, scale) one JSON line: alpha MSE between the two over the frame and over
the pixels either leaves partial or unknown, against the true matte when the capture has one (read
as truth only: the plate and the trimap never see it), the premultiplied colour's largest error
against the photo where the background is known (aF = C - (1 - a) B must hold there), seconds; then
a summary per scale.

    PYTHONPATH=. .venv/bin/python scripts/matting_plate_eval.py /work/cache/phone_200 --frames FRAMES --eval 0::15
    PYTHONPATH=. .venv/bin/python scripts/matting_plate_eval.py CAPTURE --scales 0.5
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np


def parse(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("capture", type=Path)
    p.add_argument("--frames", default=None, help="frames the plates are made from (furrow's --frames), default all")
    p.add_argument("--eval", default="0::1", help="python slice start:stop:step of those views to evaluate")
    p.add_argument("--scales", default="rule", help="comma list of scales, or 'rule'")
    p.add_argument("--json", type=Path, default=None, help="also write the rows here")
    return p.parse_args(argv)


def plated_views(capture: Path, frames, pick: slice):
    """Yield (scan in memory, its plate at full size or None, the scan set's depth width) of the views
    ``pick`` after the plate stage (one view in memory at a time)."""
    from capture.plate_scale import grow_plate
    from capture.sources import ReadConfig, open_source
    from volume.pipeline import runner
    from volume.pipeline.config import PipelineConfig
    from volume.pipeline.stages import STAGES

    upto = STAGES[: [s.name for s in STAGES].index("background plate") + 1]
    cfg = replace(PipelineConfig(), read=ReadConfig(frames), workers=1)
    with runner.run_pipeline(open_source(capture), cfg, stages=upto) as run:
        w = run.work
        plates = w.parts.get("plates") or {}
        size = (w.metadata or {}).get("depth_size")
        for ref, s in list(zip(w.refs, w.scans, strict=True))[pick]:
            s = s.load() if hasattr(s, "load") else s
            p = plates.get(ref.index)
            yield s, None if p is None else grow_plate(p, *s.depth.shape[:2]), (int(size[0]) if size else None)


def one_view(scan, plate, scales, depth_width):
    from capture.matting import UNKNOWN, MatteConfig, depth_trimap, solve_known
    from capture.matting_scale import working_scale

    img = scan.linear_rgb
    tri = depth_trimap(scan.depth)
    mask = scan.depth > 0
    t = time.perf_counter()
    ref = solve_known(img, tri, plate.background, plate.known, plate.noise, "plate", mask)
    t_ref = time.perf_counter() - t
    rows = []
    for s in scales:
        scale = working_scale(tri, depth_width) if s == "rule" else float(s)
        cfg = MatteConfig(resolution="working", depth_width=depth_width)
        import capture.matting_scale as ms

        rule = ms.working_scale
        ms.working_scale = lambda trimap, dw=None, _s=scale: _s  # the scale asked for
        try:
            t = time.perf_counter()
            m = solve_known(img, tri, plate.background, plate.known, plate.noise, "plate", mask, cfg)
            dt = time.perf_counter() - t
        finally:
            ms.working_scale = rule
        a, r = m.alpha, ref.alpha
        part = ((r > 0) & (r < 1)) | ((a > 0) & (a < 1)) | (tri == UNKNOWN)
        k = plate.known & (a > 0) & (img.max(-1) < 0.975) & (plate.background.max(-1) < 0.975)
        premul = a[..., None] * m.foreground - (img - (1 - a[..., None]) * plate.background)
        k_ref = plate.known & (r > 0) & (img.max(-1) < 0.975) & (plate.background.max(-1) < 0.975)
        premul_ref = np.abs(r[..., None] * ref.foreground - (img - (1 - r[..., None]) * plate.background))[k_ref]
        row = {"view": scan.name, "scale": round(scale, 4), "solved_at": m.scale, "seconds": round(dt, 3),
               "seconds_full": round(t_ref, 3), "method": m.method, "band_known": round(float(plate.band_known), 4),
               "mse_frame": float(np.mean((a - r) ** 2)),
               "mse_band": float(np.mean((a - r)[part] ** 2)) if part.any() else 0.0,
               "premul_err_known_max": float(np.abs(premul[k]).max()) if k.any() else 0.0,
               "premul_err_known_p99": float(np.quantile(np.abs(premul[k]).max(-1), 0.99)) if k.any() else 0.0,
               "premul_err_known_p99_full": float(np.quantile(premul_ref.max(-1), 0.99)) if k_ref.any() else 0.0}
        if scan.alpha is not None:
            row["mse_truth_full"] = float(np.mean((r - scan.alpha) ** 2))
            row["mse_truth_fast"] = float(np.mean((a - scan.alpha) ** 2))
        rows.append(row)
        print(json.dumps(row), flush=True)
    return rows


def summary(rows, scale) -> dict:
    rr = [r for r in rows if scale is None or r["scale"] == scale]
    worst = max(rr, key=lambda r: r["mse_frame"])
    out = {"scale": scale if scale is not None else "rule", "views": len(rr),
           "mse_frame_mean": float(np.mean([r["mse_frame"] for r in rr])), "mse_frame_worst": worst["mse_frame"],
           "worst_view": worst["view"], "mse_band_mean": float(np.mean([r["mse_band"] for r in rr])),
           "premul_err_known_p99_max": float(max(r["premul_err_known_p99"] for r in rr)),
           "seconds_mean": float(np.mean([r["seconds"] for r in rr])),
           "seconds_full_mean": float(np.mean([r["seconds_full"] for r in rr]))}
    if "mse_truth_full" in rr[0]:
        out.update(mse_truth_full=float(np.mean([r["mse_truth_full"] for r in rr])),
                   mse_truth_fast=float(np.mean([r["mse_truth_fast"] for r in rr])))
    return out


def main(argv=None) -> int:
    from capture.matting import warm_up

    a = parse(argv)
    warm_up()
    pick = slice(*[int(x) if x else None for x in a.eval.split(":")])
    scales = a.scales.split(",")
    rows = []
    for scan, plate, depth_width in plated_views(a.capture, a.frames, pick):
        if plate is None or not plate.known.any():
            print(json.dumps({"view": scan.name, "skipped": "no plate"}), flush=True)
            continue
        rows += one_view(scan, plate, scales, depth_width)
    for sc in sorted({r["scale"] for r in rows}) if a.scales != "rule" else [None]:
        print("summary", json.dumps(summary(rows, sc)), flush=True)
    if a.json:
        a.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Matting at the working resolution against the full-size closed-form solve (issue 32 item 1), per view.

For every view of a capture (after the extent stage; the capture's own matte hidden, so the trimap is
the depth's, as for a capture without mattes): the full-size closed-form matte (capture.matting's
estimate path, the reference) and the working-resolution one (capture.matting_scale) at the scale
its rule gives, or at each ``--scales``; alpha MSE between the two over the frame and over the
trimap's unknown pixels, against the true matte when the capture has one (mask_path), the
foreground colour's RMS difference on partial pixels, and seconds.  One JSON line per (view,
scale), then a summary per scale (mean and worst view).

    PYTHONPATH=. .venv/bin/python scripts/matting_scale_eval.py /work/cache/hardcases/conifer_room_turntable
    PYTHONPATH=. .venv/bin/python scripts/matting_scale_eval.py CAPTURE --scales 0.5,0.33 --frames 0::4
    PYTHONPATH=. .venv/bin/python scripts/matting_scale_eval.py /work/cache/phone_200 --frames 0::20 --depth-width 256
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np


def parse(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("capture", type=Path)
    p.add_argument("--frames", default=None, help="frames (furrow's --frames spec), default all")
    p.add_argument("--scales", default="rule",
                   help="comma list of scales, or 'rule' (capture.matting_scale.working_scale)")
    p.add_argument("--depth-width", type=int, default=None,
                   help="width the depth was measured at (the rule's depth term)")
    p.add_argument("--json", type=Path, default=None, help="also write the rows here")
    return p.parse_args(argv)


def solve_estimate(img, tri, background, known):
    from capture.matting import solve_matte

    return solve_matte(img, tri, "estimate")


def one_view(scan, object_depth, scales, depth_width):
    from capture.matting import UNKNOWN, depth_trimap, solve_matte
    from capture.matting_scale import matte_at_scale, working_scale

    img = scan.linear_rgb
    tri = depth_trimap(object_depth)
    t = time.perf_counter()
    ref = solve_matte(img, tri, "estimate")
    t_ref = time.perf_counter() - t
    band = tri == UNKNOWN
    rows = []
    for s in scales:
        scale = working_scale(tri, depth_width) if s == "rule" else float(s)
        t = time.perf_counter()
        a, f, m = matte_at_scale(img, tri, solve_estimate, scale)
        dt = time.perf_counter() - t
        solved = 1.0 if m is None or m.alpha.shape == tri.shape else scale  # a thin-all-over crop: full size
        part = (ref.alpha > 0.02) & (ref.alpha < 0.98)
        row = {"view": scan.name, "scale": round(scale, 4), "solved_at": round(solved, 4), "seconds": round(dt, 3),
               "seconds_full": round(t_ref, 3),
               "mse_frame": float(np.mean((a - ref.alpha) ** 2)),
               "mse_unknown": float(np.mean((a - ref.alpha)[band] ** 2)) if band.any() else 0.0,
               "fg_rms_partial": float(np.sqrt(np.mean((f - ref.foreground)[part] ** 2))) if part.any() else 0.0,
               "unknown_fraction": float(band.mean())}
        if scan.alpha is not None:
            row["mse_truth_full"] = float(np.mean((ref.alpha - scan.alpha) ** 2))
            row["mse_truth_fast"] = float(np.mean((a - scan.alpha) ** 2))
        rows.append(row)
        print(json.dumps(row), flush=True)
    return rows


def main(argv=None) -> int:
    from capture.extent import remove_surroundings
    from capture.io import read_scanset
    from capture.matting import warm_up

    a = parse(argv)
    warm_up()
    ss = read_scanset(a.capture, a.frames)
    out, _ = remove_surroundings(ss)
    scales = a.scales.split(",")
    rows = []
    for s, o in zip(ss.scans, out.scans, strict=True):
        rows += one_view(s, o.depth, scales, a.depth_width)
    for sc in sorted({r["scale"] for r in rows}) if a.scales != "rule" else [None]:
        rr = [r for r in rows if sc is None or r["scale"] == sc]
        worst = max(rr, key=lambda r: r["mse_frame"])
        summary = {"scale": sc if sc is not None else "rule", "views": len(rr),
                   "mse_frame_mean": float(np.mean([r["mse_frame"] for r in rr])),
                   "mse_frame_worst": worst["mse_frame"], "worst_view": worst["view"],
                   "mse_unknown_mean": float(np.mean([r["mse_unknown"] for r in rr])),
                   "mse_unknown_worst": float(max(r["mse_unknown"] for r in rr)),
                   "seconds_mean": float(np.mean([r["seconds"] for r in rr])),
                   "seconds_full_mean": float(np.mean([r["seconds_full"] for r in rr]))}
        if "mse_truth_full" in rr[0]:
            summary.update(mse_truth_full=float(np.mean([r["mse_truth_full"] for r in rr])),
                           mse_truth_fast=float(np.mean([r["mse_truth_fast"] for r in rr])))
        print("summary", json.dumps(summary), flush=True)
    if a.json:
        a.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())

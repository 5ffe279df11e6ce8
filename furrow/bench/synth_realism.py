"""``furrow bench synth_realism SCANS... [--eval DIR...]``: statistics of captures, to set our
synthetic data beside the unseen path-traced ones (issues 11, 15, 16).

Per scan set, with the frames i % 2 == 0 kept and the others held out (as ``furrow eval
--holdout 2``):

* ``fg``: foreground fraction of the image; ``fg_luma``: mean 8-bit sRGB luma on it;
  ``sharp``: RMS of the Laplacian of the grey image inside the foreground (8-bit units);
* ``depth_cover``: fraction of colour-foreground pixels with a depth measurement (1 - holes);
* ``miss@1/2/4``: the strand-exact reprojection statistic of issue 11: each held-out pixel's own
  depth, looked up in the 1 / 2 / 4 kept views nearest in viewing angle with a strict 4 mm
  visibility test, finds no visible match (unseen captures: fur ball 60/39/23 %, conifer
  48/31/21 %);
* ``points``: the plain RGB-D point splatter of issue 11 (render.points.reference, the ``points``
  method, on the kept scans' own depth: back-project every kept pixel; for a held-out view take
  the 4 kept cameras nearest in viewing angle, z-buffer their points in 2 x 2 splats, average the
  colours within 4 mm of the front, weighted by 1 / angle): masked PSNR, masked SSIM and the
  sharpness ratio (render.metrics, as ``furrow eval`` scores).  Unseen captures: fur ball
  20.50 dB / 0.43 / 1.26, conifer 23.55 / 0.61 / 1.44, furry bunny 20.43 / 0.49 / 1.41.
* with ``--eval FILE`` (one per scan set: the ``furrow eval --json`` file, or the ``furrow eval
  -o DIR`` folder holding eval.json): the masked PSNR / SSIM, sharpness ratio and hole fraction
  of every method it evaluated beside these.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from capture.atomic import write_json
from capture.sampling import nearest_pixel

#: Visibility tolerance of the reprojection statistic (issue 11: 4 mm, the splatter's).
VIS_TOL_M = 0.004
#: Neighbour counts of the reprojection statistic.
MISS_VIEWS = (1, 2, 4)


def miss_fractions(held, kept_scans, centre) -> dict:
    """Fraction of the held-out view's depth pixels with no visible match in the n nearest kept views."""
    pts, _ = held.camera.depth_to_points(held.depth)
    out = {}
    from render.points.reference import nearest_views

    order, _ = nearest_views(held.camera, [s.camera for s in kept_scans], centre, max(MISS_VIEWS))
    seen = np.zeros(len(pts), bool)
    for n, j in enumerate(order, 1):
        s = kept_scans[j]
        uv, z = s.camera.project(pts)
        ij = nearest_pixel(uv)
        ok = (z > 0) & (ij[:, 0] >= 0) & (ij[:, 1] >= 0) & (ij[:, 0] < s.camera.width) & (ij[:, 1] < s.camera.height)
        d = np.zeros(len(pts))
        d[ok] = s.depth[ij[ok, 1], ij[ok, 0]]
        seen |= ok & (d > 0) & (np.abs(d - z) < VIS_TOL_M)
        if n in MISS_VIEWS:
            out[f"miss@{n}"] = float(1 - seen.mean()) if len(pts) else float("nan")
    return out


def capture_stats(path: Path) -> dict:
    from capture.io import read_scanset
    from render.metrics import as_srgb8, foreground, grey, laplacian_rms, psnr, sharpness_ratio, ssim
    from render.points import reference as pr

    ss = read_scanset(path)
    kept = [s for i, s in enumerate(ss.scans) if i % 2 == 0]
    held = [s for i, s in enumerate(ss.scans) if i % 2 == 1]
    centre = 0.5 * (ss.bounds[0] + ss.bounds[1])
    cams = [s.camera for s in kept]
    clouds = pr.back_project(cams, np.stack([s.linear_rgb for s in kept]), np.stack([s.depth for s in kept]))
    rows = []
    for h in held:
        ref8 = as_srgb8(h.rgb)
        fg = foreground(ref8)
        row = {"fg": float(fg.mean()), "fg_luma": float(grey(ref8)[fg].mean()), "sharp": laplacian_rms(ref8, fg),
               "depth_cover": float((h.depth[fg] > 0).mean())}
        row.update(miss_fractions(h, kept, centre))
        pred = as_srgb8(pr.points_frame(h.camera, clouds, cams, centre)[0])
        union = fg | foreground(pred)
        row.update(points_psnr=psnr(ref8, pred, union), points_ssim=ssim(ref8, pred, union),
                   points_sharp_ratio=sharpness_ratio(ref8, pred, union))
        rows.append(row)
    return {k: float(np.mean([r[k] for r in rows])) for k in rows[0]}


def _eval_numbers(p: Path) -> dict:
    """Masked PSNR / SSIM, sharpness ratio and hole fraction of every method of a furrow eval JSON."""
    p = p / "eval.json" if p.is_dir() else p
    if not p.is_file():
        return {}
    e = json.loads(p.read_text())
    out = {}
    for method, r in e.items():
        if isinstance(r, dict) and "psnr_masked" in r:
            out.update({f"{method}_psnr": r["psnr_masked"], f"{method}_ssim": r["ssim_masked"],
                        f"{method}_sharp": r.get("sharpness"), f"{method}_holes": r["hole_fraction"]})
    return out


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="furrow bench synth_realism", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scans", nargs="*", type=Path, help="scan sets (transforms.json folders)")
    ap.add_argument("--eval", nargs="*", type=Path, default=[],
                    help="furrow eval JSON (or -o folder) per scan set (same order)")
    ap.add_argument("--json", type=Path, default=None, help="write the table as JSON")
    args = ap.parse_args(argv)
    if not args.scans:
        print("synth_realism: nothing to measure (give scan sets, e.g. from furrow synth)")
        return 0
    table = {}
    for i, p in enumerate(args.scans):
        st = capture_stats(p)
        if i < len(args.eval):
            st.update(_eval_numbers(args.eval[i]))
        table[str(p)] = st
    keys = list(next(iter(table.values())).keys())
    print("capture".ljust(34) + "".join(k[:12].rjust(13) for k in keys))
    for name, st in table.items():
        print(name[-34:].ljust(34) + "".join(
            (f"{st[k]:13.3f}" if isinstance(st[k], float) else str(st[k]).rjust(13)) for k in keys))
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        write_json(args.json, table)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

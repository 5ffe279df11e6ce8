"""``furrow bench lopt``: held-out PSNR against the L_opt cap (docs/methods.md §1.1 Eq. 1, §1.7).

Builds the model once from the frames i % 2 == 0 with every level kept (the pipeline, Eq. 1's
choice overridden), then for every cap L truncates the pyramid to the levels <= L and renders
the other frames with the microfacet renderer at tolerance E (Eq. 10-11 pick the level per
frame; a small E forces the finest level allowed).  Prints Eq. 1's fractions (N_i / L^3 and
N_i per measured voxel), the level Eq. 1 chooses, and per cap the levels used, PSNR, masked
PSNR, hole fraction and facets.  The numbers quoted in volume/pyramid.py come from:

    furrow bench lopt out/demo/furball_scan --caps 8,16,32,64,128 --tolerance 1
    furrow synth plant -o out/q/plant --views 36 --size 320x240
    furrow bench lopt out/q/plant --caps 8,16,32,64,128,256 --tolerance 1
    furrow synth furball -o out/q/fur640 --views 36 --size 640x480 --seed 1
    furrow bench lopt out/q/fur640 --caps 8,16,32,64 --tolerance 1
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

#: The method whose level-of-detail the cap limits.
METHOD = "microfacet"


def _sweep(args, model, summ: dict, held, cfg) -> dict:
    """The caps sweep over one model (every level kept) and its pipeline summary ``summ``."""
    from render.evaluate import evaluate, result_key
    from render.gl import gl_context
    from render.methods import RenderOptions
    from volume.model import SdfPyramid
    from volume.pyramid import choose_l_opt

    eq1 = {int(L): v for L, v in summ["eq1_fraction"].items()}
    out = {"scans": str(args.scans), "tolerance_px": args.tolerance, "eq1_fraction": summ["eq1_fraction"],
           "eq1_flagged_per_measured": summ["eq1_flagged_per_measured"],
           "eq1_l_opt": choose_l_opt(eq1, cfg.fuse.lopt.t), "caps": []}
    with gl_context() as ctx:
        for L in (int(c) for c in args.caps.split(",")):
            lv = tuple(x for x in model.pyramid.levels if x.resolution <= L)
            if not lv:
                continue
            r = evaluate(ctx, dataclasses.replace(model, pyramid=SdfPyramid(lv, lv[-1].resolution)), held,
                         RenderOptions.for_method(METHOD, tolerance_px=args.tolerance), methods=(METHOD,))
            a = r[result_key(METHOD)]
            row = {"cap": L, "levels_used": sorted({v["level"] for v in a["views"]}), "psnr": a["psnr"],
                   "psnr_masked": a["psnr_masked"], "hole_fraction": a["hole_fraction"], "facets": a["facets"]}
            out["caps"].append(row)
            if not args.json:
                print(f"cap {L:4d} used {row['levels_used']} psnr {a['psnr']:.3f} psnr_masked {a['psnr_masked']:.3f} "
                      f"holes {a['hole_fraction']:.4f} facets {a['facets']:.0f}", flush=True)
    return out


def main(argv: list[str]) -> int:
    from render.microfacet.lod import DEFAULT_TOLERANCE_PX

    p = argparse.ArgumentParser(prog="furrow bench lopt", description=__doc__.splitlines()[0])
    p.add_argument("scans", type=Path, help="scan set (transforms.json or its folder)")
    p.add_argument("--caps", default="8,16,32,64,128", help="comma-separated L_opt caps")
    p.add_argument("--tolerance", type=float, default=DEFAULT_TOLERANCE_PX,
                   help=f"E in pixels (default {DEFAULT_TOLERANCE_PX:g})")
    p.add_argument("--holdout", type=int, default=2)
    p.add_argument("--json", action="store_true", help="print JSON")
    args = p.parse_args(argv)

    import volume.build as vb
    from capture.sources import open_source
    from render.evaluate import build_eval_model, source_holdout
    from volume.pipeline.config import FuseConfig, PipelineConfig

    source = open_source(args.scans)
    # furrow eval's model at the defaults, every level fused (Eq. 1 on a sample would skip L_max)
    cfg = PipelineConfig(fuse=FuseConfig(sample_eq1=False))
    split = source_holdout(source, args.holdout, cfg)
    orig = vb.choose_l_opt
    vb.choose_l_opt = lambda frac, t: max(frac)  # keep every level; Eq. 1's own choice is reported below
    try:
        with build_eval_model(source, split.kept_idx, cfg) as em:
            out = _sweep(args, em.model, em.summary, split.held, cfg)
    finally:
        vb.choose_l_opt = orig
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        print(f"Eq. 1: N_i/L^3 {out['eq1_fraction']}  N_i/measured {out['eq1_flagged_per_measured']}  "
              f"-> L_opt {out['eq1_l_opt']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))

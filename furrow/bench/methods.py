"""``furrow bench methods``: every registered rendering method at its defaults, side by side --
frame time and held-out quality (masked PSNR, masked SSIM, sharpness ratio) on the same views.

The model is built from the frames i % holdout == 0 as ``furrow eval`` builds it (or loaded
with ``--model`` from ``furrow model SCANS --frames 0::2``); the other frames are the references.
Frame times are medians over ``--repeat`` draws of every view without read-back, the methods
interleaved so that they share the machine's load (llvmpipe; process CPU time beside the wall
time); quality comes from one read-back frame per view (render.evaluate.score_view, the scores
of ``furrow eval``).

    furrow bench methods out/data/furball [--model out/models/furball] [--views 6] [--repeat 3]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from capture.atomic import write_json
from furrow.bench import OUT_ROOT
from furrow.bench._common import print_result

#: Quality keys reported (means over the views; render.metrics.compare).
QUALITY = ("psnr_masked", "ssim_masked", "sharpness", "psnr", "hole_fraction")


def measure(ctx, model, held, methods, repeat: int) -> dict:
    """Per method: mean quality over ``held`` and median ms / CPU ms of ``repeat`` draws per view."""
    from render.evaluate import score_view
    from render.methods import create_renderer

    out = {}
    renderers = {m: create_renderer(m, ctx, model) for m in methods}
    try:
        times = {m: ([], []) for m in methods}
        for r in renderers.values():  # warm-up: shader compilation
            r.render(held[0].camera, read=False)
        for _ in range(repeat):
            for s in held:
                for m, r in renderers.items():
                    st = r.render(s.camera, read=False).stats
                    times[m][0].append(st.ms)
                    times[m][1].append(st.cpu_ms)
        for m, r in renderers.items():
            rows = [score_view(s, r.render(s.camera)) for s in held]
            out[m] = {k: float(np.mean([x[k] for x in rows])) for k in QUALITY}
            out[m].update(ms=float(np.median(times[m][0])), cpu_ms=float(np.median(times[m][1])),
                          facets=float(np.mean([x.get("facets", np.nan) for x in rows])))  # NaN: not counted
    finally:
        for r in renderers.values():
            r.release()
    return out


def _table(res: dict) -> None:
    from rich.console import Console
    from rich.table import Table

    t = Table(title=f"every method at its defaults: {res['scans']} ({len(res['held'])} held-out views, llvmpipe)")
    for c in ("method", "ms/frame", "CPU ms", "PSNR masked", "SSIM masked", "sharpness", "PSNR", "holes %"):
        t.add_column(c, justify="right")
    for m, r in res["methods"].items():
        t.add_row(m, f"{r['ms']:.1f}", f"{r['cpu_ms']:.1f}", f"{r['psnr_masked']:.2f}", f"{r['ssim_masked']:.3f}",
                  f"{r['sharpness']:.2f}", f"{r['psnr']:.2f}", f"{100 * r['hole_fraction']:.1f}")
    Console(width=140).print(t)


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="furrow bench methods", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scans", type=Path, nargs="?", default=OUT_ROOT / "data" / "furball", help="scan set")
    p.add_argument("--model", type=Path, default=None,
                   help="model of the frames i %% holdout == 0 (default: build it, as furrow eval does)")
    p.add_argument("--holdout", type=int, default=2)
    p.add_argument("--views", type=int, default=6, help="held-out views measured (evenly spaced)")
    p.add_argument("--repeat", type=int, default=3, help="timed draws per view and method")
    p.add_argument("--methods", default=None, help="comma-separated registry names (default all)")
    p.add_argument("-o", "--out", type=Path, default=OUT_ROOT / "bench" / "methods")
    p.add_argument("--json", action="store_true", help="print the results as JSON on stdout")
    args = p.parse_args(argv)

    from contextlib import nullcontext

    from capture.sources import open_source
    from render.evaluate import EvalModel, build_eval_model, source_holdout
    from render.gl import gl_context
    from render.methods import METHODS
    from volume.model import load_model

    methods = list(METHODS) if args.methods is None else args.methods.split(",")
    source = open_source(args.scans)
    split = source_holdout(source, args.holdout, None, args.views)
    built = nullcontext(EvalModel(load_model(args.model), "model", None, {})) if args.model else \
        build_eval_model(source, split.kept_idx)  # as furrow eval does, at the defaults
    with built as em, gl_context() as ctx:
        res = {"scans": str(args.scans), "held": split.held_idx, "methods": measure(ctx, em.model, split.held,
                                                                                     methods, args.repeat)}
    args.out.mkdir(parents=True, exist_ok=True)
    write_json(args.out / "methods.json", res)
    return print_result(res, args.json, _table, f"wrote {args.out / 'methods.json'}")

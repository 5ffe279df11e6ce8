"""``furrow eval SCANS --holdout K``: held-out evaluation of every rendering method whose spec
says it is evaluated (render.methods.eval_methods: gather, the default; the microfacet renderer; the
plain point splatter; the fixed-mesh VDTM baseline and the vertex-colour floor; docs/methods.md
§1.8, the paper's Fig. 11)."""

from __future__ import annotations

import argparse
from pathlib import Path

from render.evaluate import GEOMETRIES

HELP = "held-out evaluation: build a model from every K-th frame, render the others with every method"
DESCRIPTION_HEAD = """Build a model from the frames i % K == 0 of a scan set, render every other frame with every
method (--methods picks some; each one's spec in render/NAME/spec.py says whether it is evaluated):"""
DESCRIPTION_BODY = """Report per view and mean PSNR and SSIM (8-bit sRGB, scikit-image) over the full image and
inside the union of the reference and rendered foregrounds (their non-black 8-bit pixels: the captures are
over black), the sharpness ratio there (RMS of the Laplacian of the grey image, rendering over
reference: 1 = as crisp as the photo; PSNR rewards blur, so read the two together), the hole
fraction inside the object, ms per frame and, for the methods that count them, facets drawn.
Renderings are scored over black (premultiplied colour in linear light, what a path tracer's
coverage gives).  When the held-out
scans carry a true matte (Scan.alpha, from mask_path), the frames are also composited with their
own alpha over a white (sRGB 235) and a dark (sRGB 24) backdrop and scored against the true
composite (photo + (1 - true alpha) x backdrop; PSNR white / PSNR dark), and their alpha against
the true matte (alpha MSE inside the union of the foregrounds; SAD = sum |error| / 1000);
without a matte these are skipped with a note.
The methods that supersample are drawn with --supersample S x S samples per pixel (default 2: the
references are area-sampled photographs or path-traced images); the others draw one sample per
pixel whatever S.  A method's own flags (below) reach that method.
Writes DIR/side_by_side/VIEW.png (top: reference | {sheets};
bottom: 4 x the absolute error of each) and DIR/eval.json, and with --json FILE the numbers
there too (keys {keys}, each with psnr,
ssim, psnr_masked, ssim_masked, sharpness, psnr_white, psnr_dark, alpha_mse, alpha_sad,
ms_per_frame, alpha_pull (gather's coverage pull, NaN where none), fine_depth / partial_share
(gather's 1-pixel splats first: 1 or 0, and the mattes' partial share), ... and the per-view records;
`options`: the options each method was drawn with).

The model of the kept frames is built by the pipeline of `furrow model` with the same flags (every
flag of `furrow model` that changes the model: --matte, --backdrop, --no-photometric, --views,
--undistort, --keep-support, --no-extent, --max-res, --sdf, ...; --frames picks the frames before
the split): `furrow eval SCANS --holdout 2 --matte off` evaluates the model `furrow model SCANS
--frames 0::2 --matte off` writes.  The held-out references are read by the pipeline's reading
stages only (lenses undistorted, the capture's mattes read).
--geometry: `model` (and `auto`, the default) builds the model with that pipeline; `gt` takes
the voxels from the synthetic set's exact gt/mesh.ply (render.gt_model; the baseline mesh is
then a TSDF fusion of the kept scans).

example:
  furrow eval out/furball --holdout 2 --json out/eval_furball.json -o out/eval_furball"""


def description() -> str:
    """The --help text: the evaluated methods, the sheets and the JSON keys come from the specs."""
    from furrow.method_flags import methods_help
    from render.evaluate import result_key
    from render.methods import eval_methods, sheet_methods

    keys = ", ".join(f"`{result_key(m)}`" for m in eval_methods())
    body = DESCRIPTION_BODY.format(sheets=" | ".join(sheet_methods()), keys=keys)
    return f"{DESCRIPTION_HEAD}\n{methods_help(methods=eval_methods())}\n{body}"


def add_arguments(p: argparse.ArgumentParser) -> None:
    from furrow.method_flags import add_option_arguments
    from furrow.model_flags import add_model_arguments

    p.add_argument("scans", type=Path,
                   help="scan set (transforms.json, a folder holding one, a plain folder or a COLMAP folder)")
    p.add_argument("--holdout", type=int, required=True, metavar="K",
                   help="keep frames with i %% K == 0 for the model, evaluate on the others (K >= 2)")
    p.add_argument("--json", type=Path, default=None, metavar="FILE", help="write the numbers as JSON")
    p.add_argument("-o", "--out", type=Path, default=None,
                   help="folder for the side-by-side sheets and eval.json (default out/eval/NAME)")
    p.add_argument("--methods", default=None, metavar="A,B",
                   help="evaluate these methods only, comma-separated (default: every evaluated method)")
    p.add_argument("--geometry", choices=GEOMETRIES, default="auto", help="where the model's geometry comes from")
    p.add_argument("--l-max", type=int, default=128, help="finest level for --geometry gt (default 128)")
    add_option_arguments(p)
    p.add_argument("--max-views", type=int, default=None,
                   help="evaluate at most this many held-out views (evenly spaced)")
    p.add_argument("--save-model", type=Path, default=None, metavar="DIR",
                   help="also write the evaluated model (the kept frames', as furrow model writes it) to DIR")
    add_model_arguments(p)
    p.add_argument("--debug", action="store_true", help="show tracebacks")


def evaluate_capture(scans: Path, cfg, holdout: int, options=None, out_dir: Path | None = None, timer=None,
                     geometry: str = "auto", l_max: int = 128, max_views: int | None = None, methods=None) -> dict:
    """Held-out evaluation of a capture (module docstring): the frames i %% holdout == 0 (of those
    ``cfg`` reads) through the pipeline with ``cfg`` (volume/pipeline, as ``furrow model``), the
    others read by its reading stages and rendered with every method; returns the eval.json record.
    ``timer``: a furrow.console.StageTimer for the stage table (None: no table)."""
    from capture.sources import open_source
    from furrow.console import StageTimer, track
    from furrow.model_flags import pipeline_hooks
    from render import evaluate as ev
    from render.gl import gl_context

    timer = timer or StageTimer()
    methods = methods or ev.eval_methods()
    source = open_source(scans, cfg.undistort.mode)
    with timer.stage("read held-out views"):
        split = ev.source_holdout(source, holdout, cfg, max_views, track)
    kept, held = split.kept_idx, split.held_idx
    if not held:
        raise ValueError(f"{scans}: {len(kept)} frames leave nothing to hold out with --holdout {holdout}")
    with ev.build_eval_model(source, kept, cfg, geometry, l_max, pipeline_hooks(timer)) as em:
        with gl_context() as ctx, timer.stage(f"render {len(held)} held-out views x {len(methods)} methods"):
            res = ev.evaluate(ctx, em.model, split.held, options, methods, out_dir, track)
        model = em.model
        res.update({"photometric": model.params.get("photometric"), "undistorted": em.metadata.get("undistorted"),
                    "geometry": em.geometry, "levels": model.pyramid.resolutions,
                    "surface_voxels": [len(lv.surface) for lv in model.pyramid.levels]})
        if em.summary is not None:
            res["model"] = {k: em.summary[k] for k in ("l_opt", "views", "resolution", "surroundings", "spill")}
    res.update({"scans": str(scans), "holdout": holdout, "kept": kept, "held": held})
    return res


def run(args, console) -> int:
    from capture.atomic import write_json
    from furrow.console import StageTimer
    from furrow.model_flags import pipeline_config
    from render.methods import options_record

    methods = selected_methods(args.methods)
    options = render_options(args, methods)
    if args.holdout < 2:
        raise ValueError(f"--holdout must be >= 2, got {args.holdout}")
    timer = StageTimer()
    out_dir = args.out or Path("out") / "eval" / Path(args.scans).resolve().name
    if args.save_model is not None and args.geometry == "gt":
        raise ValueError("--save-model saves the pipeline's model: not with --geometry gt")
    cfg = pipeline_config(args, out=args.save_model)
    res = evaluate_capture(args.scans, cfg, args.holdout, options, out_dir, timer, args.geometry, args.l_max,
                           args.max_views, methods)
    res.update({"methods": list(methods), "supersample": options.supersample,
                "options": options_record(options, *methods)})
    print_tables(console, res, methods, out_dir)
    for path in [out_dir / "eval.json"] + ([args.json] if args.json else []):
        write_json(path, res)
        console.print(f"[green]wrote[/] {path}")
    console.print(timer.table())
    return 0


def selected_methods(text: str | None) -> tuple[str, ...]:
    """The methods of --methods (comma-separated registry names), or every evaluated method."""
    from render.methods import eval_methods, method_spec

    if text is None:
        return eval_methods()
    names = tuple(m.strip() for m in text.split(",") if m.strip())
    for m in names:
        method_spec(m)  # an unknown name fails here, naming the registered ones
    if not names:
        raise ValueError("--methods names no method")
    return names


def _cell(value: float, fmt: str) -> str:
    """A table cell; "-" where a method reports nothing (NaN: e.g. facets of a method that does not count them)."""
    import numpy as np

    return "-" if not np.isfinite(value) else f"{value:{fmt}}"


def print_tables(console, res: dict, methods, out_dir: Path) -> None:
    """The scores table (one row per method), the composite table and where the sheets are."""
    from rich.table import Table

    from render import evaluate as ev
    from render.methods import sheet_methods

    S = res["supersample"]
    t = Table(title=f"held-out evaluation ({len(res['held'])} views, geometry: {res['geometry']}, "
                    f"{S}x{S} samples/pixel where the method supersamples)")
    cols = (("PSNR", "psnr", ".2f"), ("SSIM", "ssim", ".3f"), ("PSNR masked", "psnr_masked", ".2f"),
            ("SSIM masked", "ssim_masked", ".3f"), ("sharpness", "sharpness", ".2f"),
            ("holes %", "hole_percent", ".2f"), ("largest hole px", "largest_hole", ".0f"),
            ("ms/frame", "ms_per_frame", ".1f"), ("CPU ms", "cpu_ms_per_frame", ".1f"), ("facets", "facets", ".0f"))
    for c in ("method", *(c[0] for c in cols)):
        t.add_column(c, justify="right")
    for k in map(ev.result_key, methods):
        r = {**res[k], "hole_percent": 100 * res[k]["hole_fraction"]}
        t.add_row(k, *(_cell(r[key], fmt) for _, key, fmt in cols))
    console.print(t)
    own = {m: v for m, v in res["options"].items() if isinstance(v, dict)}
    if own:
        console.print("method options: " + "; ".join(f"{m} " + ", ".join(f"{k}={v}" for k, v in o.items())
                                                   for m, o in own.items()), highlight=False)
    print_pulls(console, res, methods)
    print_composite_table(console, res, methods)
    sheet = " | ".join(m for m in methods if m in sheet_methods())
    console.print(f"side-by-side sheets (reference | {sheet}; below: {ev.ERROR_GAIN:g} x error): "
                  f"{out_dir / 'side_by_side'}")


def print_pulls(console, res: dict, methods) -> None:
    """One line per method that pulled its frames' coverage (render.gather.alpha_mass; frame stats ``alpha_pull``):
    the pull's mean and range over the held-out frames, or that it drew them as drawn; one per method that decides
    its fine depth (render.gather.fine_depth; ``fine_depth``, ``partial_share``): on or off, and why."""
    import numpy as np

    from render import evaluate as ev
    from render.gather.fine_depth import PARTIAL_SHARE

    for k in map(ev.result_key, methods):
        d = np.array([v.get("alpha_pull", np.nan) for v in res[k]["views"]], np.float64)
        if not np.isfinite(d).any():
            continue
        d = d[np.isfinite(d)]
        what = f"d = {d.mean():.3f} (range {d.min():.3f}-{d.max():.3f})" if d.max() > 0 else "none (d = 0)"
        console.print(f"{k}'s coverage pull (a - d a (1 - a), docs/novel_views.md): {what} over {len(d)} frames",
                      highlight=False)
    for k in map(ev.result_key, methods):
        on, share = res[k].get("fine_depth", np.nan), res[k].get("partial_share", np.nan)
        if not np.isfinite(on):
            continue
        why = (f"its mattes {share:.2f} partial, {'at least' if on else 'under'} {PARTIAL_SHARE}" if np.isfinite(share)
               else "as asked" if on else "no matte, or as asked")
        console.print(f"{k}'s fine depth (1-pixel splats first, docs/novel_views.md): {'on' if on else 'off'} ({why})",
                      highlight=False)


def print_composite_table(console, res: dict, methods) -> None:
    """The composite scores (render.evaluate.composite_scores) per method, or a note when the
    held-out scans have no true matte."""
    import numpy as np
    from rich.table import Table

    from render import evaluate as ev

    keys = list(map(ev.result_key, methods))
    if not any(np.isfinite(res[k]["alpha_mse"]) for k in keys):
        console.print("composite scores skipped: the held-out scans carry no true matte (mask_path / Scan.alpha)")
        return
    bd = ev.COMPOSITE_BACKDROPS
    t = Table(title="composites against the true composite (linear light, held-out true matte)")
    for c in ("method", f"PSNR over white ({bd['white']})", f"PSNR over dark ({bd['dark']})", "alpha MSE",
              "alpha SAD / 1000"):
        t.add_column(c, justify="right")
    for k in keys:
        r = res[k]
        t.add_row(k, *(_cell(r[c], f) for c, f in (("psnr_white", ".2f"), ("psnr_dark", ".2f"), ("alpha_mse", ".4f"),
                                                   ("alpha_sad", ".2f"))))
    console.print(t)


def render_options(args, methods):
    """RenderOptions from the command line for ``methods`` (validated: a bad value or a flag none of
    them reads fails before any work; furrow.method_flags)."""
    from furrow.method_flags import render_options as from_flags

    return from_flags(args, methods, "the evaluated methods (" + ", ".join(methods) + ")")

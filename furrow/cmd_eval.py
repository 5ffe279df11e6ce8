"""``furrow eval SCANS --holdout K``: held-out evaluation of every rendering method (gather,
the default; the microfacet renderer; the plain point splatter; the fixed-mesh VDTM baseline and
the vertex-colour floor; the exported 3D Gaussians; docs/methods.md §1.8, the paper's Fig. 11)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from render.evaluate import GEOMETRIES
from render.methods import DEFAULT_SUPERSAMPLE, DEFAULT_TOLERANCE_PX, MICROFACET_MODES

HELP = "held-out evaluation: build a model from every K-th frame, render the others with every method"
DESCRIPTION = """Build a model from the frames i % K == 0 of a scan set, render every other frame with every
method: gather (the default of `furrow render`: the splatted depth of the 2 nearest kept views,
colours resampled from them with soft visibility), the microfacet renderer, the plain RGB-D point
splatter (`points`: 4 nearest kept views, 2x2 splats, colours within 4 mm of the front averaged
by 1/angle), the fixed-mesh VDTM baseline (same cameras, same selection and blending as the
microfacets: they differ only in geometry), the mesh's vertex colours (the floor) and the model's
3D Gaussians (`splat`: what `furrow export --splats` writes, drawn with the 3D Gaussian Splatting
image formation; docs/splats.md).  Report
per view and mean PSNR and SSIM (8-bit sRGB, scikit-image) over the full image and inside the
union of the reference and rendered foregrounds (their non-black 8-bit pixels: the captures are
over black), the sharpness ratio there (RMS of the Laplacian of the grey image, rendering over
reference: 1 = as crisp as the photo; PSNR rewards blur, so read the two together), the hole
fraction inside the object, ms per frame and facet count.  Renderings are scored over black
(premultiplied colour in linear light, what a path tracer's coverage gives).  When the held-out
scans carry a true matte (Scan.alpha, from mask_path), the frames are also composited with their
own alpha over a white (sRGB 235) and a dark (sRGB 24) backdrop and scored against the true
composite (photo + (1 - true alpha) x backdrop; PSNR white / PSNR dark), and their alpha against
the true matte (alpha MSE inside the union of the foregrounds; SAD = sum |error| / 1000);
without a matte these are skipped with a note.
The microfacets and the mesh baselines are drawn with --supersample S x S samples per pixel
(default 2: the references are area-sampled photographs or path-traced images); gather,
points and splat draw one sample per pixel whatever S (gather resamples the photos, whose own
area sampling is kept; the splats' EWA low pass is their anti-aliasing).  The microfacets
parallax-correct their colours along the eye ray (--refine, default 2 steps; 0 = the paper).
Writes DIR/side_by_side/VIEW.png (top: reference | gather | microfacet | points | mesh-vdtm | splat;
bottom: 4 x the absolute error of each) and DIR/eval.json, and with --json FILE the numbers
there too (keys `gather`, `microfacet`, `points`, `mesh_vdtm`, `mesh_colour`, `splat`, each with psnr,
ssim, psnr_masked, ssim_masked, sharpness, psnr_white, psnr_dark, alpha_mse, alpha_sad,
ms_per_frame, ... and the per-view records).

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


def add_arguments(p: argparse.ArgumentParser) -> None:
    from furrow.model_flags import add_model_arguments

    p.add_argument("scans", type=Path,
                   help="scan set (transforms.json, a folder holding one, a plain folder or a COLMAP folder)")
    p.add_argument("--holdout", type=int, required=True, metavar="K",
                   help="keep frames with i %% K == 0 for the model, evaluate on the others (K >= 2)")
    p.add_argument("--json", type=Path, default=None, metavar="FILE", help="write the numbers as JSON")
    p.add_argument("-o", "--out", type=Path, default=None,
                   help="folder for the side-by-side sheets and eval.json (default out/eval/NAME)")
    p.add_argument("--tolerance", type=float, default=DEFAULT_TOLERANCE_PX,
                   help=f"microfacet screen-space tolerance E, pixels (default {DEFAULT_TOLERANCE_PX:g})")
    p.add_argument("--geometry", choices=GEOMETRIES, default="auto", help="where the model's geometry comes from")
    p.add_argument("--l-max", type=int, default=128, help="finest level for --geometry gt (default 128)")
    p.add_argument("--mode", choices=MICROFACET_MODES, default=MICROFACET_MODES[0], help="microfacet slice generation")
    p.add_argument("--supersample", type=int, default=DEFAULT_SUPERSAMPLE, metavar="S",
                   help=f"S x S samples per pixel for every method (default {DEFAULT_SUPERSAMPLE}; 1 = off)")
    p.add_argument("--refine", type=int, default=None, metavar="N",
                   help="microfacet parallax-correction steps (default 2; 0 = the paper's slice-point colour)")
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
    methods = methods or ev.EVAL_METHODS
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
    from rich.table import Table

    from furrow.console import StageTimer
    from furrow.model_flags import pipeline_config
    from render import evaluate as ev

    options = render_options(args)
    if args.holdout < 2:
        raise ValueError(f"--holdout must be >= 2, got {args.holdout}")
    timer = StageTimer()
    out_dir = args.out or Path("out") / "eval" / Path(args.scans).resolve().name
    if args.save_model is not None and args.geometry == "gt":
        raise ValueError("--save-model saves the pipeline's model: not with --geometry gt")
    cfg = pipeline_config(args, out=args.save_model)
    res = evaluate_capture(args.scans, cfg, args.holdout, options, out_dir, timer, args.geometry, args.l_max,
                           args.max_views)
    res.update({"tolerance_px": options.tolerance_px, "supersample": options.supersample,
                "refine": options.refine_steps})
    t = Table(title=f"held-out evaluation ({len(res['held'])} views, geometry: {res['geometry']}, "
                    f"E = {options.tolerance_px:g} px, {options.supersample}x{options.supersample} samples/pixel)")
    for c in ("method", "PSNR", "SSIM", "PSNR masked", "SSIM masked", "sharpness", "holes %", "largest hole px",
              "ms/frame", "CPU ms", "facets"):
        t.add_column(c, justify="right")
    for k in map(ev.result_key, ev.EVAL_METHODS):
        r = res[k]
        t.add_row(k, f"{r['psnr']:.2f}", f"{r['ssim']:.3f}", f"{r['psnr_masked']:.2f}", f"{r['ssim_masked']:.3f}",
                  f"{r['sharpness']:.2f}", f"{100 * r['hole_fraction']:.2f}", f"{r['largest_hole']:.0f}",
                  f"{r['ms_per_frame']:.1f}", f"{r['cpu_ms_per_frame']:.1f}", f"{r['facets']:.0f}")
    console.print(t)
    print_composite_table(console, res, ev)
    sheet = " | ".join(m for m in ev.EVAL_METHODS if m in ev.SHEET_METHODS)
    console.print(f"side-by-side sheets (reference | {sheet}; below: {ev.ERROR_GAIN:g} x error): "
                  f"{out_dir / 'side_by_side'}")
    for path in [out_dir / "eval.json"] + ([args.json] if args.json else []):
        write_json(path, res)
        console.print(f"[green]wrote[/] {path}")
    console.print(timer.table())
    return 0


def print_composite_table(console, res: dict, ev) -> None:
    """The composite scores (render.evaluate.composite_scores) per method, or a note when the
    held-out scans have no true matte."""
    import numpy as np
    from rich.table import Table

    keys = list(map(ev.result_key, ev.EVAL_METHODS))
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
        t.add_row(k, *(f"{r[c]:{f}}" for c, f in (("psnr_white", ".2f"), ("psnr_dark", ".2f"), ("alpha_mse", ".4f"),
                                                  ("alpha_sad", ".2f"))))
    console.print(t)


def write_json(path: Path, data: dict) -> None:
    """``data`` as indented JSON at ``path``, written atomically."""
    from capture.atomic import atomic_write

    with atomic_write(path) as tmp:
        tmp.write_text(json.dumps(data, indent=1))


def render_options(args):
    """RenderOptions from the command line (validated: a bad value fails before any work)."""
    from render.methods import RenderOptions

    return RenderOptions(tolerance_px=args.tolerance, supersample=args.supersample, refine=args.refine, mode=args.mode)

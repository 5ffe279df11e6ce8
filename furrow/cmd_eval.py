"""``furrow eval SCANS --holdout K``: held-out evaluation of the microfacet renderer against the
fixed-mesh VDTM baseline (METHODS §1.8, the paper's Fig. 11)."""

from __future__ import annotations

import argparse
import importlib
import json
from pathlib import Path

import numpy as np

HELP = "held-out evaluation: build a model from every K-th frame, render the others with both methods"
DESCRIPTION = """Build a model from the frames i % K == 0 of a scan set, render every other frame with the
microfacet renderer and with the fixed-mesh VDTM baseline (same cameras, same selection and
blending: they differ only in geometry), and report per view and mean PSNR and SSIM (8-bit
sRGB, scikit-image) over the full image and inside the union of the reference and rendered
foregrounds, the hole fraction inside the object, ms per frame and facet count.
Every method is drawn with the same --supersample S x S samples per pixel (default 2: the
references are area-sampled photographs or path-traced images); the microfacets
parallax-correct their colours along the eye ray (--refine, default 2 steps; 0 = the paper).
Writes DIR/side_by_side/*.png (reference | microfacet | baseline | 4 x |microfacet - reference|)
and, with --json, the numbers (keys `microfacet` and `mesh_vdtm`, each with psnr, ssim,
psnr_masked, ms_per_frame, ...; `mesh_colour` is the per-vertex colour floor).

--geometry: `model` builds the model with the volume stage (volume.build.build_model, the
same as `furrow model`);
`gt` takes the voxels from the synthetic set's exact gt/mesh.ply (render.gt_model; the
baseline mesh is then a TSDF fusion of the kept scans); `auto` (default) uses `model` when
the volume stage provides it, else `gt`.

example:
  furrow eval out/furball --holdout 2 --json out/eval_furball.json -o out/eval_furball"""

#: Amplification of the error panel of the side-by-side images.
ERROR_GAIN = 4.0
GEOMETRIES = ("auto", "model", "gt")
#: Samples per pixel and axis, the same for every method (render.antialias).
DEFAULT_SUPERSAMPLE = 2


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("scans", type=Path, help="scan set (transforms.json, a folder holding one, or a plain folder)")
    p.add_argument("--holdout", type=int, required=True, metavar="K",
                   help="keep frames with i %% K == 0 for the model, evaluate on the others (K >= 2)")
    p.add_argument("--json", type=Path, default=None, metavar="FILE", help="write the numbers as JSON")
    p.add_argument("-o", "--out", type=Path, default=None, help="folder for side-by-side PNGs (default out/eval/NAME)")
    p.add_argument("--tolerance", type=float, default=8.0, help="microfacet screen-space tolerance E, pixels (default 8)")
    p.add_argument("--geometry", choices=GEOMETRIES, default="auto", help="where the model's geometry comes from")
    p.add_argument("--l-max", type=int, default=128, help="finest level for --geometry gt (default 128)")
    p.add_argument("--mode", choices=["instanced", "geometry"], default="instanced", help="microfacet slice generation")
    p.add_argument("--supersample", type=int, default=DEFAULT_SUPERSAMPLE, metavar="S",
                   help=f"S x S samples per pixel for every method (default {DEFAULT_SUPERSAMPLE}; 1 = off)")
    p.add_argument("--refine", type=int, default=None, metavar="N",
                   help="microfacet parallax-correction steps (default 2; 0 = the paper's slice-point colour)")
    p.add_argument("--max-views", type=int, default=None, help="evaluate at most this many held-out views (evenly spaced)")
    p.add_argument("--debug", action="store_true", help="show tracebacks")


def volume_builder():
    """The volume stage's public model builder, or None while it does not exist."""
    try:
        mod = importlib.import_module("volume.build")
    except ModuleNotFoundError as e:
        if e.name in ("volume.build",):
            return None
        raise
    return getattr(mod, "build_model", None)


def build_eval_model(kept, scans_path: Path, geometry: str, l_max: int):
    """Model of the kept scans; returns (model, geometry actually used)."""
    from capture.io import resolve_transforms

    builder = volume_builder() if geometry in ("auto", "model") else None
    if geometry == "model" and builder is None:
        raise RuntimeError("--geometry model: the volume stage has no volume.build.build_model yet; use --geometry gt")
    if builder is not None:
        out = builder(kept, provenance={"scans": str(scans_path), "frames": "i % holdout == 0"})
        return (out[0] if isinstance(out, tuple) else out), "model"
    from render.gt_model import model_from_geometry, read_ply_mesh

    base = scans_path if scans_path.is_dir() else resolve_transforms(scans_path).parent
    ply = base / "gt" / "mesh.ply"
    if not ply.is_file():
        raise FileNotFoundError(f"{ply}: --geometry gt needs a synthetic scan set with gt/mesh.ply")
    v, f = read_ply_mesh(ply)
    return model_from_geometry(kept, v, f, l_max, provenance={"scans": str(scans_path), "gt_mesh": str(ply)}), "gt"


def reference_foreground(scan) -> np.ndarray:
    """Foreground of a reference view: measured depth or any non-black 8-bit pixel."""
    return (scan.depth > 0) | (scan.srgb8.max(axis=-1) > 0)


def summarise(views: list[dict]) -> dict:
    keys = ("psnr", "ssim", "psnr_masked", "ssim_masked", "hole_fraction", "largest_hole", "ms", "cpu_ms", "facets")
    out = {k: float(np.nanmean([v.get(k, np.nan) for v in views])) for k in keys}
    out["ms_per_frame"] = out.pop("ms")
    out["cpu_ms_per_frame"] = out.pop("cpu_ms")
    out["largest_hole"] = float(np.max([v["largest_hole"] for v in views]))
    out["views"] = views
    return out


def evaluate(ctx, model, held, tolerance: float, mode: str = "instanced", out_dir: Path | None = None,
             progress=None, supersample: int = DEFAULT_SUPERSAMPLE, refine: int | None = None) -> dict:
    """Render every held-out scan with both methods (and the vertex-colour floor), all with the
    same ``supersample``; metrics per view and means."""
    from capture.imageio import write_png
    from capture.scan import to_uint8_srgb
    from render import metrics
    from render.microfacet import MicrofacetRenderer
    from render.vdtm import VdtmRenderer, render_vertex_colour

    mf = MicrofacetRenderer.from_model(ctx, model, mode=mode, refine=refine)
    vd = VdtmRenderer.from_model(ctx, model)
    res = {"microfacet": [], "mesh_vdtm": [], "mesh_colour": []}
    try:
        mf.render(held[0].camera, tolerance, read=False, supersample=supersample)  # warm-up: shader compilation
        vd.render(held[0].camera, read=False, supersample=supersample)
        items = progress(held, "evaluating") if progress else held
        for scan in items:
            ref = scan.srgb8
            fg = reference_foreground(scan)
            a = mf.render(scan.camera, tolerance, supersample=supersample)
            b = vd.render(scan.camera, supersample=supersample)
            c = render_vertex_colour(ctx, model, scan.camera, supersample=supersample)
            name = Path(scan.name).name
            for key, fr in (("microfacet", a), ("mesh_vdtm", b), ("mesh_colour", c)):
                m = metrics.compare(ref, fr.rgb, fg, fr.alpha)
                m.update({"view": name, "ms": fr.ms, "cpu_ms": fr.cpu_ms, "facets": fr.facets})
                if key == "microfacet":
                    m.update({"level": a.resolution, "spacing_m": a.spacing})
                res[key].append(m)
            if out_dir is not None:
                a8, b8 = to_uint8_srgb(a.rgb), to_uint8_srgb(b.rgb)
                err = np.clip(np.abs(a8.astype(np.float32) - ref.astype(np.float32)) * ERROR_GAIN, 0, 255).astype(np.uint8)
                write_png(out_dir / "side_by_side" / (Path(name).stem + ".png"), np.concatenate([ref, a8, b8, err], 1))
    finally:
        mf.release()
        vd.release()
    return {k: summarise(v) for k, v in res.items()}


def mg_default_refine() -> int:
    from render.microfacet_geometry import DEPTH_REFINE

    return DEPTH_REFINE


def run(args, console) -> int:
    from rich.table import Table

    from capture.io import read_scanset
    from capture.scan import ScanSet
    from furrow.console import StageTimer, track
    from render.gl import gl_context

    from render.antialias import check_factor

    if args.holdout < 2:
        raise ValueError(f"--holdout must be >= 2, got {args.holdout}")
    check_factor(args.supersample)
    from render.microfacet import MAX_REFINE

    if args.refine is not None and not 0 <= args.refine <= MAX_REFINE:
        raise ValueError(f"--refine must be 0..{MAX_REFINE} steps, got {args.refine}")
    timer = StageTimer()
    with timer.stage("read scans"):
        ss = read_scanset(args.scans)
    n = len(ss.scans)
    kept_idx = [i for i in range(n) if i % args.holdout == 0]
    held_idx = [i for i in range(n) if i % args.holdout != 0]
    if not held_idx:
        raise ValueError(f"{args.scans}: {n} frames leave nothing to hold out with --holdout {args.holdout}")
    if args.max_views is not None and len(held_idx) > args.max_views:
        held_idx = [held_idx[int(round(j))] for j in np.linspace(0, len(held_idx) - 1, args.max_views)]
    kept = ScanSet(tuple(ss.scans[i] for i in kept_idx), ss.bounds, ss.metadata)
    with timer.stage(f"build model from {len(kept_idx)} frames"):
        model, used = build_eval_model(kept, args.scans, args.geometry, args.l_max)
    out_dir = args.out or Path("out") / "eval" / Path(args.scans).resolve().name
    with gl_context() as ctx, timer.stage(f"render {len(held_idx)} held-out views x 2 methods"):
        res = evaluate(ctx, model, [ss.scans[i] for i in held_idx], args.tolerance, args.mode, out_dir, track,
                       args.supersample, args.refine)
    res.update({"scans": str(args.scans), "holdout": args.holdout, "kept": kept_idx, "held": held_idx,
                "geometry": used, "tolerance_px": args.tolerance, "supersample": args.supersample,
                "refine": args.refine if args.refine is not None else mg_default_refine(), "levels": model.pyramid.resolutions,
                "surface_voxels": [len(lv.surface) for lv in model.pyramid.levels]})
    t = Table(title=f"held-out evaluation ({len(held_idx)} views, geometry: {used}, E = {args.tolerance:g} px, "
                    f"{args.supersample}x{args.supersample} samples/pixel)")
    for c in ("method", "PSNR", "SSIM", "PSNR masked", "SSIM masked", "holes %", "largest hole px", "ms/frame",
              "CPU ms", "facets"):
        t.add_column(c, justify="right")
    for k in ("microfacet", "mesh_vdtm", "mesh_colour"):
        r = res[k]
        t.add_row(k, f"{r['psnr']:.2f}", f"{r['ssim']:.3f}", f"{r['psnr_masked']:.2f}", f"{r['ssim_masked']:.3f}",
                  f"{100 * r['hole_fraction']:.2f}", f"{r['largest_hole']:.0f}", f"{r['ms_per_frame']:.1f}",
                  f"{r['cpu_ms_per_frame']:.1f}", f"{r['facets']:.0f}")
    console.print(t)
    console.print(f"side-by-side images (reference | microfacet | baseline | {ERROR_GAIN:g} x error): "
                  f"{out_dir / 'side_by_side'}")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(res, indent=1))
        console.print(f"[green]wrote[/] {args.json}")
    console.print(timer.table())
    return 0

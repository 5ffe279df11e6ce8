"""``furrow bench render``: speed against error of the microfacet renderer (docs/methods.md §1.7-1.8).

The paper's Table 1 (facets and frame rate per volume resolution) reproduced and extended with
held-out error: for every pyramid level (forced) and for the tolerance E in {2, 4, 8, 16} px
(automatic level, Eq. 10-11), at 640x480 and 1280x720, the frame time, the facet count, the
held-out PSNR (full and masked), and the ratio of the frame time to the bare fill cost of the
paper's slices (all of them, untextured, positions-only vertex stage) drawn in the same run.
Also: geometry shader vs instancing, and the fixed-mesh VDTM baseline.

Pipelines (issue 12), side by side in one run, interleaved per view and repeat: the reference
pipeline (one pass over the paper's slices with the whole shader per fragment) and the fast one
(exact tile culling + visibility pre-pass + one colour pass per drawn sample), at E = 8 with 1x1
and 2x2 samples and at the finest level: medians of wall and process-CPU ms, the ratios to the
bare fill, held-out PSNR of both, and the fast pipeline's per-pass CPU ms (select, prepass,
colour, resolve, read-back; each pass synchronised in separate profiled frames).  The machine's
load average is recorded beside them.

Data: a synthetic fur ball written by ``furrow synth`` (black background, EXR depth); the
model takes its voxels from the exact ``gt/mesh.ply`` (render.gt_model) and the frames
i % holdout == 0; the references are the other frames.  The 1280x720 references come from a
second capture of the same scene at that size (same poses: same vertical field of view).

    furrow bench render [--scans out/data/furball] [--scans-720 out/data/furball_720]
                        [--views 3] [--l-max 128] [--repeats 3] [-o out/bench/render] [--json]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from capture.atomic import write_json
from furrow.bench import OUT_ROOT

TOLERANCES = (2.0, 4.0, 8.0, 16.0)
#: Frames of the pipeline comparison: (name, option changes); level -1 = the finest (a resolution L otherwise).
PIPELINE_FRAMES = (("E=8, 1x1", {"supersample": 1}), ("E=8, 2x2", {"supersample": 2}),
                   ("finest level, 1x1", {"supersample": 1, "level": -1}))
#: The two pipelines: renderer attributes (render.microfacet.gl.MicrofacetRenderer cull / prepass).
PIPELINES = {"reference": {"cull": False, "prepass": False}, "fast": {"cull": True, "prepass": True}}
#: The method measured, the baseline beside it (render.methods registry names).
METHOD, BASELINE = "microfacet", "mesh-vdtm"


def _ensure_capture(path: Path, size: tuple[int, int]) -> None:
    if (path / "transforms.json").is_file():
        return
    from datasets_synthetic.rig import TurntableRig
    from datasets_synthetic.synth import SynthConfig, synthesize, write_capture

    print(f"synthesising the fur ball at {size[0]}x{size[1]} into {path} ...", file=sys.stderr)
    cap = synthesize(SynthConfig(scene="furball", background="black", rig=TurntableRig(width=size[0], height=size[1])))
    write_capture(cap, path, depth_format="exr")


def _mean(rows: list[dict], keys) -> dict:
    return {k: float(np.mean([r[k] for r in rows])) for k in keys}


def _bare_fill(renderer, camera, options):
    """Stats of the bare fill of the paper's slices (all of them, untextured) for this frame."""
    cull = renderer.cull
    renderer.cull = False
    try:
        return renderer.render(camera, options, fill_only=True, read=False).stats
    finally:
        renderer.cull = cull


def _measure(renderer, views, options) -> dict:
    """Mean metrics over the views; frame time = median (ms); fill = the bare fill of the slices."""
    from render.evaluate import score_view

    rows = []
    for s in views:
        m = score_view(s, renderer.render(s.camera, options))
        fill = _bare_fill(renderer, s.camera, options)
        rows.append({**m, "fill_ms": fill.ms, "fill_cpu_ms": fill.cpu_ms, "spacing_mm": 1e3 * m["spacing_m"]})
    out = _mean(rows, ("psnr", "psnr_masked", "ssim", "hole_fraction", "facets", "spacing_mm"))
    for k in ("ms", "fill_ms", "cpu_ms", "fill_cpu_ms"):
        out[k] = float(np.median([r[k] for r in rows]))
    out["ratio_to_fill"] = out["ms"] / max(out["fill_ms"], 1e-6)
    out["cpu_ratio_to_fill"] = out["cpu_ms"] / max(out["fill_cpu_ms"], 1e-6)
    out["level"] = int(np.round(np.median([r["level"] for r in rows])))
    return out


def _sweep(r, vd, views, resolutions, base, con, key: str) -> dict:
    """One image size: forced levels, tolerances (+ geometry-shader time), the quality options at
    the paper's E, and the baseline."""
    from render.evaluate import score_view

    r.render(views[0].camera, base, read=False)  # warm-up (shader compilation)
    r.render(views[0].camera, base, mode="geometry", read=False)
    res = {"levels": [], "tolerances": [], "options": []}
    for L in resolutions:
        con.print(f"{key}: level {L}^3 ...")
        res["levels"].append({"L": L, **_measure(r, views, base.changed_for(METHOD, level=L))})
    for E in TOLERANCES:
        con.print(f"{key}: E = {E:g} px ...")
        row = {"E": E, **_measure(r, views, base.changed_for(METHOD, tolerance_px=E))}
        row["geometry_shader_ms"] = float(np.median([r.render(s.camera, base, tolerance_px=E, mode="geometry",
                                                              read=False).stats.ms for s in views]))
        res["tolerances"].append(row)
    # the two quality options beyond the paper, at the paper's E
    own = base.of(METHOD)
    for refine in (0, own.refine_steps):
        for ssf in (1, 2):
            con.print(f"{key}: E = {own.tolerance_px:g}, refine {refine}, {ssf}x{ssf} samples ...")
            res["options"].append({"refine": refine, "supersample": ssf,
                                   **_measure(r, views, base.changed_for(METHOD, refine=refine, supersample=ssf))})
    for name, ssf, keys in (("mesh_vdtm", base.supersample, ("psnr", "psnr_masked", "ssim", "ms", "cpu_ms", "facets")),
                            ("mesh_vdtm_ss2", 2, ("psnr", "psnr_masked", "ms"))):
        res[name] = _mean([score_view(s, vd.render(s.camera, supersample=ssf)) for s in views], keys)
    return res


def _load(args, sizes, con):
    """(model, held-out frame indices, {size: reference scans})."""
    from capture.io import read_scanset
    from render.evaluate import holdout_split
    from render.gt_model import model_from_geometry
    from volume.metrics import read_ply_mesh

    _ensure_capture(args.scans, sizes[0])
    ss = read_scanset(args.scans)
    split = holdout_split(ss, args.holdout, args.views)
    v, f = read_ply_mesh(args.scans / "gt" / "mesh.ply")
    con.print(f"model: {len(split.kept.scans)} kept views, voxels from gt/mesh.ply up to {args.l_max}^3 ...")
    model = model_from_geometry(split.kept, v, f, args.l_max)
    refs = {sizes[0]: split.held}
    for size in sizes[1:]:
        path = args.scans_720 if size == (1280, 720) else None
        if path is None:
            con.print(f"[yellow]no reference capture for {size}; skipped")
            continue
        _ensure_capture(path, size)
        s2 = read_scanset(path)
        refs[size] = [s2.scans[i] for i in split.held_idx]
    return model, split.held_idx, refs


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="furrow bench render", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scans", type=Path, default=OUT_ROOT / "data" / "furball")
    p.add_argument("--scans-720", type=Path, default=OUT_ROOT / "data" / "furball_720")
    p.add_argument("--holdout", type=int, default=2)
    p.add_argument("--views", type=int, default=3, help="held-out views measured (evenly spaced)")
    p.add_argument("--l-max", type=int, default=128)
    p.add_argument("--sizes", default="640x480,1280x720")
    p.add_argument("-o", "--out", type=Path, default=OUT_ROOT / "bench" / "render")
    p.add_argument("--supersample", type=int, default=1, help="samples per pixel and axis of the level / E sweeps")
    p.add_argument("--refine", type=int, default=None, help="parallax-correction steps of the sweeps (default 2)")
    p.add_argument("--repeats", type=int, default=3, help="repeats of the pipeline comparison (medians)")
    p.add_argument("--no-sweep", action="store_true", help="only the pipeline comparison (no level / E sweeps)")
    p.add_argument("--json", action="store_true", help="print the results as JSON on stdout")
    p.add_argument("--replot", action="store_true", help="only redraw render.png from OUT/render.json")
    args = p.parse_args(argv)
    if args.replot:
        _plot(json.loads((args.out / "render.json").read_text()), args.out / "render.png")
        return 0

    from rich.console import Console

    from render.gl import gl_context
    from render.methods import RenderOptions, create_renderer

    base = RenderOptions.for_method(METHOD, supersample=args.supersample, refine=args.refine)
    con = Console(stderr=True, width=170)
    sizes = [tuple(int(v) for v in s.split("x")) for s in args.sizes.split(",")]
    model, held, refs = _load(args, sizes, con)
    results = {"scans": str(args.scans), "held_views": held, "levels": model.pyramid.resolutions,
               "supersample": args.supersample, "refine": args.refine,
               "surface_voxels": [len(lv.surface) for lv in model.pyramid.levels], "sizes": {}, "pipelines": {}}
    with gl_context() as ctx, create_renderer(METHOD, ctx, model, base) as r, \
            create_renderer(BASELINE, ctx, model, base) as vd:
        for size, views in refs.items():
            key = f"{size[0]}x{size[1]}"
            results["pipelines"][key] = _pipelines(r, views, base, args.repeats, con, key)
            if not args.no_sweep:
                results["sizes"][key] = _sweep(r, vd, views, model.pyramid.resolutions, base, con, key)
    args.out.mkdir(parents=True, exist_ok=True)
    write_json(args.out / "render.json", results)
    _tables(con, results, len(held))
    if results["sizes"]:
        _plot(results, args.out / "render.png")
    con.print(f"wrote {args.out / 'render.json'}" + (f" and {args.out / 'render.png'}" if results["sizes"] else ""))
    if args.json:
        print(json.dumps(results, indent=1))
    return 0


def _load_average() -> list[float]:
    import os

    return [round(x, 2) for x in os.getloadavg()]


def _pipelines(r, views, base, repeats: int, con, key: str) -> list[dict]:
    """PIPELINE_FRAMES with both PIPELINES and the bare fill, interleaved per view and repeat
    (module docstring); one row per frame configuration."""
    from render.evaluate import score_view

    rows = []
    for name, changes in PIPELINE_FRAMES:
        if changes.get("level") == -1:
            changes = {**changes, "level": r.levels[-1].resolution}
        opts = base.changed_for(METHOD, **changes)
        con.print(f"{key}: pipelines, {name} ...")
        times = {k: [] for k in (*PIPELINES, "fill")}
        scores, passes, load = {}, {}, [_load_average()]
        for p, attrs in PIPELINES.items():  # warm-up (compilation, buffer sizes) and the scores
            _set(r, attrs)
            r.render(views[0].camera, opts, read=False)
            scores[p] = [score_view(s, r.render(s.camera, opts)) for s in views]
        for _ in range(repeats):
            for s in views:
                for p, attrs in PIPELINES.items():
                    _set(r, attrs)
                    times[p].append(r.render(s.camera, opts, read=False).stats)
                times["fill"].append(_bare_fill(r, s.camera, opts))
                r.profile = True  # the per-pass breakdown, in a separate (synchronised) frame
                for k, (_, cpu) in r.render(s.camera, opts).stats.passes.items():
                    passes.setdefault(k, []).append(cpu)
                r.profile = False
        load.append(_load_average())
        row = {"frame": name, "options": {k: v for k, v in changes.items()}, "load_before_after": load,
               "facets": int(times["fast"][0].facets), "tiles": int(np.median([t.tiles for t in times["fast"]])),
               "level": int(times["fast"][0].resolution),
               "passes_cpu_ms": {k: float(np.median(v)) for k, v in passes.items()}}
        for k, ts in times.items():
            row[f"{k}_ms"] = float(np.median([t.ms for t in ts]))
            row[f"{k}_cpu_ms"] = float(np.median([t.cpu_ms for t in ts]))
        for p in PIPELINES:
            row[f"{p}_x_fill"] = row[f"{p}_ms"] / max(row["fill_ms"], 1e-6)
            row[f"{p}_cpu_x_fill"] = row[f"{p}_cpu_ms"] / max(row["fill_cpu_ms"], 1e-6)
            for m in ("psnr", "psnr_masked", "ssim"):
                row[f"{p}_{m}"] = float(np.mean([sc[m] for sc in scores[p]]))
        rows.append(row)
    _set(r, PIPELINES["fast"])
    return rows


def _set(renderer, attrs: dict) -> None:
    for k, v in attrs.items():
        setattr(renderer, k, v)


def _pipeline_table(con, key: str, rows: list[dict], n_views: int) -> None:
    from rich.table import Table

    load = f"load {rows[0]['load_before_after'][0][0]:.1f} -> {rows[-1]['load_before_after'][-1][0]:.1f}"
    t = Table(title=f"microfacet pipelines side by side, {key} (fur ball, {n_views} held-out views, medians; {load})")
    for c in ("frame", "L", "slices", "tiles", "fill ms", "fill CPU", "ref ms", "ref CPU", "ref x fill", "fast ms",
              "fast CPU", "fast x fill", "CPU x fill", "PSNR ref", "PSNR fast", "mask ref", "mask fast"):
        t.add_column(c, justify="right")
    for r in rows:
        t.add_row(r["frame"], str(r["level"]), str(r["facets"]), str(r["tiles"]), f"{r['fill_ms']:.1f}",
                  f"{r['fill_cpu_ms']:.1f}", f"{r['reference_ms']:.1f}", f"{r['reference_cpu_ms']:.1f}",
                  f"{r['reference_x_fill']:.1f}", f"{r['fast_ms']:.1f}", f"{r['fast_cpu_ms']:.1f}",
                  f"{r['fast_x_fill']:.1f}", f"{r['fast_cpu_x_fill']:.1f}", f"{r['reference_psnr']:.2f}",
                  f"{r['fast_psnr']:.2f}", f"{r['reference_psnr_masked']:.2f}", f"{r['fast_psnr_masked']:.2f}")
    con.print(t)
    names = list(dict.fromkeys(k for r in rows for k in r["passes_cpu_ms"]))
    t = Table(title=f"fast pipeline per pass, {key}: CPU ms (medians; each pass synchronised)")
    for c in ("frame", *names, "sum"):
        t.add_column(c, justify="right")
    for r in rows:
        ps = r["passes_cpu_ms"]
        t.add_row(r["frame"], *[f"{ps[k]:.1f}" if k in ps else "" for k in names], f"{sum(ps.values()):.1f}")
    con.print(t)


def _tables(con, results: dict, n_views: int) -> None:
    from rich.table import Table

    from render.microfacet.lod import DEFAULT_TOLERANCE_PX

    for key, rows in results.get("pipelines", {}).items():
        _pipeline_table(con, key, rows, n_views)

    for key, res in results["sizes"].items():
        t = Table(title=f"microfacet speed vs error, {key} (fur ball, {n_views} held-out views, llvmpipe)")
        for c in ("config", "level", "l mm", "facets", "ms/frame", "CPU ms", "fill ms", "x fill", "CPU x fill", "GS ms",
                  "PSNR", "PSNR mask", "holes %"):
            t.add_column(c, justify="right")
        for row in res["levels"]:
            t.add_row(f"L={row['L']}", str(row["level"]), f"{row['spacing_mm']:.2f}", f"{row['facets']:.0f}",
                      f"{row['ms']:.1f}", f"{row['cpu_ms']:.1f}", f"{row['fill_ms']:.1f}",
                      f"{row['ratio_to_fill']:.1f}",
                      f"{row['cpu_ratio_to_fill']:.1f}", "",
                      f"{row['psnr']:.2f}", f"{row['psnr_masked']:.2f}", f"{100 * row['hole_fraction']:.1f}")
        for row in res["tolerances"]:
            t.add_row(f"E={row['E']:g}px", str(row["level"]), f"{row['spacing_mm']:.2f}", f"{row['facets']:.0f}",
                      f"{row['ms']:.1f}", f"{row['cpu_ms']:.1f}", f"{row['fill_ms']:.1f}",
                      f"{row['ratio_to_fill']:.1f}", f"{row['cpu_ratio_to_fill']:.1f}",
                      f"{row['geometry_shader_ms']:.1f}",
                      f"{row['psnr']:.2f}", f"{row['psnr_masked']:.2f}",
                      f"{100 * row['hole_fraction']:.1f}")
        b = res["mesh_vdtm"]
        t.add_row("mesh VDTM", "", "", f"{b['facets']:.0f}", f"{b['ms']:.1f}", f"{b['cpu_ms']:.1f}", "", "", "", "",
                  f"{b['psnr']:.2f}",
                  f"{b['psnr_masked']:.2f}", "")
        con.print(t)
        t = Table(title=f"quality options at E = {DEFAULT_TOLERANCE_PX:g} px, {key}: parallax correction (refine) "
                        "and supersampling")
        for c in ("refine", "samples", "ms/frame", "CPU ms", "x fill", "CPU x fill", "PSNR", "PSNR mask", "holes %"):
            t.add_column(c, justify="right")
        for row in res.get("options", []):
            t.add_row(str(row["refine"]), f"{row['supersample']}x{row['supersample']}", f"{row['ms']:.1f}",
                      f"{row['cpu_ms']:.1f}", f"{row['ratio_to_fill']:.1f}", f"{row['cpu_ratio_to_fill']:.1f}",
                      f"{row['psnr']:.2f}", f"{row['psnr_masked']:.2f}",
                      f"{100 * row['hole_fraction']:.1f}")
        b2 = res.get("mesh_vdtm_ss2")
        if b2:
            t.add_row("mesh VDTM", "2x2", f"{b2['ms']:.1f}", "", "", "", f"{b2['psnr']:.2f}",
                      f"{b2['psnr_masked']:.2f}", "")
        con.print(t)


def _plot(results: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(12, 4.5))
    for key, res in results["sizes"].items():
        L = [r["L"] for r in res["levels"]]
        ax[0].plot(L, [r["ms"] for r in res["levels"]], "o-", label=f"{key} microfacet")
        ax[0].plot(L, [r["cpu_ms"] for r in res["levels"]], "^:", label=f"{key} microfacet, CPU ms")
        ax[0].plot(L, [r["fill_ms"] for r in res["levels"]], "x--", label=f"{key} bare fill")
        ax[1].plot([r["ms"] for r in res["levels"]], [r["psnr_masked"] for r in res["levels"]], "o-",
                   label=f"{key} levels (E=8)")
        ax[1].plot([r["ms"] for r in res["tolerances"]], [r["psnr_masked"] for r in res["tolerances"]], "s-",
                   label=f"{key} E=2,4,8,16")
        for r in res["tolerances"]:
            ax[1].annotate(f"E{r['E']:g}", (r["ms"], r["psnr_masked"]), fontsize=7)
        b = res["mesh_vdtm"]
        ax[1].plot([b["ms"]], [b["psnr_masked"]], "k*", ms=10, label=f"{key} mesh VDTM")
    ax[0].set_xscale("log", base=2)
    ax[0].set_yscale("log")
    ax[0].set_xlabel("volume resolution L")
    ax[0].set_ylabel("ms / frame (llvmpipe, wall and process CPU)")
    ax[0].axhline(100, color="r", lw=0.8, ls=":")
    ax[0].legend(fontsize=7)
    ax[1].set_xscale("log")
    ax[1].set_xlabel("ms / frame")
    ax[1].set_ylabel("held-out PSNR inside the mask (dB)")
    ax[1].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

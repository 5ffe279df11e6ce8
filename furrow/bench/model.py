"""``furrow bench model``: time and accuracy of the signed distance volume against resolution and method,
and the speed of the whole ``furrow model`` build before/after (``--speed``).

For each scene (``datasets_synthetic`` captures with exact ground truth, cached under
``OUT/data``) and each fusion method (``consensus``: Wheeler-Sato-Ikeuchi style, ``tsdf``:
Open3D's UniformTSDFVolume), the levels 8 .. max(--res) are fused coarse to fine and, at
every resolution in ``--res``, compared with the ground-truth mesh (gt/mesh.ply):
surface-voxel precision / recall / F1, sign accuracy within 3 voxels of the surface and the
mean distance error there (volume.metrics), plus Eq. 1's fraction and the cumulative fusion
time.  ``--target`` also times the whole ``furrow model`` pipeline (fusion, pyramid, spheres,
mesh, RGBz) on the 36-view 640x480 fur ball to a 128^3 pyramid: the issue's target is < 60 s.

``--speed`` times ``furrow model`` at the defaults on the 640x480 captures with millimetre
16-bit PNG depth (``furball-mm``, ``plant-mm``; 18 kept views = frames 0::2, and all 36), each
run in a fresh process (after one untimed warm-up run of this tree: numba compiles once): wall and CPU
seconds (the child's rusage) and peak resident memory (its ru_maxrss), medians of ``--repeats`` runs, with the stage
table of ``--json``.  ``--before``
names what the current tree is compared with, run interleaved with it (so a ratio compares
runs made side by side): ``reference`` = ``furrow model --reference-pipeline`` of this tree
(the slow paths kept beside the fast ones), ``git:REF`` = ``furrow model`` of that commit (a
``git archive`` of it), ``none``.  ``--eval`` adds the held-out quality of both trees
(``furrow eval SCANS --holdout 2``: masked PSNR / SSIM of microfacet and mesh-vdtm; needs
``git:REF``).  Targets (issue 12): 18 views of the fur ball < 20 s, of the plant < 10 s.

``--scale`` measures peak memory, time and model size against the number of frames and the frame
size, with a plot of memory against frames (furrow/bench/_model_scale.py, issue 24).

The ground truth is computed coarse to fine too: the exact distance at a coarse voxel centre
bounds its children's (1-Lipschitz), so only children that can lie within 3 voxels of the
surface are evaluated with Open3D's RaycastingScene; the others keep the coarse sign and a
distance of at least 3 voxels (enough for every metric above).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

from capture.atomic import write_json
from capture.sampling import voxel_centres
from furrow.bench import OUT_ROOT
from furrow.bench._common import save_figure

os.environ.setdefault("OMP_WAIT_POLICY", "passive")
#: The source checkout (``--speed`` times this tree and ``git archive``s the before ref from it).
ROOT = Path(__file__).resolve().parents[2]

#: Scenes: name -> furrow synth arguments (noisy, holed scans as a real scanner gives them).
SCENES = {
    "furball": ["furball", "--depth-noise", "0.002", "--holes", "0.02", "--grazing", "75"],
    "torus": ["torus", "--depth-noise", "0.002", "--holes", "0.02", "--grazing", "75"],
    "furball-clean": ["furball"],
    # the speed benchmark's captures: 36 views 640x480 (the synth defaults), millimetre PNG depth
    "furball-mm": ["furball", "--size", "640x480", "--views", "36", "--png-depth-unit", "0.001"],
    "plant-mm": ["plant", "--size", "640x480", "--views", "36", "--png-depth-unit", "0.001"],
}
#: --speed targets: wall seconds for 18 kept views (issue 12).
SPEED_TARGETS = {"furball-mm": 20.0, "plant-mm": 10.0}
#: --speed view counts -> furrow --frames spec.
VIEW_FRAMES = {18: "0::2", 36: None}
GT_COARSE = 32
NEAR_VOXELS = 3.0


def capture(name: str, data: Path, small: bool) -> Path:
    """Path of a cached synthetic capture (made with `furrow synth` on first use)."""
    from furrow.cli import main as cli

    out = data / (name + ("-small" if small else ""))
    if not (out / "transforms.json").is_file():
        args = ["synth", *SCENES[name], "-o", str(out), "--overwrite"] + (["--small"] if small else [])
        rc = cli(args)
        if rc != 0:
            raise SystemExit(f"furrow {' '.join(args)} failed ({rc})")
    return out


def gt_volumes(verts, faces, origin, extent, resolutions) -> dict[int, np.ndarray]:
    """Ground-truth signed distance at every resolution (coarse to fine, module docstring)."""
    import open3d as o3d

    from volume.fusion import upsample2
    from volume.grid import flat_voxel_indices
    from volume.metrics import mesh_sdf

    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(np.ascontiguousarray(verts, np.float32)),
                        o3d.core.Tensor(np.ascontiguousarray(faces, np.uint32)))
    out = {}
    L = GT_COARSE
    cur = mesh_sdf(verts, faces, origin, extent / L, L)
    out[L] = cur
    top = max(resolutions)
    while L < top:
        Lf, wf, wc = 2 * L, extent / (2 * L), extent / L
        need = upsample2(np.abs(cur) <= np.sqrt(3) / 2 * wc + NEAR_VOXELS * wf * 2)
        idx = np.nonzero(need.reshape(-1))[0]
        far = np.float32((NEAR_VOXELS + 1) * wf)  # not evaluated: farther than every metric looks
        fine = np.where(upsample2(cur) > 0, far, -far).astype(np.float32).reshape(-1)
        for s in range(0, len(idx), 1 << 20):
            sl = idx[s:s + (1 << 20)]
            x = voxel_centres(flat_voxel_indices(sl, Lf), origin, wf).astype(np.float32)
            q = o3d.core.Tensor(x)
            d = scene.compute_distance(q).numpy()
            occ = scene.compute_occupancy(q, nsamples=3).numpy() > 0.5
            fine[sl] = np.where(occ, -d, d)
        cur = fine.reshape(Lf, Lf, Lf)
        L = Lf
        out[L] = cur
    return out


def run_scene(name: str, scans: Path, resolutions: list[int], methods: list[str], frames: str | None) -> list[dict]:
    from capture.io import read_scanset
    from volume.fusion import FusionConfig, fuse_consensus, scan_maps
    from volume.grid import cube_for_bounds
    from volume.metrics import read_ply_mesh, sdf_scores
    from volume.pyramid import discontinuity_fraction
    from volume.tsdf import fuse_tsdf

    ss = read_scanset(scans, frames)
    origin, extent = cube_for_bounds(ss.bounds)
    t0 = time.perf_counter()
    verts, faces = read_ply_mesh(scans / "gt" / "mesh.ply")
    gt = gt_volumes(verts, faces, origin, extent, resolutions)
    gt_s = time.perf_counter() - t0
    cfg = FusionConfig()
    rows = []
    for method in methods:
        fuse = fuse_consensus if method == "consensus" else fuse_tsdf
        t = time.perf_counter()
        maps = [scan_maps(s, cfg.max_grazing_deg, cfg.smooth_sigma_z) for s in ss.scans]
        cum = time.perf_counter() - t
        coarse = None
        L = 8
        while L <= max(resolutions):
            t = time.perf_counter()
            f = fuse(ss, origin, extent / L, L, cfg, maps, coarse=coarse)
            cum += time.perf_counter() - t
            coarse = f
            if L in resolutions:
                s = sdf_scores(f.values, gt[L], f.voxel_size)
                rows.append({"scene": name, "method": method, "resolution": L, "seconds_cumulative": round(cum, 2),
                             "eq1_fraction": round(discontinuity_fraction(f.measured, f.voxel_size, 1.5,
                                                                           f.measured_mask), 5),
                             **{k: (round(v, 4) if isinstance(v, float) else v) for k, v in s.items()},
                             "views": len(ss), "image": f"{ss.scans[0].camera.width}x{ss.scans[0].camera.height}",
                             "gt_seconds": round(gt_s, 1)})
                print(_fmt(rows[-1]), flush=True)
            L *= 2
    return rows


def run_target(scans: Path) -> dict:
    """The whole pipeline (as `furrow model --max-res 128`), timed per stage."""
    from capture.sources import open_source
    from furrow.console import StageTimer
    from furrow.model_flags import pipeline_hooks
    from volume.pipeline.config import FuseConfig, PipelineConfig
    from volume.pipeline.runner import run_pipeline
    from volume.pyramid import LoptConfig

    timer = StageTimer()
    t0 = time.perf_counter()
    source = open_source(scans)
    with run_pipeline(source, PipelineConfig(fuse=FuseConfig(lopt=LoptConfig(max_res=128))),
                      pipeline_hooks(timer)) as run:
        summary = run.summary()
    total = time.perf_counter() - t0
    cam = source.frames[0].camera
    return {"views": summary["views"]["kept"], "image": f"{cam.width}x{cam.height}",
            "seconds_total": round(total, 2), "seconds": {k: round(v, 2) for k, v in timer.seconds.items()},
            "l_opt": summary["l_opt"], "eq1_fraction": summary["eq1_fraction"], "target_seconds": 60.0,
            "met": total < 60.0}


def run_spheres(name: str, scans: Path, targets: list[float], res: int = 64) -> list[dict]:
    """Sphere count and achieved 1 - IoU for a sweep of error targets (docs/methods.md §3)."""
    from capture.io import read_scanset
    from volume.build import fuse_levels
    from volume.model import SdfLevel
    from volume.pipeline.config import FuseConfig
    from volume.pyramid import LoptConfig
    from volume.spheres import fit_spheres, volume_iou

    ss = read_scanset(scans)
    origin, _, fused, _, _ = fuse_levels(ss, FuseConfig(lopt=LoptConfig(max_res=res)))
    f = fused[res]
    lv = SdfLevel(res, origin, f.voxel_size, np.zeros((0, 3), np.int32), f.values)
    rows = []
    for e in targets:
        t = time.perf_counter()
        sph, err = fit_spheres(lv, e)
        dt = time.perf_counter() - t
        rows.append({"scene": name, "resolution": res, "target": e, "spheres": len(sph), "error": round(err, 5),
                     "error_bruteforce": round(1 - volume_iou(sph, lv), 5), "seconds": round(dt, 3)})
        r = rows[-1]
        print(f"spheres {name:14s} {res}^3 target {e:.2f}: {r['spheres']:5d} spheres, 1 - IoU {r['error']:.4f} "
              f"(brute force {r['error_bruteforce']:.4f}), {dt:.2f}s", flush=True)
    return rows


def _run_child(cmd: list[str], cwd: Path, env: dict) -> dict:
    """Run ``cmd`` in a fresh process: (wall s, CPU s, peak MiB, the last stdout line parsed as JSON)."""
    import subprocess
    import tempfile

    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        t0 = time.perf_counter()
        p = subprocess.Popen(cmd, cwd=cwd, env=env, stdout=out, stderr=err, text=True)
        _, status, ru = os.wait4(p.pid, 0)
        wall = time.perf_counter() - t0
        p.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        err.seek(0)
        lines = out.read().strip().splitlines()
        if p.returncode != 0 or not lines:
            raise SystemExit(f"{' '.join(cmd)} failed ({p.returncode}): {err.read()[-2000:]}")
    return {"wall_s": wall, "cpu_s": ru.ru_utime + ru.ru_stime, "peak_mb": ru.ru_maxrss / 1024.0,
            "summary": json.loads(lines[-1])}


def _tree(before: str, work: Path) -> Path | None:
    """Source tree of the ``before`` variant: a git archive of REF for ``git:REF``, else None."""
    import subprocess

    if not before.startswith("git:"):
        return None
    dst = work / ("before-" + before[4:].replace("/", "_"))
    if not (dst / "furrow").is_dir():
        dst.mkdir(parents=True, exist_ok=True)
        arc = subprocess.run(["git", "-C", str(ROOT), "archive", before[4:]], capture_output=True, check=True).stdout
        subprocess.run(["tar", "-x", "-C", str(dst)], input=arc, check=True)
    return dst


def run_speed(scene: str, scans: Path, views: list[int], repeats: int, before: str, work: Path) -> list[dict]:
    """Interleaved before/after ``furrow model`` runs at the defaults (module docstring)."""
    variants = [("after", ROOT, [])]
    old = _tree(before, work)
    if before == "reference":
        variants.insert(0, ("before", ROOT, ["--reference-pipeline"]))
    elif old is not None:
        variants.insert(0, ("before", old, []))
    rows = []
    for n in views:
        frames = ["--frames", VIEW_FRAMES[n]] if VIEW_FRAMES.get(n) else []
        runs = {name: [] for name, _, _ in variants}
        for rep in range(-1, repeats):  # run -1: untimed warm-up (numba's compile cache, the disk cache)
            for name, tree, extra in variants:
                env = {**os.environ, "PYTHONPATH": str(tree), "OMP_WAIT_POLICY": "passive"}
                out = work / f"model-{scene}-{n}-{name}"
                cmd = [sys.executable, "-m", "furrow", "model", str(scans), "-o", str(out), "--overwrite", "--json",
                       *frames, *extra]
                if rep < 0 and name == "before":
                    continue  # the warm-up compiles this tree's numba kernels; the before tree has none
                r = _run_child(cmd, tree, env)
                if rep < 0:
                    continue
                runs[name].append(r)
                print(f"speed {scene} {n} views {name} run {rep + 1}: {r['wall_s']:.1f} s wall, "
                      f"{r['cpu_s']:.1f} s CPU, {r['peak_mb']:.0f} MiB", flush=True)
        for name, rr in runs.items():
            med = {k: float(np.median([r[k] for r in rr])) for k in ("wall_s", "cpu_s", "peak_mb")}
            stages = {k: float(np.median([r["summary"]["seconds"].get(k, np.nan) for r in rr]))
                      for k in rr[0]["summary"]["seconds"]}
            rows.append({"scene": scene, "views": n, "variant": name, "before": before if name == "before" else "",
                         "runs": len(rr), **med, "wall_all": [round(r["wall_s"], 2) for r in rr],
                         "cpu_all": [round(r["cpu_s"], 2) for r in rr], "stages_median_s": stages,
                         "l_opt": rr[0]["summary"]["l_opt"], "mesh": rr[0]["summary"]["mesh"],
                         "target_s": SPEED_TARGETS.get(scene) if n == 18 else None})
        if "before" in runs:  # ratio of runs made side by side (same repeat)
            ratio = [b["wall_s"] / a["wall_s"] for b, a in zip(runs["before"], runs["after"])]
            rows[-1]["speedup_wall_median"] = float(np.median(ratio))
            rows[-1]["speedup_cpu_median"] = float(np.median([b["cpu_s"] / a["cpu_s"]
                                                              for b, a in zip(runs["before"], runs["after"])]))
    return rows


def run_quality(scene: str, scans: Path, before: str, work: Path) -> list[dict]:
    """Held-out masked PSNR / SSIM of microfacet and mesh-vdtm, ``furrow eval --holdout 2`` of both trees."""
    old = _tree(before, work)
    rows = []
    for name, tree in ([("before", old)] if old is not None else []) + [("after", ROOT)]:
        js = work / f"eval-{scene}-{name}.json"
        env = {**os.environ, "PYTHONPATH": str(tree), "OMP_WAIT_POLICY": "passive"}
        cmd = [sys.executable, "-m", "furrow", "eval", str(scans), "--holdout", "2", "--json", str(js),
               "-o", str(work / f"eval-{scene}-{name}")]
        import subprocess

        subprocess.run(cmd, cwd=tree, env=env, check=True, capture_output=True)
        d = json.loads(js.read_text())
        rows.append({"scene": scene, "variant": name, **{f"{m}_{k}": d[m][k] for m in ("microfacet", "mesh_vdtm")
                                                          for k in ("psnr_masked", "ssim_masked")}})
        print(f"quality {scene} {name}: " + ", ".join(f"{k} {v:.3f}" for k, v in rows[-1].items()
                                                     if isinstance(v, float)), flush=True)
    return rows


def speed_table(rows: list[dict], quality: list[dict]):
    from rich.table import Table

    t = Table(title="furrow model at the defaults (medians of fresh-process runs; ratio = before / after, same repeat)")
    for c in ("scene", "views", "variant", "runs", "wall s", "CPU s", "peak MiB", "speed-up wall / CPU", "target",
              "microfacet dB / SSIM", "mesh-vdtm dB / SSIM"):
        t.add_column(c, justify="left" if c in ("scene", "variant") else "right")
    q = {(r["scene"], r["variant"]): r for r in quality}
    for r in rows:
        sp = f"{r['speedup_wall_median']:.2f}x / {r['speedup_cpu_median']:.2f}x" if "speedup_wall_median" in r else ""
        tg = ""
        if r["target_s"] and r["variant"] == "after":
            tg = f"< {r['target_s']:.0f} s: {'met' if r['wall_s'] < r['target_s'] else 'MISSED'}"
        qq = q.get((r["scene"], r["variant"])) if r["views"] == 18 else None
        mf = f"{qq['microfacet_psnr_masked']:.2f} / {qq['microfacet_ssim_masked']:.3f}" if qq else ""
        mv = f"{qq['mesh_vdtm_psnr_masked']:.2f} / {qq['mesh_vdtm_ssim_masked']:.3f}" if qq else ""
        t.add_row(r["scene"], str(r["views"]), r["variant"] + (f" ({r['before']})" if r["before"] else ""),
                  str(r["runs"]), f"{r['wall_s']:.1f}", f"{r['cpu_s']:.1f}", f"{r['peak_mb']:.0f}", sp, tg, mf, mv)
    return t


def _fmt(r: dict) -> str:
    return (f"{r['scene']:14s} {r['method']:9s} {r['resolution']:4d}^3  {r['seconds_cumulative']:7.2f}s  "
            f"P {r['precision']:.3f} R {r['recall']:.3f} F1 {r['f1']:.3f}  sign {r['sign_accuracy']:.4f}  "
            f"err {r['dist_error_voxels']:.3f} vox  eq1 {r['eq1_fraction']:.4f}")


def plot(rows: list[dict], out: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 4, figsize=(18, 4.2))
    keys = [("seconds_cumulative", "fusion time (s, cumulative 8..L)"), ("f1", "surface-voxel F1"),
            ("sign_accuracy", "sign accuracy (|d| < 3 voxels)"), ("dist_error_voxels", "distance error (voxels)")]
    for ax, (k, title) in zip(axes, keys):
        for scene in sorted({r["scene"] for r in rows}):
            for method in sorted({r["method"] for r in rows}):
                rr = [r for r in rows if r["scene"] == scene and r["method"] == method]
                if rr:
                    ax.plot([r["resolution"] for r in rr], [r[k] for r in rr], "o-" if method == "consensus" else "s--",
                            label=f"{scene} / {method}")
        ax.set_xscale("log", base=2)
        ax.set_xlabel("resolution L")
        ax.set_title(title)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    return save_figure(fig, out / "model_bench.png", dpi=110)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="furrow bench model", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", default="furball,torus", help=f"comma list of {sorted(SCENES)}")
    ap.add_argument("--methods", default="consensus,tsdf", help="comma list of consensus, tsdf")
    ap.add_argument("--res", default="64,128,256", help="resolutions to score (powers of two >= 32)")
    ap.add_argument("--small", action="store_true", help="CI-sized captures (12 views, 160x120)")
    ap.add_argument("--frames", default=None, help="frame spec passed to the reader (e.g. 0::2)")
    ap.add_argument("--target", action="store_true",
                    help="also time the full pipeline on the 36-view 640x480 fur ball to 128^3 (target < 60 s)")
    ap.add_argument("--no-sweep", action="store_true", help="skip the resolution/method sweep")
    ap.add_argument("--spheres", default="", help="also sweep sphere-set error targets, e.g. 0.4,0.3,0.2,0.1,0.05")
    ap.add_argument("--speed", action="store_true", help="time furrow model at the defaults, before/after (docstring)")
    ap.add_argument("--speed-scenes", default="furball-mm", help="comma list of furball-mm, plant-mm, or NAME=PATH")
    ap.add_argument("--views", default="18,36", help="--speed: kept views, 18 (frames 0::2) and/or 36")
    ap.add_argument("--repeats", type=int, default=3, help="--speed: runs per variant (medians)")
    ap.add_argument("--before", default="reference", help="--speed: reference, git:REF or none")
    ap.add_argument("--eval", action="store_true", help="--speed: also held-out quality of both trees (git:REF)")
    ap.add_argument("--scale", action="store_true",
                    help="peak memory, time and model size against frames and frame size (furrow/bench/_model_scale.py;"
                         " --before git:REF adds that commit's builds)")
    ap.add_argument("--sizes", default="640x480,1280x960,1920x1440", help="--scale: frame sizes WxH")
    ap.add_argument("--frame-counts", default="18,36,72,144", help="--scale: frame counts (subsets of the largest)")
    ap.add_argument("--scale-spill", choices=["auto", "always", "never"], default=None,
                    help="--scale: furrow model --spill for every build (default: furrow model's, auto)")
    ap.add_argument("--scale-scans", default=None, metavar="WxH=PATH,...",
                    help="--scale: use these captures instead of synthesising the plant (one per frame size)")
    ap.add_argument("-o", "--out", type=Path, default=OUT_ROOT / "bench" / "model")
    ap.add_argument("--json", action="store_true", help="print the rows as JSON on stdout")
    args = ap.parse_args(argv)
    if args.scale:
        from furrow.bench._model_scale import scale_main

        return scale_main(args, _run_child, _tree, ROOT)
    res = [int(r) for r in args.res.split(",") if r]
    if any(r < GT_COARSE or r & (r - 1) for r in res):
        raise SystemExit(f"--res: powers of two >= {GT_COARSE}, got {res}")
    data = args.out / "data"
    if args.speed:
        return _speed_main(args, data)
    rows, target = [], None
    if not args.no_sweep:
        for scene in [s for s in args.scenes.split(",") if s]:
            if scene not in SCENES:
                raise SystemExit(f"unknown scene {scene!r}; choose from {sorted(SCENES)}")
            rows += run_scene(scene, capture(scene, data, args.small), res,
                              [m for m in args.methods.split(",") if m], args.frames)
    sphere_rows = []
    if args.spheres:
        targets = [float(e) for e in args.spheres.split(",") if e]
        for scene in [s for s in args.scenes.split(",") if s]:
            sphere_rows += run_spheres(scene, capture(scene, data, args.small), targets)
    if args.target:
        target = run_target(capture("furball-clean", data, False))
        print(f"target: {target['views']} views {target['image']} -> 128^3 pyramid in {target['seconds_total']} s "
              f"(target < 60 s: {'met' if target['met'] else 'NOT met'}); stages {target['seconds']}", flush=True)
    result = {"rows": rows, "target": target, "spheres": sphere_rows}
    args.out.mkdir(parents=True, exist_ok=True)
    name = "model_bench.json" if rows else ("model_bench_spheres.json" if sphere_rows else "model_bench_target.json")
    write_json(args.out / name, result)
    if rows:
        p = plot(rows, args.out)
        print(f"plot: {p}")
    if args.json:
        print(json.dumps(result))
    return 0


def _speed_main(args, data: Path) -> int:
    from rich.console import Console

    views = [int(v) for v in args.views.split(",") if v]
    if any(v not in VIEW_FRAMES for v in views):
        raise SystemExit(f"--views: choose from {sorted(VIEW_FRAMES)}")
    work = (args.out / "speed").resolve()
    work.mkdir(parents=True, exist_ok=True)
    rows, quality = [], []
    for item in [s for s in args.speed_scenes.split(",") if s]:
        name, _, path = item.partition("=")
        scans = (Path(path) if path else capture(name, data, False)).resolve()
        rows += run_speed(name, scans, views, args.repeats, args.before, work)
        if args.eval:
            quality += run_quality(name, scans, args.before, work)
    result = {"speed": rows, "quality": quality, "before": args.before, "load_average": os.getloadavg()}
    write_json(args.out / "model_bench_speed.json", result)
    Console(stderr=True, width=200).print(speed_table(rows, quality))
    if args.json:
        print(json.dumps(result))
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

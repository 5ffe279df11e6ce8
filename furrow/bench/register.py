"""``furrow bench register``: pose error after registration vs. initial perturbation, and time.

Scenes (ground-truth poses known, every view but the gauge perturbed by exactly D degrees
about a random axis through the object centre and D % of the object size in a random
direction, seeded):

* ``control``: analytic ray-cast object (tilted torus + sphere + box, no symmetry), exact depth;
* ``torus`` / ``plant`` / ``furball``: ``datasets_synthetic`` captures (``--small`` rig: 12 views,
  160x120, rendered with the true poses);
* ``face``: the REAL structured-light range map shipped in pymeshlab's wheel (GPL-3.0 sample
  data), cut into 2x3 overlapping windows;
* ``furball-board`` / ``plant-board`` / ``torus-board``: the same scenes standing on a ChArUco
  board (``datasets_synthetic.board``), 480x360 views from 50 degrees elevation;
* ``sfm``: the analytic object with a feature-rich solid texture, 36 views at 320x240 (SfM needs
  a short baseline; used for the ``colmap`` method).

* ``plant`` / ``torus`` / ``furball`` / ``furball-curly`` / ``furball-uniform`` / ``furrybunny`` with
  ``--data DIR``: 36-view 640x480 captures written once by ``furrow synth NAME -o DIR/NAME
  --depth-format exr`` (``furball-curly``: ``furrow synth furball --curly``, the harder fur ball of
  issue 22; ``furball-uniform``: ``--coat uniform``, one coat on a sphere, issue 31; made when
  missing), given a consumer sensor's traits in memory (``--sensor mm``, the default: flying
  pixels on depth edges, z^2 noise, 16-bit millimetre quantisation;
  ``capture.registration.scenes.sensor_depth``).

``--rigs free,turntable``: the per-scan-pose registration and the turntable prior
(``turntable_place``), each on the same perturbed poses.

``--captures DIR,...``: ``furrow register``'s defaults on captures whose recorded poses are already
perturbed and whose true poses are in ``gt/cameras_true.json`` (``furrow synth --pose-noise-deg``,
or the independent path-traced hard cases of /work/cache/hardcases): every view is scored, the
ones kept at their input pose too (issue 31: all views written; none worse than its input).

Errors (``capture.registration.report.pose_errors``): rotation of cam_from_world and
displacement of the object centre in camera coordinates (mm and % of the object size), after the
rigid transform that best fits all poses to the truth, over every view (all are written: the
ones kept or flagged at their input pose are scored there).  After the independent check
(``capture.registration.verify``) each row counts the views registered / kept at input / flagged,
and ``worse_max_deg``: the most a view ends worse than its input pose (both after the
best-fitting rigid gauge).  With ``--captures`` (output in the input's frame) also without the
rigid fit (``direct_*``, ``worse_max_direct_deg``: a view kept at its input scores exactly as its
input), and the output poses (``poses``, cam_from_world).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

from capture.atomic import write_json
from furrow.bench import OUT_ROOT

os.environ.setdefault("OMP_WAIT_POLICY", "passive")



SCENES = ("control", "torus", "plant", "furball", "furball-curly", "furball-uniform", "furrybunny", "face", "sfm",
          "furball-board", "plant-board", "torus-board")
#: Data scenes written by ``furrow synth`` with extra flags (folder name -> (scene, flags)).
SYNTH_VARIANTS = {"furball-curly": ("furball", ["--curly"]), "furball-uniform": ("furball", ["--coat", "uniform"])}
RIGS = ("free", "turntable")
METHODS = ("icp", "icp-geom", "colmap", "board")


def load_data_scene(name: str, data: Path, views: int, width: int, sensor: str):
    """A ``furrow synth`` capture under ``data``/NAME (written when missing, exact EXR depth), with
    the sensor's traits applied: (ScanSet with true poses, true cam_from_world)."""
    import subprocess

    from capture import io as cio
    from capture.registration import scenes

    folder = data / name
    if not (folder / "transforms.json").is_file():
        height = width * 3 // 4
        scene, extra = SYNTH_VARIANTS.get(name, (name, []))
        subprocess.run([sys.executable, "-m", "furrow", "synth", scene, "-o", str(folder), "--views", str(views),
                        "--size", f"{width}x{height}", "--depth-format", "exr", *extra], check=True)
    ss = cio.read_scanset(folder)
    if sensor == "mm":
        ss = scenes.with_sensor(ss, seed=0)
    return ss, [s.camera.cam_from_world for s in ss.scans]


def load_scene(name: str, views: int, width: int):
    """(ScanSet with TRUE poses, list of true cam_from_world)."""
    from capture.registration import scenes

    if name == "control":
        cams = scenes.ring_cameras(views, width=width, height=width * 3 // 4)
        ss = scenes.render_set(scenes.control_object(), cams)
    elif name == "sfm":
        cams = scenes.ring_cameras(36, width=320, height=240)
        ss = scenes.render_set(scenes.control_object(), cams, rich_texture=True)
    elif name == "face":
        from capture.registration import rangemap

        ss = rangemap.face_scanset()
    else:
        import dataclasses

        from datasets_synthetic.synth import SMALL_RIG, SynthConfig, synthesize

        scene = spec = None
        rig = dataclasses.replace(SMALL_RIG, views_per_ring=views, width=width, height=width * 3 // 4)
        if name.endswith("-board"):
            from datasets_synthetic.board import add_board
            from datasets_synthetic.scenes import build_scene

            name = name[: -len("-board")]
            scene, spec = add_board(build_scene(name))
            # the board needs pixels: 480x360, looking down 50 degrees from 0.65 m
            rig = dataclasses.replace(SMALL_RIG, views_per_ring=views, width=480, height=360,
                                      elevations_deg=(50.0,), distance=0.65, fov_y_deg=40.0)
        params = {}
        if name in ("furball-curly", "furball-uniform"):
            from datasets_synthetic.fur_variants import CURLY, UNIFORM

            name, params = "furball", dict(CURLY if name == "furball-curly" else UNIFORM)
        cap = synthesize(SynthConfig(scene=name, rig=rig, supersample=2, scene_params=params), scene=scene)
        from capture.camera import Camera
        from capture.scan import Scan, ScanSet

        scans = tuple(Scan(s.rgb, s.depth, Camera(s.camera.K, c.cam_from_world, s.camera.width, s.camera.height,
                                                  s.camera.name), s.name)
                      for s, c in zip(cap.scanset.scans, cap.true_cameras))
        meta = dict(cap.scanset.metadata)
        bounds = cap.scanset.bounds
        if spec is not None:
            meta["board_spec"] = spec
            # object bounds (without the board): the size that errors are quoted against
            from capture.scan import bounds_from_points

            bounds = bounds_from_points(build_scene(name).mesh.vertices, margin=0.05)
        ss = ScanSet(scans, bounds, meta)
    return ss, [s.camera.cam_from_world for s in ss.scans]


def with_poses(ss, poses):
    from capture.camera import Camera
    from capture.scan import Scan, ScanSet

    return ScanSet(tuple(Scan(s.rgb, s.depth, Camera(s.camera.K, p, s.camera.width, s.camera.height, s.camera.name),
                              s.name) for s, p in zip(ss.scans, poses)), ss.bounds, ss.metadata)


def _register(inp, method: str, rig: str, ss):
    from capture.registration import icp, pipeline

    if method == "icp-geom":
        return pipeline.register(inp, "icp", "nominal", icp.IcpConfig(color_scale_frac=0.0), rig=rig)
    if method == "board":
        return pipeline.register(inp, "board", "nominal", board=ss.metadata.get("board_spec"), rig=rig)
    if method not in ("icp", "colmap"):
        raise ValueError(method)
    return pipeline.register(inp, method, "nominal", rig=rig)


def run_one(ss, gt, method: str, deg: float, seed: int, rig: str = "free") -> dict:
    from capture.registration import perturb, report

    c = ss.bounds.mean(axis=0)
    size = ss.size
    pert = perturb.perturb_poses(gt, deg, deg / 100 * size, c, seed=seed)
    inp = with_poses(ss, pert)
    t0 = time.perf_counter()
    try:
        _, rep, poses = _register(inp, method, rig, ss)
    except Exception as e:  # a method that cannot run on a scene is reported, not hidden
        return {"method": method, "rig": rig, "perturb_deg": deg, "failed": f"{type(e).__name__}: {e}",
                "seconds": time.perf_counter() - t0}
    secs = time.perf_counter() - t0
    idx = list(range(len(gt)))  # every view is written (issue 31): registered, kept or flagged at its input
    e = report.pose_errors([poses[k] for k in idx], [gt[k] for k in idx], c, gauge=None) if len(idx) > 1 else None
    b = report.pose_errors(pert, gt, c, gauge=None)
    worse = [a - b["rot_deg"][k] for a, k in zip(e["rot_deg"], idx)] if e is not None else []
    evidence: dict = {}
    for s in rep.scans:
        for ev in s.evidence:
            evidence[ev] = evidence.get(ev, 0) + 1
    out = {"method": method, "rig": rep.rig, "perturb_deg": deg, "perturb_frac": deg / 100, "seconds": secs,
           "n_views": len(gt), "n_written": len(idx),
           "n_registered": sum(s.status == "registered" for s in rep.scans), "flagged": rep.flagged,
           "kept": rep.kept, "size_m": size,
           "evidence_counts": evidence, "rig_detection": rep.rig_detection,
           "before_rot_median_deg": b["rot_median_deg"], "before_rot_max_deg": b["rot_max_deg"],
           "before_trans_median_frac": b["trans_median_m"] / size,
           "check": dict(rep.check), "status": {s.name: s.status for s in rep.scans},
           "worse_max_deg": max(worse) if worse else None,
           "view_rot_deg": {rep.scans[k].name: e["rot_deg"][i] for i, k in enumerate(idx)} if e is not None else {},
           "view_rot_in_deg": {s.name: b["rot_deg"][k] for k, s in enumerate(rep.scans)}}
    if e is not None:
        out.update({"rot_median_deg": e["rot_median_deg"], "rot_max_deg": e["rot_max_deg"],
                    "trans_median_mm": 1000 * e["trans_median_m"], "trans_max_mm": 1000 * e["trans_max_m"],
                    "trans_median_frac": e["trans_median_m"] / size, "trans_max_frac": e["trans_max_m"] / size})
    return out


def sfm_only(ss, gt, seed: int) -> dict:
    """SfM poses alone (before any ICP), for the photometric-vs-geometric comparison."""
    from capture.registration import colmap, perturb, report

    c = ss.bounds.mean(axis=0)
    pert = perturb.perturb_poses(gt, 5.0, 0.05 * ss.size, c, seed=seed)
    t0 = time.perf_counter()
    try:
        r = colmap.sfm_poses(with_poses(ss, pert))
    except Exception as e:
        return {"method": "sfm-only", "perturb_deg": 5.0, "failed": f"{type(e).__name__}: {e}",
                "seconds": time.perf_counter() - t0}
    idx = [k for k, p in enumerate(r.poses) if p is not None]
    e = report.pose_errors([r.poses[k] for k in idx], [gt[k] for k in idx], c)
    return {"method": "sfm-only", "perturb_deg": 5.0, "seconds": time.perf_counter() - t0, "n_views": len(gt),
            "n_registered": len(idx), "rot_median_deg": e["rot_median_deg"], "rot_max_deg": e["rot_max_deg"],
            "trans_median_frac": e["trans_median_m"] / ss.size, "trans_max_frac": e["trans_max_m"] / ss.size,
            "reprojection_px": r.reprojection_px, "scale_umeyama": r.scale, "scale_depth_ratio": r.depth_ratio_scale}


DATA_SCENES = ("plant", "torus", "furball", "furball-curly", "furball-uniform", "furrybunny")


def true_poses(folder: Path, names: list[str]) -> list:
    """cam_from_world per scan name from ``folder``/gt/cameras_true.json (matched by file stem)."""
    from capture.camera import cam_from_world_of_transform

    path = folder / "gt" / "cameras_true.json"
    frames = json.loads(path.read_text())["frames"]
    by = {Path(f.get("name") or f.get("file_path", "")).stem: f for f in frames}
    missing = [n for n in names if Path(n).stem not in by]
    if missing:
        raise SystemExit(f"{path}: no true pose for {', '.join(missing[:3])}")
    return [cam_from_world_of_transform(by[Path(n).stem]["transform_matrix"]) for n in names]


def run_capture(folder: Path, pose_prior: str | None = None) -> dict:
    """``pipeline.register`` with ``furrow register``'s defaults on a capture with its true poses:
    per view the rotation error in and out (after the rigid fit of all views to the truth)."""
    from capture import io as cio
    from capture.registration import pipeline, report
    from capture.registration.prior import parse_prior

    ss = cio.read_scanset(folder)
    gt = true_poses(folder, [s.name for s in ss.scans])
    inp = [s.camera.cam_from_world for s in ss.scans]
    c = ss.bounds.mean(axis=0)
    t0 = time.perf_counter()
    prior = parse_prior(pose_prior) if pose_prior else None
    _, rep, poses = pipeline.register(ss, "auto", "nominal", rig="auto", pose_prior=prior)
    e, b = report.pose_errors(poses, gt, c, gauge=None), report.pose_errors(inp, gt, c, gauge=None)
    worse = [o - i for o, i in zip(e["rot_deg"], b["rot_deg"])]
    import numpy as np

    same = [bool(np.allclose(p, q, atol=1e-9)) for p, q in zip(poses, inp)]
    moved = [w for w, s in zip(worse, same) if not s]
    # the output is in the input's frame: also scored without the rigid fit (a view kept at its input scores as it)
    d_out = [report.transform_delta(o, g, c)[0] for o, g in zip(poses, gt)]
    d_in = [report.transform_delta(i, g, c)[0] for i, g in zip(inp, gt)]
    names = [s.name for s in rep.scans]
    return {"scene": folder.name, "method": "auto", "rig": rep.rig, "perturb_deg": float("nan"),
            "seconds": time.perf_counter() - t0, "n_views": len(gt), "n_written": len(poses),
            "n_registered": sum(s.status == "registered" for s in rep.scans), "flagged": rep.flagged,
            "kept": rep.kept, "pose_prior": rep.pose_prior, "size_m": ss.size,
            "before_rot_median_deg": b["rot_median_deg"], "before_rot_max_deg": b["rot_max_deg"],
            "rot_median_deg": e["rot_median_deg"], "rot_max_deg": e["rot_max_deg"],
            "trans_median_mm": 1000 * e["trans_median_m"], "trans_max_mm": 1000 * e["trans_max_m"],
            "worse_max_deg": max(worse), "n_unchanged": sum(same),
            "worse_max_moved_deg": max(moved) if moved else None,
            "direct_rot_median_deg": float(np.median(d_out)), "direct_rot_max_deg": max(d_out),
            "direct_before_rot_median_deg": float(np.median(d_in)), "direct_before_rot_max_deg": max(d_in),
            "worse_max_direct_deg": max(o - i for o, i in zip(d_out, d_in)),
            "poses": [np.asarray(p).tolist() for p in poses],
            "status": {n: s.status for n, s in zip(names, rep.scans)},
            "reason": {n: s.reason for n, s in zip(names, rep.scans) if s.status != "registered"},
            "view_rot_deg": dict(zip(names, e["rot_deg"])), "view_rot_in_deg": dict(zip(names, b["rot_deg"])),
            "check": dict(rep.check), "notes": list(rep.notes)}


def _captures(args, rows: list) -> list:
    for d in [Path(x) for x in args.captures.split(",") if x]:
        r = run_capture(d, args.pose_prior)
        rows = [x for x in rows if x.get("scene") != r["scene"] or x.get("method") != "auto"] + [r]
        if not args.json:
            print(f"{r['scene']:28s} written {r['n_written']}/{r['n_views']} (registered {r['n_registered']}, "
                  f"kept {len(r['kept'])}, flagged {len(r['flagged'])})  input med {r['before_rot_median_deg']:.3f} "
                  f"max {r['before_rot_max_deg']:.3f}  output med {r['rot_median_deg']:.3f} max "
                  f"{r['rot_max_deg']:.3f} deg  worst vs input {r['worse_max_deg']:+.3f} (moved views "
                  f"{r['worse_max_moved_deg'] if r['worse_max_moved_deg'] is not None else float('nan'):+.3f}, "
                  f"{r['n_unchanged']} unchanged)  without the rigid fit: input med "
                  f"{r['direct_before_rot_median_deg']:.3f} max {r['direct_before_rot_max_deg']:.3f}, output med "
                  f"{r['direct_rot_median_deg']:.3f} max {r['direct_rot_max_deg']:.3f}, worst vs input "
                  f"{r['worse_max_direct_deg']:+.3f}  {r['seconds']:.0f}s",
                  flush=True)
    return rows


def _args(argv):
    ap = argparse.ArgumentParser(prog="furrow bench register", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", default="plant,torus,furball", help=f"comma list of {SCENES}")
    ap.add_argument("--methods", default="icp", help=f"comma list of {METHODS}")
    ap.add_argument("--rigs", default="free,turntable", help=f"comma list of {RIGS}")
    ap.add_argument("--perturb", default="1,2,5", help="rotation degrees (translation = same number in %% of size)")
    ap.add_argument("--views", type=int, default=36)
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--data", type=Path, default=OUT_ROOT / "data",
                    help="folder of the plant/torus/furball captures (DIR/NAME, written when missing)")
    ap.add_argument("--sensor", choices=["mm", "exact"], default="mm",
                    help="give the captures a consumer sensor's traits (mm) or keep exact depth")
    ap.add_argument("--frames", default=None, help="use these views of the data captures, e.g. 0::2")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--resume", action="store_true", help="keep the rows of an earlier register.json, run the rest")
    ap.add_argument("--sfm", action="store_true", help="also run SfM alone on every scene (5 degrees)")
    ap.add_argument("--captures", default="", help="comma list of capture folders with gt/cameras_true.json: "
                    "register each as given (furrow register's defaults) instead of --scenes")
    ap.add_argument("--pose-prior", default=None, metavar="DEG,FRACTION", help="with --captures: furrow register's "
                    "--pose-prior (default: the rig's)")
    ap.add_argument("-o", "--out", type=Path, default=OUT_ROOT / "bench" / "register")
    ap.add_argument("--json", action="store_true")
    return ap.parse_args(argv)


def _key(r: dict) -> tuple:
    return (r["scene"], r["method"], r.get("rig", "free"), float(r["perturb_deg"]))


def main(argv: list[str] | None = None) -> int:
    args = _args(argv)
    path = args.out / "register.json"
    rows = json.loads(path.read_text()) if args.resume and path.is_file() else []
    done = {_key(r) for r in rows if "failed" not in r}
    degs = [float(x) for x in args.perturb.split(",") if x]
    args.out.mkdir(parents=True, exist_ok=True)
    if args.captures:
        rows = _captures(args, rows)
        write_json(path, rows)
        if args.json:
            print(json.dumps(rows, indent=1))
        return 0
    for scene in [s for s in args.scenes.split(",") if s]:
        if scene not in SCENES:
            raise SystemExit(f"unknown scene {scene!r}; choose from {SCENES}")
        t0 = time.perf_counter()
        if scene in DATA_SCENES and args.width >= 320:
            ss, gt = load_data_scene(scene, args.data, args.views, args.width, args.sensor)
            if args.frames:
                ss = ss.select(args.frames)
                gt = [s.camera.cam_from_world for s in ss.scans]
        else:
            ss, gt = load_scene(scene, args.views, args.width)
        load_s = time.perf_counter() - t0
        for m in [m for m in args.methods.split(",") if m]:
            for rig in [r for r in args.rigs.split(",") if r]:
                for d in degs:
                    if (scene, m, rig, d) in done:
                        continue
                    r = run_one(ss, gt, m, d, args.seed, rig)
                    r.update(scene=scene, rig=rig, load_seconds=load_s, sensor=args.sensor,
                             width=ss.scans[0].camera.width)
                    rows = [x for x in rows if _key(x) != _key(r)] + [r]
                    write_json(path, rows)
                    if not args.json:
                        print(_fmt(r), flush=True)
        if args.sfm:
            r = sfm_only(ss, gt, args.seed)
            r.update(scene=scene)
            rows.append(r)
            if not args.json:
                print(_fmt(r), flush=True)
    write_json(path, rows)
    plot(rows, args.out / "register.png")
    if args.json:
        print(json.dumps(rows, indent=1))
    return 0


def plot(rows: list[dict], path: Path) -> None:
    """Median (solid) and max (dashed) rotation error against the perturbation, per scene, one
    colour per rig; the number of placed views is written at each point."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = [r for r in rows if "rot_median_deg" in r and "rig" in r]
    scenes = sorted({r["scene"] for r in rows})
    if not scenes:
        return
    fig, axes = plt.subplots(1, len(scenes), figsize=(4.2 * len(scenes), 3.6), squeeze=False)
    for ax, sc in zip(axes[0], scenes):
        for rig, col in zip(RIGS, ("tab:blue", "tab:orange")):
            rr = sorted([r for r in rows if r["scene"] == sc and r["rig"] == rig], key=lambda r: r["perturb_deg"])
            if not rr:
                continue
            x = [r["perturb_deg"] for r in rr]
            ax.plot(x, [r["rot_median_deg"] for r in rr], "o-", color=col, label=f"{rig} median")
            ax.plot(x, [r["rot_max_deg"] for r in rr], "s--", color=col, alpha=0.6, label=f"{rig} max")
            for r in rr:
                ax.annotate(f"{r['n_registered']}/{r['n_views']}", (r["perturb_deg"], r["rot_median_deg"]),
                            fontsize=7, color=col, textcoords="offset points", xytext=(3, -9))
        ax.set_yscale("log")
        ax.set_title(sc)
        ax.set_xlabel("perturbation (deg and % of size)")
        ax.set_ylabel("rotation error after registration (deg)")
        ax.grid(True, which="both", alpha=0.3)
    axes[0][0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _fmt(r: dict) -> str:
    head = f"{r['scene']:8s} {r['method']:9s} {r.get('rig', 'free'):9s} {r['perturb_deg']:4.0f}deg"
    if "failed" in r:
        return f"{head}  FAILED ({r['failed']})  {r['seconds']:.1f}s"
    if "rot_median_deg" not in r:
        return f"{head}  registered {r['n_registered']}/{r['n_views']}  {r['seconds']:.1f}s"
    ck = r.get("check") or {}
    counts = (f"reg/kept/flag {ck.get('registered', '-')}/{ck.get('kept at input', '-')}/{ck.get('flagged', '-')}  "
              if ck else "")
    worse = f"worse by <= {r['worse_max_deg']:.3f} deg  " if r.get("worse_max_deg") is not None else ""
    return (f"{head}  input {r['before_rot_median_deg']:.2f} deg  written {r.get('n_written', '-')}/{r['n_views']}  "
            f"{counts}rot med {r['rot_median_deg']:.4f} max {r['rot_max_deg']:.4f} deg  {worse}"
            f"trans med {r['trans_median_mm']:.3f} mm max {r['trans_max_mm']:.3f} mm  {r['seconds']:.0f}s")


if __name__ == "__main__":
    sys.exit(main())

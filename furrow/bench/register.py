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

Errors (``capture.registration.report.pose_errors``): rotation of cam_from_world and
displacement of the object centre in camera coordinates, after aligning the gauge (first scan),
over the registered views; flagged views are counted, not scored.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

from furrow.bench import OUT_ROOT

os.environ.setdefault("OMP_WAIT_POLICY", "passive")


import numpy as np  # noqa: E402

SCENES = ("control", "torus", "plant", "furball", "face", "sfm", "furball-board", "plant-board", "torus-board")
METHODS = ("icp", "icp-geom", "colmap", "board")


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
        cap = synthesize(SynthConfig(scene=name, rig=rig, supersample=2), scene=scene)
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


def run_one(ss, gt, method: str, deg: float, seed: int) -> dict:
    from capture.registration import icp, perturb, pipeline, report

    c = ss.bounds.mean(axis=0)
    size = ss.size
    pert = perturb.perturb_poses(gt, deg, deg / 100 * size, c, seed=seed)
    inp = with_poses(ss, pert)
    t0 = time.perf_counter()
    try:
        if method == "icp":
            _, rep, poses = pipeline.register(inp, "icp", "nominal")
        elif method == "icp-geom":
            _, rep, poses = pipeline.register(inp, "icp", "nominal", icp.IcpConfig(color_scale_frac=0.0))
        elif method == "colmap":
            _, rep, poses = pipeline.register(inp, "colmap", "nominal")
        elif method == "board":
            _, rep, poses = pipeline.register(inp, "board", "nominal", board=ss.metadata.get("board_spec"))
        else:
            raise ValueError(method)
    except Exception as e:  # a method that cannot run on a scene is reported, not hidden
        return {"method": method, "perturb_deg": deg, "failed": f"{type(e).__name__}: {e}",
                "seconds": time.perf_counter() - t0}
    secs = time.perf_counter() - t0
    reg = [s.registered for s in rep.scans]
    idx = [k for k in range(len(gt)) if reg[k]]
    e = report.pose_errors([poses[k] for k in idx], [gt[k] for k in idx], c) if len(idx) > 1 else None
    b = report.pose_errors(pert, gt, c)
    out = {"method": method, "perturb_deg": deg, "perturb_frac": deg / 100, "seconds": secs,
           "n_views": len(gt), "n_registered": len(idx), "flagged": rep.flagged, "size_m": size,
           "before_rot_median_deg": b["rot_median_deg"], "before_trans_median_frac": b["trans_median_m"] / size}
    if e is not None:
        out.update({"rot_median_deg": e["rot_median_deg"], "rot_max_deg": e["rot_max_deg"],
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


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="furrow bench register", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", default="control,torus,plant,furball,face", help=f"comma list of {SCENES}")
    ap.add_argument("--methods", default="icp,icp-geom", help=f"comma list of {METHODS}")
    ap.add_argument("--perturb", default="2,5,10", help="rotation degrees (translation = same number in %% of size)")
    ap.add_argument("--views", type=int, default=12)
    ap.add_argument("--width", type=int, default=160)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--sfm", action="store_true", help="also run SfM alone on every scene (5 degrees)")
    ap.add_argument("-o", "--out", type=Path, default=OUT_ROOT / "bench" / "register")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    rows = []
    degs = [float(x) for x in args.perturb.split(",") if x]
    for scene in [s for s in args.scenes.split(",") if s]:
        if scene not in SCENES:
            raise SystemExit(f"unknown scene {scene!r}; choose from {SCENES}")
        t0 = time.perf_counter()
        ss, gt = load_scene(scene, args.views, args.width)
        load_s = time.perf_counter() - t0
        for m in [m for m in args.methods.split(",") if m]:
            for d in degs:
                r = run_one(ss, gt, m, d, args.seed)
                r.update(scene=scene, load_seconds=load_s)
                rows.append(r)
                if not args.json:
                    print(_fmt(r), flush=True)
        if args.sfm:
            r = sfm_only(ss, gt, args.seed)
            r.update(scene=scene)
            rows.append(r)
            if not args.json:
                print(_fmt(r), flush=True)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "register.json").write_text(json.dumps(rows, indent=1))
    if args.json:
        print(json.dumps(rows, indent=1))
    return 0


def _fmt(r: dict) -> str:
    head = f"{r['scene']:8s} {r['method']:9s} {r['perturb_deg']:4.0f}deg"
    if "failed" in r:
        return f"{head}  FAILED ({r['failed']})  {r['seconds']:.1f}s"
    if "rot_median_deg" not in r:
        return f"{head}  registered {r['n_registered']}/{r['n_views']}  {r['seconds']:.1f}s"
    return (f"{head}  rot med {r['rot_median_deg']:.4f} max {r['rot_max_deg']:.4f} deg   "
            f"trans med {100 * r['trans_median_frac']:.4f} max {100 * r['trans_max_frac']:.4f} %size   "
            f"reg {r['n_registered']}/{r['n_views']}  {r['seconds']:.1f}s")


if __name__ == "__main__":
    sys.exit(main())

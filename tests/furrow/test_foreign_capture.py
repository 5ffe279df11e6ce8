"""A capture from another tool: y-up world, shifted origin, millimetre PNG depth, no furrow bounds block,
an OPENCV camera model with zero distortion.  `furrow eval` must give the same quality as on the same
capture in furrow's own layout: nothing may depend on +z up, the origin, or our metadata."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np

from furrow.cli import main

#: Largest allowed difference of held-out PSNR (dB) between the two layouts of one capture: the grids
#: differ (bounds from depth instead of furrow.bounds), nothing else.
SAME_CAPTURE_DB = 0.75


def foreign_copy(src: Path, dst: Path) -> None:
    import cv2

    (dst / "images").mkdir(parents=True)
    (dst / "depth").mkdir()
    meta = json.loads((src / "transforms.json").read_text())
    T = np.eye(4)
    T[:3, :3] = [[1, 0, 0], [0, 0, 1], [0, -1, 0]]      # z-up -> y-up
    T[:3, 3] = [0.3, 1.2, -0.5]
    frames = []
    for f in meta["frames"]:
        name = Path(f["file_path"]).name
        shutil.copy(src / f["file_path"], dst / "images" / name)
        raw = cv2.imread(str(src / f["depth_file_path"]), cv2.IMREAD_UNCHANGED).astype(np.float64)
        metres = raw * f.get("depth_unit_scale_factor", meta["depth_unit_scale_factor"])
        cv2.imwrite(str(dst / "depth" / name), np.round(metres / 0.001).astype(np.uint16))
        frames.append({"file_path": f"images/{name}", "depth_file_path": f"depth/{name}",
                       "transform_matrix": (T @ np.asarray(f["transform_matrix"])).tolist()})
    g = meta["frames"][0]
    out = {"camera_model": "OPENCV", **{k: g[k] for k in ("fl_x", "fl_y", "cx", "cy", "w", "h")},
           "k1": 0.0, "k2": 0.0, "p1": 0.0, "p2": 0.0, "depth_unit_scale_factor": 0.001, "frames": frames}
    (dst / "transforms.json").write_text(json.dumps(out))


def test_foreign_layout_evaluates_like_our_own(tmp_path):
    scan = tmp_path / "scan"
    assert main(["synth", "furball", "-o", str(scan), "--small", "--views", "12", "--size", "200x150"]) == 0
    foreign_copy(scan, tmp_path / "foreign")
    res = {}
    for name in ("scan", "foreign"):
        js = tmp_path / f"{name}.json"
        out = str(tmp_path / f"{name}_out")
        # only the two methods compared below are drawn
        assert main(["eval", str(tmp_path / name), "--holdout", "2", "--json", str(js), "-o", out,
                     "--methods", "microfacet,mesh-vdtm"]) == 0
        res[name] = json.loads(js.read_text())
    for method in ("microfacet", "mesh_vdtm"):
        a, b = res["scan"][method]["psnr_masked"], res["foreign"][method]["psnr_masked"]
        assert abs(a - b) < SAME_CAPTURE_DB, (method, a, b)
    assert res["foreign"]["microfacet"]["psnr_masked"] > res["foreign"]["mesh_vdtm"]["psnr_masked"]

"""``furrow render`` and ``furrow eval`` end to end on the analytic sphere scene."""

from __future__ import annotations

import json

import numpy as np

from capture.imageio import read_color
from capture.scan import to_uint8_srgb
from furrow.cli import main
from tests import scenes as scene
from tests.conftest import image_diff_stats
from volume.model import save_model


def _transforms(cams, path):
    frames = [{"file_path": f"images/{c.name}", **c.to_nerfstudio()} for c in cams]
    path.write_text(json.dumps({"frames": frames}))
    return path


def test_render_cli_writes_one_png_per_frame(tmp_path):
    cams = scene.ring_cameras(12)
    model = scene.build_model(cams)
    save_model(model, tmp_path / "model")
    tj = _transforms(cams, tmp_path / "transforms.json")
    out = tmp_path / "renders"
    assert main(["render", str(tmp_path / "model"), "--cameras", str(tj), "--frames", "0::4", "-o", str(out)]) == 0
    names = sorted(p.name for p in out.glob("*.png"))
    assert names == ["cam_000.png", "cam_004.png", "cam_008.png"]
    # rendered at the input pose: the input image (8-bit sRGB), black background
    img = read_color(out / "cam_004.png")
    ref = to_uint8_srgb(model.rgbz.rgb[4])
    st = image_diff_stats(img, ref, (model.rgbz.depth[4] > 0) | (img.max(-1) > 0))
    assert st["psnr"] > 45.0, st
    assert img[0, 0].tolist() == [0, 0, 0]
    stats = json.loads((out / "render_stats.json").read_text())
    assert len(stats["frames"]) == 3 and all(f["facets"] > 0 for f in stats["frames"])
    assert stats["method"] == "gather" and stats["supersample"] == 1  # gather draws one sample per pixel
    # baseline and orbit
    assert main(["render", str(tmp_path / "model"), "--cameras", str(tj), "--frames", "2", "--method", "mesh-vdtm",
                 "-o", str(tmp_path / "vdtm")]) == 0
    assert (tmp_path / "vdtm" / "cam_002.png").is_file()
    assert main(["render", str(tmp_path / "model"), "--cameras", str(tj), "--orbit", "3", "-o",
                 str(tmp_path / "orbit")]) == 0
    assert len(list((tmp_path / "orbit").glob("orbit_*.png"))) == 3


def test_render_cli_errors(tmp_path):
    assert main(["render", str(tmp_path / "nope"), "--cameras", str(tmp_path / "t.json"), "-o", str(tmp_path)]) == 1
    cams = scene.ring_cameras(4)
    save_model(scene.build_model(cams), tmp_path / "model")
    tj = _transforms(cams, tmp_path / "transforms.json")
    base = ["render", str(tmp_path / "model"), "--cameras", str(tj), "-o", str(tmp_path / "r")]
    mf = ["--method", "microfacet"]
    assert main(base + mf + ["--supersample", "0"]) == 1
    assert main(base + mf + ["--supersample", "9"]) == 1
    assert main(base + mf + ["--refine", "-1"]) == 1
    assert main(base + ["--supersample", "2"]) == 1  # the default method (gather) draws one sample
    assert main(base + ["--method", "mesh-vdtm", "--refine", "1"]) == 1
    assert not (tmp_path / "r").exists()  # nothing written on bad arguments


def test_eval_summary_means():
    from render.evaluate import summarise

    views = [{"psnr": 20.0, "ssim": 0.5, "psnr_masked": 10.0, "ssim_masked": 0.2, "sharpness": 0.9,
              "hole_fraction": 0.1, "largest_hole": 3, "ms": 10.0, "cpu_ms": 5.0, "facets": 100},
             {"psnr": 30.0, "ssim": 0.7, "psnr_masked": 14.0, "ssim_masked": 0.4, "sharpness": 1.1,
              "hole_fraction": 0.3, "largest_hole": 9, "ms": 30.0, "cpu_ms": 7.0, "facets": 300}]
    s = summarise(views)
    assert s["psnr"] == 25.0 and s["psnr_masked"] == 12.0 and s["ms_per_frame"] == 20.0 and s["cpu_ms_per_frame"] == 6.0
    assert s["largest_hole"] == 9 and np.isclose(s["hole_fraction"], 0.2) and np.isclose(s["sharpness"], 1.0)


def test_eval_cli_on_analytic_scan_set(tmp_path):
    """`furrow eval --geometry gt` end to end: a scan set of the sphere scene with gt/mesh.ply."""
    import open3d as o3d

    from capture.io import write_transforms
    from capture.scan import Scan, ScanSet

    cams = scene.ring_cameras(12)
    scans = []
    for c in cams:
        rgb, depth = scene.render_rgbz(c)
        scans.append(Scan(rgb, depth, c, name=c.name))
    v, f = scene.mesh()
    m = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(v.astype(np.float64)), o3d.utility.Vector3iVector(f))
    ply = tmp_path / "mesh.ply"
    o3d.io.write_triangle_mesh(str(ply), m)
    write_transforms(ScanSet(tuple(scans), scene.BOUNDS), tmp_path / "scans", depth_format="exr",
                     extra_files={"gt/mesh.ply": ply.read_bytes()})
    out_json = tmp_path / "eval.json"
    assert main(["eval", str(tmp_path / "scans"), "--holdout", "2", "--geometry", "gt", "--l-max", "32",
                 "--json", str(out_json), "-o", str(tmp_path / "ev")]) == 0
    res = json.loads(out_json.read_text())
    for key in ("gather", "microfacet", "points", "mesh_vdtm", "mesh_colour"):
        for k in ("psnr", "ssim", "psnr_masked", "ssim_masked", "sharpness", "ms_per_frame"):
            assert np.isfinite(res[key][k]), (key, k)
        assert len(res[key]["views"]) == 6
    assert 0.3 < res["points"]["sharpness"] < 3.0
    assert res["held"] == [1, 3, 5, 7, 9, 11] and res["geometry"] == "gt"
    assert res["supersample"] == 2 and res["options"]["microfacet"]["refine"] is None  # the defaults, recorded
    assert res["options"]["microfacet"]["tolerance_px"] == 8.0 and res["methods"][0] == "gather"
    assert json.loads((tmp_path / "ev" / "eval.json").read_text()) == res
    sheets = sorted((tmp_path / "ev" / "side_by_side").glob("*.png"))
    assert len(sheets) == 6
    # reference | gather | microfacet | points | mesh-vdtm | splat over their error maps
    sheet = read_color(sheets[0])
    assert sheet.shape == (2 * cams[0].height, 6 * cams[0].width, 3)
    # kept views are 60 degrees apart here: only check the renders are far better than nothing
    from render import metrics

    black = []
    for i in res["held"]:
        ref = to_uint8_srgb(scans[i].rgb)
        black.append(metrics.psnr(ref, np.zeros_like(ref), ref.max(-1) > 0))
    assert res["microfacet"]["psnr_masked"] > np.mean(black) + 3.0, (res["microfacet"]["psnr_masked"], black)


def test_render_cli_writes_rgba_and_flattens_over_background(tmp_path):
    """With a matte in the model: RGBA PNG (straight alpha, partial at the fringe); --background
    white writes the same frame flattened over white in linear light; --background and --env clash."""
    import cv2

    from capture.scan import srgb_to_linear
    from render.composite.background import unpack_rgba8

    cams = scene.ring_cameras(12)
    model = scene.build_model(cams)
    model = scene.with_alpha(model, scene.soft_matte(model.rgbz.depth))
    save_model(model, tmp_path / "model")
    tj = _transforms(cams, tmp_path / "transforms.json")
    base = ["render", str(tmp_path / "model"), "--cameras", str(tj), "--frames", "4"]
    assert main(base + ["-o", str(tmp_path / "rgba")]) == 0
    rgba = cv2.imread(str(tmp_path / "rgba" / "cam_004.png"), cv2.IMREAD_UNCHANGED)[..., [2, 1, 0, 3]]
    a = rgba[..., 3]
    assert np.mean((a > 0) & (a < 255)) > 0.02 and (a == 255).any() and (a == 0).any()
    assert main(base + ["--background", "white", "-o", str(tmp_path / "white")]) == 0
    white = read_color(tmp_path / "white" / "cam_004.png")
    pm, al = unpack_rgba8(rgba)
    want = pm + (1 - al[..., None])  # over white, linear
    got = srgb_to_linear(white / 255.0)
    assert np.abs(got - want).max() < 0.02
    assert main(base + ["--background", "white", "--env", "studio", "-o", str(tmp_path / "x")]) == 1
    assert main(base + ["--background", "nowhere", "-o", str(tmp_path / "y")]) == 1

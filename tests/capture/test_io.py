"""Scan-set readers/writers: exact round trips, the half-pixel convention, and validation errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from capture.io import ScanIOError, read_cameras, read_scanset, write_plain_folder, write_transforms
from capture.scan import Scan, ScanSet
from tests.scenes import render_depth, ring_cameras, sphere_scene


def sphere_scanset(n=3, w=40, h=30, radius=0.1, seed=0) -> ScanSet:
    """Analytic sphere seen from a ring of cameras (0.5 m out, 0.1 m up): exact z-depth, random colour."""
    rng = np.random.default_rng(seed)
    elevation = float(np.degrees(np.arctan2(0.1, 0.5)))
    cams = ring_cameras(n, w, h, radius=float(np.hypot(0.5, 0.1)), elevations=(elevation,), focal=50.0,
                        name="images/f{:03d}.png")
    scene = sphere_scene(radius)
    scans = [Scan(rng.integers(0, 256, (h, w, 3), dtype=np.uint8), render_depth(scene, cam), cam, cam.name)
             for cam in cams]
    return ScanSet(tuple(scans), np.array([[-0.2] * 3, [0.2] * 3]), {"scene": "sphere"})


@pytest.mark.parametrize("fmt, tol", [("exr", 0.0), ("png", 0.0005), ("png-0.1mm", 0.00005)])
def test_transforms_round_trip(tmp_path, fmt, tol):
    ss = sphere_scanset()
    write_transforms(ss, tmp_path / "scan", depth_format=fmt)
    back = read_scanset(tmp_path / "scan")
    assert len(back) == len(ss)
    assert np.array_equal(back.bounds, ss.bounds)
    for a, b in zip(ss.scans, back.scans):
        assert np.array_equal(a.rgb, b.rgb)
        assert np.abs(a.depth - b.depth).max() <= tol + 1e-7   # mm PNG quantises to 0.5 mm
        assert np.allclose(a.camera.K, b.camera.K, atol=1e-12)
        assert np.allclose(a.camera.cam_from_world, b.camera.cam_from_world, atol=1e-12)


def test_plain_folder_round_trip(tmp_path):
    ss = sphere_scanset()
    write_plain_folder(ss, tmp_path / "plain")
    back = read_scanset(tmp_path / "plain")
    for a, b in zip(ss.scans, back.scans):
        assert np.array_equal(a.rgb, b.rgb) and np.array_equal(a.depth, b.depth)
        assert np.allclose(a.camera.cam_from_world, b.camera.cam_from_world, atol=1e-12)


def test_half_pixel_convention_on_disk(tmp_path):
    """A centred principal point is (w-1)/2 inside furrow and w/2 in transforms.json."""
    ss = sphere_scanset(n=1, w=40, h=30)
    write_transforms(ss, tmp_path / "s", depth_format="exr")
    meta = json.loads((tmp_path / "s/transforms.json").read_text())
    assert meta["frames"][0]["cx"] == pytest.approx(20.0) and meta["frames"][0]["cy"] == pytest.approx(15.0)
    # A hand-written nerfstudio file with cx = w/2 reads back as the OpenCV centre (w-1)/2,
    # so the sphere's centre projects to the middle of the image both ways.
    cam = read_cameras(tmp_path / "s")[0].camera
    assert cam.K[0, 2] == pytest.approx(19.5) and cam.K[1, 2] == pytest.approx(14.5)
    uv, _ = cam.project(np.zeros((1, 3)))
    assert np.allclose(uv, [[19.5, 14.5]], atol=1e-9)


def test_symmetric_depth_is_centred(tmp_path):
    """The sphere's depth silhouette is symmetric about the image centre only with the right half pixel."""
    ss = sphere_scanset(n=1, w=40, h=30)
    write_transforms(ss, tmp_path / "s", depth_format="exr")
    d = read_scanset(tmp_path / "s").scans[0].depth
    # camera looks at the sphere centre from slightly above: left-right symmetry is exact
    assert np.array_equal(d > 0, (d > 0)[:, ::-1])


def test_refuses_to_overwrite_and_leaves_nothing_on_failure(tmp_path):
    ss = sphere_scanset()
    out = write_transforms(ss, tmp_path / "scan").parent
    with pytest.raises(ScanIOError, match="already exists"):
        write_transforms(ss, out)
    bad = ScanSet((Scan(ss.scans[0].rgb, np.full((30, 40), 100.0, np.float32), ss.scans[0].camera, "x"),), ss.bounds)
    with pytest.raises(ScanIOError, match="does not fit 16-bit"):
        write_transforms(bad, tmp_path / "bad", depth_format="png")
    assert not (tmp_path / "bad").exists()
    assert [p.name for p in tmp_path.iterdir()] == ["scan"]    # no temp folder left behind


# ---------------------------------------------------------------- validation errors
@pytest.fixture
def scan_dir(tmp_path):
    write_transforms(sphere_scanset(), tmp_path / "scan", depth_format="png")
    return tmp_path / "scan"


def _edit(scan_dir, fn):
    p = scan_dir / "transforms.json"
    meta = json.loads(p.read_text())
    fn(meta)
    p.write_text(json.dumps(meta))


def _to_angle_layout(meta, bad_frame=None, bad_angle=None):
    """transforms.json in the NeRF synthetic / instant-ngp layout: camera_angle_x instead of fl_x / fl_y / cx / cy
    (the principal point at the image centre), file paths without their suffix; ``bad_frame`` gets ``bad_angle``."""
    import math

    for i, f in enumerate(meta["frames"]):
        w = f.get("w", meta.get("w"))
        fx = f.pop("fl_x", meta.get("fl_x"))
        for k in ("fl_y", "cx", "cy"):
            f.pop(k, None)
        f["camera_angle_x"] = bad_angle if i == bad_frame else 2 * math.atan(0.5 * w / fx)
        f["file_path"] = "./" + f["file_path"].rsplit(".", 1)[0]
    for k in ("fl_x", "fl_y", "cx", "cy"):
        meta.pop(k, None)


def test_camera_angle_x_layout_reads_the_same_cameras(scan_dir):
    """The camera_angle_x layout (capture.io._intrinsics) gives the explicit intrinsics' focal length, square pixels
    and the image centre, and the same images through suffix-less paths."""
    before = read_scanset(scan_dir)
    _edit(scan_dir, _to_angle_layout)
    after = read_scanset(scan_dir)
    for a, b in zip(before.scans, after.scans, strict=True):
        assert (a.camera.width, a.camera.height) == (b.camera.width, b.camera.height)
        np.testing.assert_allclose(b.camera.K, [[a.camera.K[0, 0], 0, (a.camera.width - 1) / 2],
                                                [0, a.camera.K[0, 0], (a.camera.height - 1) / 2], [0, 0, 1]],
                                   rtol=1e-12, atol=1e-9)
        np.testing.assert_array_equal(a.rgb, b.rgb)


@pytest.mark.parametrize("angle", [0.0, 3.5, "wide"])
def test_a_field_of_view_out_of_range_is_named(scan_dir, angle):
    _edit(scan_dir, lambda meta: _to_angle_layout(meta, 1, angle))
    with pytest.raises(ScanIOError, match=r"frame 1 .*camera_angle_x"):
        read_scanset(scan_dir)


def test_missing_image_named(scan_dir):
    (scan_dir / "images/f001.png").unlink()
    with pytest.raises(ScanIOError, match=r"images/f001.png: colour image not found"):
        read_scanset(scan_dir)


def test_missing_depth_named(scan_dir):
    (scan_dir / "depth/f002.png").unlink()
    with pytest.raises(ScanIOError, match=r"depth/f002.png: depth file not found"):
        read_scanset(scan_dir)


def test_corrupt_png_named(scan_dir):
    (scan_dir / "images/f000.png").write_bytes(b"\x89PNG garbage")
    with pytest.raises(ScanIOError, match=r"f000.png: not a readable image"):
        read_scanset(scan_dir)


@pytest.mark.parametrize("rel, img, msg", [
    ("images/f001.png", np.zeros((10, 10, 3), np.uint8),
     r"f001.png: image is 10x10 but its camera \(.*transforms\.json frame 1\) says 40x30"),
    ("depth/f001.png", np.ones((30, 41), np.uint16), r"depth/f001.png: depth is 41x30"),
    ("depth/f000.png", np.zeros((30, 40), np.uint16), r"depth/f000.png: depth is all zero"),
    ("images/f002.png", np.zeros((30, 40, 3), np.uint8),
     r"images/f002.png: colour image is blank \(every pixel 0 to 0\)"),
    ("images/f001.png", np.full((30, 40, 3), 200, np.uint8) + (np.arange(40) % 2).astype(np.uint8)[None, :, None],
     r"images/f001.png: colour image is blank \(every pixel 200 to 201\)"),
], ids=["size_mismatch", "depth_size_mismatch", "all_zero_depth", "black_frame", "one_colour_frame"])
def test_bad_image_named(scan_dir, rel, img, msg):
    import cv2
    cv2.imwrite(str(scan_dir / rel), img)
    with pytest.raises(ScanIOError, match=msg):
        read_scanset(scan_dir)


def test_a_dim_frame_is_not_blank(scan_dir):
    """A frame spanning two 8-bit levels more than capture.sources.BLANK_LEVELS (a dark, flat view) is read."""
    import cv2

    from capture.sources import BLANK_LEVELS
    img = np.full((30, 40, 3), 3, np.uint8) + (np.arange(40) % (BLANK_LEVELS + 2)).astype(np.uint8)[None, :, None]
    cv2.imwrite(str(scan_dir / "images/f001.png"), img)
    assert np.array_equal(read_scanset(scan_dir).scans[1].rgb, img)


def test_nonfinite_pose_named(scan_dir):
    _edit(scan_dir, lambda m: m["frames"][1]["transform_matrix"][0].__setitem__(3, float("nan")))
    with pytest.raises(ScanIOError, match=r"frame 1 \(images/f001.png\).*NaN"):
        read_scanset(scan_dir)


def test_nonrigid_pose_named(scan_dir):
    def scale(m):
        tm = np.asarray(m["frames"][2]["transform_matrix"])
        tm[:3, :3] *= 1.1
        m["frames"][2]["transform_matrix"] = tm.tolist()
    _edit(scan_dir, scale)
    with pytest.raises(ScanIOError, match=r"frame 2 \(images/f002.png\).*not rigid"):
        read_scanset(scan_dir)


def test_unknown_units_named(scan_dir):
    def drop(m):  # the writer puts the unit at the top level only (nerfstudio-style)
        m.pop("depth_unit_scale_factor")
        assert not any("depth_unit_scale_factor" in f for f in m["frames"])
    _edit(scan_dir, drop)
    with pytest.raises(ScanIOError,
                       match=r"f000.png: integer depth image but no depth_unit_scale_factor in "
                             r"\S*transforms.json: unknown units"):
        read_scanset(scan_dir)


def test_bad_unit_value_named(scan_dir):
    _edit(scan_dir, lambda m: m["frames"][0].__setitem__("depth_unit_scale_factor", -1))
    with pytest.raises(ScanIOError, match=r"frame 0.*depth_unit_scale_factor must be a positive"):
        read_scanset(scan_dir)


def test_distortion_rejected(scan_dir):
    _edit(scan_dir, lambda m: m.__setitem__("k1", 0.1))
    with pytest.raises(ScanIOError, match="distortion"):
        read_scanset(scan_dir)


def test_exr_depth_without_factor_is_metres(tmp_path):
    ss = sphere_scanset(n=2)
    write_transforms(ss, tmp_path / "s", depth_format="exr")
    _edit(tmp_path / "s", lambda m: m.pop("depth_unit_scale_factor"))
    back = read_scanset(tmp_path / "s")
    assert np.array_equal(back.scans[0].depth, ss.scans[0].depth)


def test_nan_inf_depth_becomes_no_data(tmp_path):
    ss = sphere_scanset(n=1)
    s = ss.scans[0]
    d = s.depth.copy()
    d[0, :5] = np.nan
    d[1, :5] = np.inf
    d[2, :5] = -1
    scan = Scan(s.rgb, d, s.camera, s.name)
    assert np.all(scan.depth[:3, :5] == 0)


def test_frames_spec_and_auto_bounds(scan_dir):
    def drop_bounds(m):
        m.pop("furrow")
    _edit(scan_dir, drop_bounds)
    ss = read_scanset(scan_dir, frames="0::2")
    assert [s.name for s in ss.scans] == ["images/f000.png", "images/f002.png"]
    # auto bounds contain the radius-0.1 sphere's visible points, with a margin
    assert np.all(ss.bounds[0] < -0.05) and np.all(ss.bounds[1] > 0.05) and np.all(np.abs(ss.bounds) < 0.2)


def test_not_a_scanset(tmp_path):
    with pytest.raises(ScanIOError, match="neither"):
        read_scanset(tmp_path)
    (tmp_path / "transforms.json").write_text("{not json")
    with pytest.raises(ScanIOError, match="invalid JSON"):
        read_scanset(tmp_path)

"""Lens distortion read, not refused: models, undistortion against OpenCV, depth across edges."""

from __future__ import annotations

import json

import numpy as np
import pytest

from capture.camera import Camera, make_K
from capture.imageio import ScanIOError
from capture.io import read_cameras, read_scanset, write_transforms
from capture.lens import (
    FISHEYE,
    PERSPECTIVE,
    Lens,
    LensError,
    colmap_lens,
    distort_pixels,
    remap_depth,
    undistort_maps,
    undistort_pixels,
    undistorted_camera,
)
from capture.scan import Scan, ScanSet, linear_to_srgb

#: The issue's OPENCV coefficients (k1 k2 p1 p2) and a fisheye set.
OPENCV = Lens(PERSPECTIVE, (-0.12, 0.03, 8e-4, -5e-4), "OPENCV")
FISH = Lens(FISHEYE, (0.03, -0.01, 0.002, -0.0005), "OPENCV_FISHEYE")
W, H = 160, 120
K = make_K(150.0, 152.0, 81.3, 58.6)
#: Agreement with OpenCV's own point undistortion (pixels): the issue's figure.
TOL_PX = 0.01


@pytest.mark.parametrize("lens", [OPENCV, FISH], ids=["opencv", "fisheye"])
@pytest.mark.parametrize("mode", ["keep", "crop", "full"])
def test_maps_agree_with_cv2_undistort_points(lens, mode):
    import cv2

    K_new, w, h = undistorted_camera(K, lens, W, H, mode)
    mx, my = undistort_maps(K, lens, K_new, w, h)
    src = np.stack([mx.ravel(), my.ravel()], axis=1).astype(np.float64)
    inside = (src[:, 0] >= 0) & (src[:, 0] <= W - 1) & (src[:, 1] >= 0) & (src[:, 1] <= H - 1)
    if mode == "crop":
        assert inside.mean() > 0.999   # nerfstudio's choice: (nearly) every output pixel sees the scene
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
    pts = src[inside].reshape(-1, 1, 2)
    if lens.fisheye:
        back = cv2.fisheye.undistortPoints(pts, K, lens.dist, P=K_new, criteria=crit).reshape(-1, 2)
    else:
        back = cv2.undistortPoints(pts, K, lens.dist, R=None, P=K_new, criteria=crit).reshape(-1, 2)
    grid = np.stack(np.meshgrid(np.arange(w), np.arange(h)), axis=-1).reshape(-1, 2)[inside]
    assert np.abs(back - grid).max() < TOL_PX


@pytest.mark.parametrize("lens", [OPENCV, FISH], ids=["opencv", "fisheye"])
def test_forward_model_inverts_cv2(lens):
    rng = np.random.default_rng(0)
    uv = rng.uniform([0, 0], [W - 1, H - 1], (500, 2))
    d = distort_pixels(uv, K, lens)
    assert np.abs(undistort_pixels(d, K, lens) - uv).max() < TOL_PX
    assert np.abs(d - uv).max() > 1.0   # the lens really moves pixels


def test_depth_never_averaged_across_an_edge():
    rng = np.random.default_rng(1)
    depth = np.where(rng.random((40, 50)) < 0.5, 1.0, 2.5).astype(np.float32)
    depth[rng.random((40, 50)) < 0.1] = 0.0
    my, mx = np.mgrid[0:40, 0:50].astype(np.float32)
    mx = mx + rng.uniform(-0.7, 0.7, mx.shape).astype(np.float32)
    my = my + rng.uniform(-0.7, 0.7, my.shape).astype(np.float32)
    out = remap_depth(depth, mx, my)
    assert set(np.unique(out).tolist()) <= {0.0, 1.0, 2.5}
    # on a smooth ramp the four samples agree: bilinear, exact for a linear field
    ramp = (1.0 + 0.001 * np.arange(50, dtype=np.float32))[None].repeat(40, 0)
    inner = (mx > 0) & (mx < 49) & (my > 0) & (my < 39)
    assert np.abs(remap_depth(ramp, mx, my) - (1.0 + 0.001 * mx))[inner].max() < 1e-5


def _smooth(x, y):
    """A smooth linear colour of normalised image coordinates."""
    return np.stack([0.4 + 0.3 * np.sin(3 * x), 0.4 + 0.3 * np.cos(2 * y), 0.5 + 0.2 * x * y], axis=-1)


def _distorted_capture(lens, edge_x=0.05):
    """One view of two fronto-parallel planes (z = 1 m left of x/z = edge_x, 2 m right of it)
    carrying a smooth colour, seen through ``lens``."""
    cam = Camera(K, np.eye(4), W, H, name="images/f000.png")
    g = np.stack(np.meshgrid(np.arange(W), np.arange(H)), axis=-1).reshape(-1, 2).astype(np.float64)
    und = undistort_pixels(g, K, lens)
    x = ((und[:, 0] - K[0, 2]) / K[0, 0]).reshape(H, W)
    y = ((und[:, 1] - K[1, 2]) / K[1, 1]).reshape(H, W)
    rgb = np.round(linear_to_srgb(_smooth(x, y)) * 255).astype(np.uint8)
    depth = np.where(x < edge_x, 1.0, 2.0).astype(np.float32)
    return ScanSet((Scan(rgb, depth, cam, cam.name),), np.array([[-2.0, -2, 0.5], [2, 2, 2.5]]), {})


@pytest.mark.parametrize("lens", [OPENCV, FISH], ids=["opencv", "fisheye"])
def test_capture_read_undistorted(tmp_path, lens):
    write_transforms(_distorted_capture(lens), tmp_path / "scan", depth_format="exr", lens=lens)
    meta = json.loads((tmp_path / "scan/transforms.json").read_text())
    assert meta["camera_model"] == lens.source and meta["k1"] == lens.coeffs[0]
    ss = read_scanset(tmp_path / "scan")
    s = ss.scans[0]
    K_new, w, h = undistorted_camera(K, lens, W, H)
    assert np.allclose(s.camera.K, K_new) and (s.camera.width, s.camera.height) == (w, h)
    assert ss.metadata["undistorted"]["models"] == [lens.source]
    x, y = np.meshgrid((np.arange(w) - K_new[0, 2]) / K_new[0, 0], (np.arange(h) - K_new[1, 2]) / K_new[1, 1])
    # the default keeps K: pixels whose ray the lens did not image (barrel corners) are empty, the rest measured
    mx, my = undistort_maps(K, lens, K_new, w, h)
    seen = (mx >= 0.5) & (mx <= W - 1.5) & (my >= 0.5) & (my <= H - 1.5)
    assert seen.mean() > 0.95 and (s.depth[seen] > 0).all()
    assert (s.depth[(mx < -0.5) | (mx > W - 0.5) | (my < -0.5) | (my > H - 0.5)] == 0).all()
    inner = seen[2:-2, 2:-2]
    err = np.abs(s.linear_rgb - _smooth(x, y))[2:-2, 2:-2][inner]
    assert np.median(err) < 0.005 and err.max() < 0.03
    d = s.depth[1:-1, 1:-1]
    assert set(np.unique(d[d > 0]).tolist()) <= {1.0, 2.0}                # nothing averaged across the edge
    xs = x[1:-1, 1:-1]
    far = (np.abs(xs - 0.05) > 1.5 / K_new[0, 0]) & (d > 0)
    assert np.array_equal((d == 1.0)[far], (xs < 0.05)[far])              # and the edge where it belongs
    assert read_cameras(tmp_path / "scan")[0].camera.width == w           # cameras alone: the same pinhole


def test_keep_is_cv2_undistort_with_the_same_camera_matrix():
    """The default resamples once to the captured K and size: what ``cv2.undistort(img, K, D)`` gives (an
    independent reference: OpenCV's own one-call undistortion), to float32 rounding."""
    import cv2

    from capture.lens import undistort_scan

    rng = np.random.default_rng(2)
    img = cv2.GaussianBlur(rng.random((H, W, 3)).astype(np.float32), (0, 0), 2.0)
    cam = Camera(K, np.eye(4), W, H)
    K_new, w, h = undistorted_camera(K, OPENCV, W, H, "keep")
    assert np.array_equal(K_new, K) and (w, h) == (W, H)
    out = undistort_scan(Scan(img, np.ones((H, W), np.float32), cam), OPENCV, K, cam).rgb
    ref = cv2.undistort(img, K, OPENCV.dist)
    assert np.abs(out - ref)[4:-4, 4:-4].max() < 2e-3
    assert np.abs(out - img).max() > 0.05   # the lens does move pixels


def test_full_keeps_every_source_pixel(tmp_path):
    write_transforms(_distorted_capture(OPENCV), tmp_path / "scan", depth_format="exr", lens=OPENCV)
    s = read_scanset(tmp_path / "scan", undistort="full").scans[0]
    assert (s.camera.width, s.camera.height) == (W, H)
    assert (s.depth == 0).any() and (s.depth > 0).mean() > 0.9          # black corners, no made-up depth


def test_per_frame_override_and_unsupported(tmp_path):
    write_transforms(_distorted_capture(OPENCV), tmp_path / "scan", depth_format="exr", lens=OPENCV)
    tj = tmp_path / "scan/transforms.json"
    meta = json.loads(tj.read_text())
    meta["frames"][0].update(camera_model="OPENCV_FISHEYE", k1=0.03, k2=-0.01, k3=0.002, k4=-0.0005, p1=0, p2=0)
    tj.write_text(json.dumps(meta))
    fc = read_cameras(tj)[0]
    assert fc.lens.model == FISHEYE and fc.lens.coeffs == FISH.coeffs
    meta["camera_model"] = meta["frames"][0]["camera_model"] = "EQUIRECTANGULAR"
    tj.write_text(json.dumps(meta))
    with pytest.raises(ScanIOError, match=r"EQUIRECTANGULAR.*not supported; supported: PINHOLE, SIMPLE_PINHOLE, "
                                          r"OPENCV, OPENCV_FISHEYE") as e:
        read_scanset(tj)
    assert "\n" not in str(e.value) and str(tj) in str(e.value)


def test_colmap_models_parsed():
    assert colmap_lens("PINHOLE", ()) is None and colmap_lens("OPENCV", (0, 0, 0, 0)) is None
    assert colmap_lens("SIMPLE_RADIAL", (0.1,)).coeffs == (0.1, 0, 0, 0, 0, 0, 0, 0)
    assert colmap_lens("RADIAL", (0.1, -0.02)).coeffs == (0.1, -0.02, 0, 0, 0, 0, 0, 0)
    assert colmap_lens("OPENCV", (0.1, -0.02, 1e-3, 2e-3)).coeffs == (0.1, -0.02, 1e-3, 2e-3, 0, 0, 0, 0)
    full = colmap_lens("FULL_OPENCV", (0.1, -0.02, 1e-3, 2e-3, 0.01, 0.02, 0.03, 0.04))
    assert full.model == PERSPECTIVE and full.coeffs == (0.1, -0.02, 1e-3, 2e-3, 0.01, 0.02, 0.03, 0.04)
    fish = colmap_lens("OPENCV_FISHEYE", (0.03, -0.01, 0.002, -0.0005))
    assert fish.model == FISHEYE and fish.source == "OPENCV_FISHEYE"
    with pytest.raises(LensError, match="THIN_PRISM_FISHEYE is not supported; supported: SIMPLE_PINHOLE"):
        colmap_lens("THIN_PRISM_FISHEYE", (0,) * 12)
    with pytest.raises(LensError, match="needs 4 distortion parameters"):
        colmap_lens("OPENCV", (0.1,))


def test_colmap_reader_undistorts(tmp_path):
    """A COLMAP OPENCV camera is undistorted at read time like the transforms.json one."""
    pycolmap = pytest.importorskip("pycolmap")
    from capture.io import write_plain_folder
    from capture.io_colmap import read_colmap

    ss = _distorted_capture(OPENCV)
    write_plain_folder(ss, tmp_path / "plain", depth_format="exr")
    rec = pycolmap.Reconstruction()
    try:
        cam = pycolmap.Camera.create_from_model_name(1, "OPENCV", 150.0, W, H)
        cam.params = [K[0, 0], K[1, 1], K[0, 2] + 0.5, K[1, 2] + 0.5, *OPENCV.coeffs[:4]]
        rec.add_camera_with_trivial_rig(cam)
        im = pycolmap.Image(name="f000.png", camera_id=1, image_id=1)
        rec.add_image_with_trivial_frame(im, pycolmap.Rigid3d(pycolmap.Rotation3d(np.eye(3)), np.zeros(3)))
    except (AttributeError, TypeError) as e:   # pragma: no cover - pycolmap API drift
        pytest.skip(f"pycolmap API for building models differs: {e}")
    (tmp_path / "sparse").mkdir()
    rec.write(str(tmp_path / "sparse"))
    back = read_colmap(tmp_path / "sparse", tmp_path / "plain/rgb", tmp_path / "plain/depth")
    K_new, w, h = undistorted_camera(K, OPENCV, W, H)
    assert np.allclose(back.scans[0].camera.K, K_new) and back.metadata["undistorted"]["models"] == ["OPENCV"]
    assert set(np.unique(back.scans[0].depth[1:-1, 1:-1]).tolist()) <= {1.0, 2.0}

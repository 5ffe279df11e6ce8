"""View and resolution choice (volume.views): near-duplicate views dropped with their reason,
N most spread-out views, the working scale from the object's footprint against the output size."""

from __future__ import annotations

import numpy as np
import pytest

from capture.camera import Camera, look_at, make_K, misread_poses
from capture.scan import Scan
from volume.views import (
    AUTO_MIN_ANGLE_DEG,
    COLLAPSE_MIN_VIEWS,
    footprint_px,
    object_centre,
    scaled_scan,
    select_views,
    working_scale,
)


def _ring(angles_deg, radius=0.5, w=64, h=48):
    K = make_K(60.0, 60.0, (w - 1) / 2, (h - 1) / 2)
    out = []
    for i, a in enumerate(np.radians(angles_deg)):
        eye = [radius * np.cos(a), radius * np.sin(a), 0.1]
        out.append(Camera(K, look_at(eye, [0.0, 0.0, 0.0]), w, h, f"c{i}"))
    return out


def test_object_centre_is_where_the_ring_looks():
    np.testing.assert_allclose(object_centre(_ring(np.arange(0, 360, 30))), 0.0, atol=1e-9)


def test_cameras_at_one_place_looking_one_way_are_all_kept_and_said():
    """A ring whose poses were inverted (world-to-camera where camera-to-world belong): every camera stands at one
    point looking one way, so --views auto would keep one; it keeps all, each view's reason says why (the
    depth-agreement stage then names the inversion); a capture of two such views is left alone."""
    ring = _ring(np.arange(0, 360, 30))
    inv = [Camera(c.K, c.world_from_cam, c.width, c.height) for c in ring]  # read: world_from_cam = cam_from_world
    for c, x in zip(ring, inv):
        np.testing.assert_allclose(misread_poses(x.world_from_cam)["inverse"], c.world_from_cam, atol=1e-12)
    centres = np.array([c.center for c in inv])
    assert np.ptp(centres, axis=0).max() < 1e-9  # the collapse this guards against
    kept, reasons = select_views(inv, "auto")
    assert kept == list(range(12)) and all(r["collapsed"] for r in reasons)
    assert "are the poses camera-to-world?" in reasons[0]["reason"]
    assert select_views(inv[:2], "auto")[0] == [0] and COLLAPSE_MIN_VIEWS == 3
    assert select_views(inv, "3")[0] != list(range(12))  # an asked number is a number


def test_auto_drops_near_duplicates_only():
    angles = [0, 0.5, 30, 60, 61, 90, 120]  # 0.5 and 61 repeat a neighbour within 2 deg
    kept, reasons = select_views(_ring(angles), "auto", centre=np.zeros(3))
    assert kept == [0, 2, 3, 5, 6]
    assert "near-duplicate of view 0" in reasons[1]["reason"] and not reasons[1]["kept"]
    assert "near-duplicate of view 3" in reasons[4]["reason"]
    assert all(r["kept"] for r in reasons if r["view"] in kept)
    assert reasons[1]["angle_to_nearest_kept_deg"] < AUTO_MIN_ANGLE_DEG
    # a duplicate direction at another distance adds scale: kept
    cams = _ring([0, 30]) + _ring([0.5], radius=1.0)
    assert select_views(cams, "auto", centre=np.zeros(3))[0] == [0, 1, 2]


def test_n_views_spread_and_all():
    cams = _ring(np.arange(0, 360, 10))
    kept, _ = select_views(cams, "4", centre=np.zeros(3))
    assert len(kept) == 4
    ang = sorted(np.arange(0, 360, 10)[kept])
    assert min(np.diff(ang + [ang[0] + 360])) >= 80  # spread round the ring
    assert select_views(cams, "all")[0] == list(range(36))
    with pytest.raises(ValueError, match="--views"):
        select_views(cams, "many")


def test_working_scale():
    assert working_scale([400, 420, 380], None)[0] == 1.0
    s, rep = working_scale([400, 420, 380], (320, 240))  # needs 0.9 * 240 = 216 px of 400
    assert s == 0.625 and "scaled by 0.625" in rep["reason"]
    assert working_scale([100], (1280, 960))[0] == 1.0  # never up


def test_scaled_scan_keeps_measured_depth_and_pixel_centres():
    cam = _ring([0], w=64, h=48)[0]
    depth = np.zeros((48, 64), np.float32)
    depth[10:30, 20:40] = np.linspace(0.4, 0.5, 20)[None, :]
    rgb = np.full((48, 64, 3), 128, np.uint8)
    sc = scaled_scan(Scan(rgb, depth, cam), 0.5)
    assert (sc.camera.width, sc.camera.height) == (32, 24) and sc.rgb.shape == (24, 32, 3)
    assert set(np.unique(sc.depth[sc.depth > 0])) <= set(np.unique(depth[depth > 0]))  # no blended depth
    assert footprint_px(sc.depth) == 10 and footprint_px(depth) == 20
    # a world point projects to the same place in both, up to the scale
    p = cam.unproject(np.array([25.0, 15.0]), np.array(0.45))
    uv, _ = cam.project(p)
    uv2, _ = sc.camera.project(p)
    np.testing.assert_allclose((uv2 + 0.5) * 2, uv + 0.5, atol=1e-9)

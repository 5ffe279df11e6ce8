"""capture.depth_agreement: the views' depths against their poses, on seeded scenes with exact depth."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from capture.camera import invert_rigid, make_K, misread_poses
from capture.depth_agreement import (
    MAX_PAIR_ANGLE,
    AgreementConfig,
    _reprojected,
    agreement,
    convention_check,
    focal_check,
    focal_factors,
    intrinsics_check,
    neighbours,
    pair_hits,
    scales,
    units_check,
    verdict,
    view_sample,
)
from tests.scenes import Scene, make_scanset, ring_cameras, scan_ring, spheres_scene

CFG = AgreementConfig()


@pytest.fixture(scope="module")
def ring():
    return make_scanset(spheres_scene(), scan_ring(12, 96, 72), noise=0.0005)


def _check(scans, cfg=CFG):
    samples = [view_sample(s.depth, s.camera, cfg.points, i) for i, s in enumerate(scans)]
    s, share, share_all, per_view, _ = agreement(samples, [x.camera for x in scans], cfg)
    return verdict(s, share, share_all), s, share_all


def _with_depth(scans, f):
    return [replace(x, depth=f(i, x.depth).astype(np.float32)) for i, x in enumerate(scans)]


def test_right_depth_agrees_at_scale_one(ring):
    rec, s, share = _check(ring.scans)
    assert rec["status"] == "agree", rec
    assert abs(np.log(rec["best_scale"])) <= np.log(1.01), rec
    assert rec["share"] > 0.4
    assert 1.0 in scales() and share[np.argmin(np.abs(np.log(s)))] >= 0.9 * max(share)


@pytest.mark.parametrize("factor", [2.0, 0.4])
def test_depth_in_another_unit_agrees_best_at_its_inverse(ring, factor):
    """Depth x factor (a wrong depth unit, or poses at 1 / factor of their scale): the check names the
    scale that undoes it, to a grid step, and the share there is the right capture's."""
    rec, _, _ = _check(_with_depth(ring.scans, lambda i, z: z * factor))
    assert rec["status"] == "scale", rec
    assert abs(np.log(rec["best_scale"] * factor)) <= np.log(1.01), rec
    right, _, _ = _check(ring.scans)
    assert rec["best_share"] == pytest.approx(right["share"], abs=0.05) and rec["share"] < right["share"] / 2
    assert "depth_unit_scale_factor" in rec["message"]


def test_intrinsics_of_another_frame_agree_nowhere(ring):
    """The principal point at the corner (a frame of another convention): no scale agrees."""
    scans = [replace(x, camera=replace(x.camera, K=make_K(x.camera.K[0, 0], x.camera.K[1, 1], 0.0, 0.0)))
             for x in ring.scans]
    rec, _, share = _check(scans)
    assert rec["status"] == "none" and max(share) < 0.05, rec


def _table_scene(height=-0.06, radius=0.6):
    """The five spheres on a round table top (z = ``height``) of ``radius``: ray cast in closed form."""
    sp = spheres_scene()

    def ray(o, d):
        down = d[:, 2] < -1e-9
        t = np.where(down, (height - o[:, 2]) / np.where(down, d[:, 2], -1.0), np.inf)
        t = np.where(t > 0, t, np.inf)
        p = o + np.where(np.isfinite(t), t, 0.0)[:, None] * d
        return np.minimum(sp.raycast(o, d), np.where(np.hypot(p[:, 0], p[:, 1]) < radius, t, np.inf))
    return Scene("table", sp.sdf, ray, sp.bounds)


def test_a_table_top_is_scale_blind_and_left_out():
    """A table seen by a ring of cameras at one height agrees at every depth scale (each camera's scaled plane
    is one plane): its points are found scale-blind and left out of the scale search, which still finds 1 on
    the right capture and the undoing scale on the half-scale one."""
    cams = ring_cameras(6, 96, 72, elevations=(25.0,), fov_deg=40.0)
    ss = make_scanset(_table_scene(), cams, noise=0.0005)
    samples = [view_sample(x.depth, x.camera, CFG.points, i) for i, x in enumerate(ss.scans)]
    s, share, share_all, _, blind = agreement(samples, cams, CFG)
    rec = verdict(s, share, share_all)
    assert rec["status"] == "agree" and abs(np.log(rec["best_scale"])) <= np.log(1.01), rec
    assert blind > 0.5  # most of the frame is table
    half = [view_sample(0.5 * x.depth, x.camera, CFG.points, i) for i, x in enumerate(ss.scans)]
    rec = verdict(*agreement(half, cams, CFG)[:3])
    assert rec["status"] == "scale" and abs(np.log(rec["best_scale"] / 2.0)) <= np.log(1.01), rec


def _pair_reference(points, cam_i, cam_j, depth_small, step, s, rel):
    """pair_hits point by point and scale by scale (the reference): (agreeing, landed), each (S, m)."""
    ok, on = np.zeros((len(s), len(points)), bool), np.zeros((len(s), len(points)), bool)
    for a, sc in enumerate(s):
        for b, p in enumerate(points):
            w = cam_i.world_from_cam[:3, :3] @ (sc * p) + cam_i.world_from_cam[:3, 3]
            q = cam_j.world_from_cam[:3, :3].T @ (w - cam_j.world_from_cam[:3, 3])
            if q[2] <= 1e-9:
                continue
            uvw = cam_j.K @ q
            u, v = uvw[0] / uvw[2], uvw[1] / uvw[2]
            r, c = int(np.rint(v / step)), int(np.rint(u / step))
            if 0 <= r < depth_small.shape[0] and 0 <= c < depth_small.shape[1]:
                zj = sc * float(depth_small[r, c])
                ok[a, b] = zj > 0 and abs(q[2] - zj) <= rel * zj
                on[a, b] = zj > 0
    return ok, on


def test_pair_hits_equal_the_point_by_point_reference(ring):
    a, b = ring.scans[0], ring.scans[1]
    pts, _, _ = view_sample(a.depth, a.camera, 300, 0)
    _, small, step = view_sample(b.depth, b.camera, 10, 1)
    s = scales()[::7]
    ok, on = pair_hits(pts, a.camera, b.camera, small, step, s, 0.01)
    ref_ok, ref_on = _pair_reference(pts, a.camera, b.camera, small, step, s, 0.01)
    np.testing.assert_array_equal(ok, ref_ok)
    np.testing.assert_array_equal(on, ref_on)
    assert ok.sum(1).max() > 50 and (on | ~ok).all() and on.sum() > ok.sum()


def test_views_of_opposite_sides_are_not_compared(ring):
    """Views further apart than MAX_PAIR_ANGLE have no neighbour (-1): 2 of the 12 ring views 180 degrees
    apart are not compared (they share too little of the object: a fur ball's two opposite views had agreed best
    at the scale 1.26 by chance), 4 of them 90 degrees apart neither, every 3rd of them (120) neither; the
    whole ring (30 degrees) has both neighbours."""
    assert MAX_PAIR_ANGLE < 90
    cams = [x.camera for x in ring.scans]
    for step in (6, 3, 4):
        assert (neighbours(cams[::step], 2) == -1).all(), step
    nb = neighbours(cams, 2)
    assert (nb >= 0).all() and sorted(nb[0]) == [1, 11]
    samples = [view_sample(x.depth, x.camera, 100, i) for i, x in enumerate(ring.scans[::6])]
    _, share, share_all, per_view, _ = agreement(samples, cams[::6], CFG)
    assert not share.any() and not share_all.any() and np.isnan(per_view).all()


def _focal_times(scans, k):
    """The scans with every camera's fl_x and fl_y times ``k`` (principal point kept), the depth as measured."""
    def cam(c):
        return replace(c, K=make_K(c.K[0, 0] * k, c.K[1, 1] * k, c.K[0, 2], c.K[1, 2]))
    return [replace(x, camera=cam(x.camera)) for x in scans]


def _focal(scans):
    samples = [view_sample(s.depth, s.camera, CFG.points, i) for i, s in enumerate(scans)]
    return focal_check(samples, [x.camera for x in scans], CFG)


@pytest.mark.parametrize("k", [0.8, 1.25, 1.5])
def test_a_focal_length_off_is_named_with_the_factor_that_undoes_it(ring, k):
    """Focal lengths k times the ones the depth was measured with (intrinsics of another image size): the check
    says ``focal`` with the factor 1 / k (to 2 %), nearly every view pair agreeing more there, the depth at its own
    scale; a scale search alone would have read it as a depth scale or as nothing."""
    rec = _focal(_focal_times(ring.scans, k))
    assert rec["status"] == "focal", rec
    assert abs(np.log(rec["focal_factor"] * k)) <= np.log(1.02), rec
    assert rec["pairs_better"] >= 0.9 * (rec["pairs_better"] + rec["pairs_worse"])
    assert abs(np.log(rec["depth_scale_at_focal"])) <= np.log(1.011)
    assert rec["focal_share"] > 1.2 * rec["share_as_given"] and "fl_x" in rec["message"]


def test_right_intrinsics_and_a_depth_scale_are_not_a_focal_length(ring):
    """The right capture keeps its focal lengths (best factor 1); depth in another unit (x 2) is not taken for
    a focal length: no factor makes it agree at the depth's own scale."""
    rec = _focal(ring.scans)
    assert rec["status"] == "as given" and rec["focal_factor"] == 1.0, rec
    assert 1.0 in focal_factors()
    rec = _focal(_with_depth(ring.scans, lambda i, z: z * 2.0))
    assert rec["status"] == "as given", rec


def test_pair_hits_with_a_focal_factor_equal_the_point_by_point_reference(ring):
    """pair_hits(..., focal=f) is the point-by-point reference with both cameras' fl_x, fl_y times f and view
    i's points back-projected through them (x and y over f)."""
    a, b = ring.scans[0], ring.scans[1]
    pts, _, _ = view_sample(a.depth, a.camera, 200, 0)
    _, small, step = view_sample(b.depth, b.camera, 10, 1)
    f = np.array([0.8, 1.0, 1.3])
    s = np.array([1.0, 1.0, 1.1])
    ok, on = pair_hits(pts, a.camera, b.camera, small, step, s, 0.01, f)
    for g, (fg, sg) in enumerate(zip(f, s)):
        ca, cb = (_focal_times([x], fg)[0].camera for x in (a, b))
        ref_ok, ref_on = _pair_reference(pts * [1 / fg, 1 / fg, 1.0], ca, cb, small, step, [sg], 0.01)
        np.testing.assert_array_equal(ok[g], ref_ok[0])
        np.testing.assert_array_equal(on[g], ref_on[0])
    assert ok[1].sum() > 50 and ok[0].sum() < ok[1].sum()


def _misread(scans, name):
    """The scans as a reader would have them had each pose been written in convention ``name`` of
    capture.camera.misread_poses (the pose read P, from the true pose T: T F, T^-1, F T^-1 with F the y/z flip)."""
    F = np.diag([1.0, -1.0, -1.0, 1.0])
    def read(c):
        T = c.world_from_cam
        P = {"axes": T @ F, "inverse": invert_rigid(T), "inverse, axes": F @ invert_rigid(T)}[name]
        np.testing.assert_allclose(misread_poses(P)[name], T, atol=1e-9)
        return replace(c, cam_from_world=invert_rigid(P))
    return [replace(x, camera=read(x.camera)) for x in scans]


@pytest.mark.parametrize("name", ["axes", "inverse", "inverse, axes"])
def test_poses_written_in_another_convention_are_named(ring, name):
    """Poses written in another convention (camera axes negated, world-to-camera for camera-to-world): the scales'
    verdict is ``none`` or a wrong scale; the convention check names the misreading, its depths agreeing at scale
    1 as the right capture's do."""
    scans = _misread(ring.scans, name)
    rec, _, _ = _check(scans)
    assert rec["status"] in ("none", "scale"), rec
    samples = [view_sample(s.depth, s.camera, CFG.points, i) for i, s in enumerate(scans)]
    conv = convention_check(samples, [x.camera for x in scans], CFG, rec["best_share"])
    right, _, _ = _check(ring.scans)
    assert conv["status"] == "convention" and conv["convention"] == name, conv
    assert conv["tried"][name]["share"] == pytest.approx(right["share"], abs=0.02)
    assert "once the poses are" in conv["message"]


def test_depth_in_another_unit_is_no_convention(ring):
    """Depth x 2: the scales name it; no other convention makes the depths agree."""
    scans = _with_depth(ring.scans, lambda i, z: z * 2.0)
    rec, _, _ = _check(scans)
    samples = [view_sample(s.depth, s.camera, CFG.points, i) for i, s in enumerate(scans)]
    conv = convention_check(samples, [x.camera for x in scans], CFG, rec["best_share"])
    assert rec["status"] == "scale" and conv["status"] == "as read", conv


def _intrinsics(scans, fn):
    """The scans with each camera's K replaced by ``fn(K, camera)``, the depth as measured."""
    return [replace(x, camera=replace(x.camera, K=fn(x.camera.K, x.camera))) for x in scans]


def _intrinsics_verdict(scans):
    rec, _, _ = _check(scans)
    samples = [view_sample(s.depth, s.camera, CFG.points, i) for i, s in enumerate(scans)]
    return rec, intrinsics_check(samples, [x.camera for x in scans], CFG, rec["best_share"])


def test_intrinsics_of_an_image_twice_the_size_are_named(ring):
    """fl_x, fl_y, cx, cy of an image twice the size (images resized after calibration): read as a depth scale or
    as nothing; the intrinsics check names it with the factor 0.5 that undoes it, agreeing as the right capture."""
    def twice(K, c):
        return make_K(2 * K[0, 0], 2 * K[1, 1], 2 * K[0, 2] + 0.5, 2 * K[1, 2] + 0.5)  # OpenCV centres, 2x grid
    rec, intr = _intrinsics_verdict(_intrinsics(ring.scans, twice))
    right, _, _ = _check(ring.scans)
    assert rec["status"] in ("none", "scale") and intr["status"] == "intrinsics", (rec, intr)
    assert intr["intrinsics"] == "image size" and intr["factor"] == pytest.approx(0.5, abs=0.01), intr
    assert intr["tried"]["image size"]["share"] == pytest.approx(right["share"], abs=0.02)
    assert "images 2 times the size" in intr["message"]


def test_a_principal_point_at_the_corner_is_named(ring):
    """cx = cy = 0: the views' depths agree nowhere; with the principal point at the image's centre (where the
    ring's is) they agree as the right capture's."""
    rec, intr = _intrinsics_verdict(_intrinsics(ring.scans, lambda K, c: make_K(K[0, 0], K[1, 1], 0.0, 0.0)))
    assert rec["status"] == "none" and intr["status"] == "intrinsics" and intr["intrinsics"] == "centre", intr
    rec, intr = _intrinsics_verdict(_with_depth(ring.scans, lambda i, z: z * 2.0))
    assert rec["status"] == "scale" and intr["status"] == "as read", intr  # a depth unit is no intrinsic


def test_reprojected_sample_is_the_sample_of_the_new_intrinsics(ring):
    """_reprojected(view_sample(depth, camera)) through K_new is view_sample(depth, camera with K_new): the same
    pixels, back-projected through the new intrinsics."""
    x = ring.scans[3]
    K_new = make_K(0.7 * x.camera.K[0, 0], 0.8 * x.camera.K[1, 1], 10.0, 20.0)
    got = _reprojected(view_sample(x.depth, x.camera, 200, 5), x.camera.K, K_new)
    ref = view_sample(x.depth, replace(x.camera, K=K_new), 200, 5)
    np.testing.assert_allclose(got[0], ref[0], rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(got[1], ref[1])


@pytest.mark.parametrize("k", [1000.0, 0.01])
def test_depth_units_beyond_the_scale_search_are_named(ring, k):
    """Depth k times its true value (millimetres read as metres, or the reverse), beyond the scales searched: the
    scales find nothing; the units check names the factor 1 / k that undoes it, agreeing as the right capture."""
    scans = _with_depth(ring.scans, lambda i, z: z * k)
    rec, _, _ = _check(scans)
    samples = [view_sample(s.depth, s.camera, CFG.points, i) for i, s in enumerate(scans)]
    units = units_check(samples, [x.camera for x in scans], CFG, rec["best_share"])
    right, _, _ = _check(ring.scans)
    assert rec["status"] in ("none", "scale") and units["status"] == "units", (rec, units)
    assert units["factor"] == pytest.approx(1 / k) and "depth_unit_scale_factor" in units["message"]
    assert units["tried"][f"x{1 / k:g}"]["share"] == pytest.approx(right["share"], abs=0.02)
    samples = [view_sample(s.depth, s.camera, CFG.points, i) for i, s in enumerate(ring.scans)]
    assert units_check(samples, [x.camera for x in ring.scans], CFG, right["best_share"])["status"] == "as read"


def test_config_is_validated():
    with pytest.raises(ValueError):
        AgreementConfig(rel=0.0)
    with pytest.raises(ValueError):
        AgreementConfig(points=0)

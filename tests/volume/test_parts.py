"""Sphere sets (docs/methods.md §3), marching-cubes mesh, vertex colour and RGBz images (docs/methods.md §1.4)."""

from __future__ import annotations

import numpy as np
import pytest

from tests.scenes import make_scanset, render_depth, scan_ring, sphere_scene, torus_scene
from volume.grid import cube_for_bounds, voxel_centers
from volume.mesh import MeshConfig, clean_and_decimate, marching_cubes, vertex_colors
from volume.model import SdfLevel
from volume.rgbz import RgbzConfig, build_rgbz, close_holes, hole_fraction, raycast_depth
from volume.spheres import fit_spheres, volume_iou

L = 32


def _level(scene, res=L):
    o, ext = cube_for_bounds(scene.bounds)
    w = ext / res
    v = scene.sdf(voxel_centers(o, w, res)).reshape(res, res, res).astype(np.float32)
    return SdfLevel(res, o, w, np.zeros((0, 3), np.int32), v)


def _sphere_mesh():
    """(scene, level, vertices, faces): the sphere scene's exact SDF level and its marching-cubes mesh."""
    scene = sphere_scene()
    lv = _level(scene)
    return (scene, lv) + tuple(marching_cubes(lv))


# ------------------------------------------------------------------ spheres
def test_sphere_set_meets_error_target_and_matches_brute_force():
    lv = _level(torus_scene())
    counts = []
    for target in (0.3, 0.2, 0.1, 0.05):
        sph, err = fit_spheres(lv, target)
        assert err <= target
        assert err == pytest.approx(1 - volume_iou(sph, lv), abs=1e-12)  # incremental IoU == reference
        counts.append(len(sph))
    assert counts == sorted(counts) and counts[0] < counts[-1]  # tighter target -> more spheres


def test_sphere_set_of_a_ball_is_small():
    lv = _level(sphere_scene())
    sph, err = fit_spheres(lv, 0.2)
    assert len(sph) == 1 and err <= 0.2
    # that sphere is the ball itself (centre near the origin, radius ~ 7 cm)
    assert np.linalg.norm(sph.centers[0]) < lv.voxel_size and abs(sph.radii[0] - 0.07) < lv.voxel_size


def test_sphere_set_empty_and_bad_target():
    lv = _level(sphere_scene())
    empty = SdfLevel(L, lv.origin, lv.voxel_size, np.zeros((0, 3), np.int32), np.ones((L, L, L), np.float32))
    sph, err = fit_spheres(empty, 0.1)
    assert len(sph) == 0 and err == 0.0
    with pytest.raises(ValueError, match="sphere-error"):
        fit_spheres(lv, 1.5)


# ------------------------------------------------------------------ mesh
def test_marching_cubes_on_exact_sdf():
    lv = _level(sphere_scene())
    v, f = marching_cubes(lv)
    assert len(f) > 1000
    r = np.linalg.norm(v, axis=1)
    assert np.abs(r - 0.07).max() < 0.1 * lv.voxel_size
    tri = v[f].astype(np.float64)
    signed_vol = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6
    assert signed_vol == pytest.approx(4 / 3 * np.pi * 0.07 ** 3, rel=0.02)  # > 0: faces point outwards
    v2, f2 = clean_and_decimate(v, f, MeshConfig(target_faces=500))
    assert len(f2) <= 500 and len(f2) > 300
    assert np.abs(np.linalg.norm(v2, axis=1) - 0.07).max() < 0.5 * lv.voxel_size


def test_marching_cubes_no_surface():
    lv = _level(sphere_scene())
    empty = SdfLevel(L, lv.origin, lv.voxel_size, np.zeros((0, 3), np.int32), np.ones((L, L, L), np.float32))
    v, f = marching_cubes(empty)
    assert v.shape == (0, 3) and f.shape == (0, 3)


def test_vertex_colors_from_constant_images():
    _, lv, v, f = _sphere_mesh()
    cams = scan_ring(6, 64, 48)
    depth = raycast_depth(v, f, cams)
    col = np.array([0.2, 0.4, 0.6], np.float32)
    imgs = np.broadcast_to(col, (6, 48, 64, 3))
    c = vertex_colors(v, f, cams, imgs, depth, lv.voxel_size)
    np.testing.assert_allclose(c, np.broadcast_to(col, c.shape), atol=1e-4)  # float32 weighted means


# ------------------------------------------------------------------ RGBz
def test_raycast_depth_matches_exact_depth():
    scene, lv, v, f = _sphere_mesh()
    cams = scan_ring(3, 80, 60)
    geo = raycast_depth(v, f, cams)
    for cam, g in zip(cams, geo):
        ref = render_depth(scene, cam)
        both = (ref > 0) & (g > 0)
        assert both.sum() > 0.95 * (ref > 0).sum()
        # the hit points lie on the true sphere (radial error; depth error grows at grazing pixels)
        pts, _ = cam.depth_to_points(g)
        assert np.abs(np.linalg.norm(pts, axis=1) - 0.07).max() < 0.1 * lv.voxel_size
        assert np.median(np.abs(g - ref)[both]) < 0.15 * lv.voxel_size


def test_hole_fraction_and_closing():
    d = np.zeros((40, 40), np.float32)
    d[10:30, 10:30] = 1.0
    d[15:17, 15:17] = 0.0  # a 4-pixel hole inside a 400-pixel silhouette
    assert hole_fraction(d) == pytest.approx(4 / 400)
    c = close_holes(d, 5)
    assert hole_fraction(c) == 0.0
    valid = d > 0
    np.testing.assert_array_equal(c[valid], d[valid])  # measured pixels never change
    assert close_holes(d, 0) is d


def test_build_rgbz_fills_holes_and_keeps_agreeing_depth():
    scene, lv, v, f = _sphere_mesh()
    ss = make_scanset(scene, scan_ring(4, 80, 60), holes=0.03, seed=3)
    rgbz, stats = build_rgbz(ss, v, f, lv, RgbzConfig())
    assert rgbz.depth.shape == (4, 60, 80) and rgbz.rgb.shape == (4, 60, 80, 3)
    for s, d, st in zip(ss.scans, rgbz.depth, stats):
        m = s.depth > 0
        # exact depth agrees: measured kept, to the half-float storage (volume.model.RGBZ_STORAGE)
        np.testing.assert_array_equal(d[m], s.depth[m].astype(np.float16))
        ref = render_depth(scene, s.camera)
        holes = (ref > 0) & ~m
        filled = holes & (d > 0)
        # hole blobs on the silhouette: the 32^3 mesh is a chord polygon, a few edge rays miss it
        assert filled.sum() >= 0.85 * holes.sum()
        e = np.abs(d[filled] - ref[filled])  # holes filled by the geometry (grazing edge pixels: larger)
        assert np.median(e) < 0.15 * lv.voxel_size and np.mean(e < 0.3 * lv.voxel_size) >= 0.9
        assert st["holes_after"] <= st["holes_before"]
    # the pixels whose depth the capture measured are kept apart from the fill (render.gather), alike
    # in the compact and the dense store
    dense, _ = build_rgbz(ss, v, f, lv, RgbzConfig(store="dense"))
    want = np.stack([s.depth > 0 for s in ss.scans])
    assert (rgbz.depth > 0).sum() > want.sum()  # something was filled
    np.testing.assert_array_equal(rgbz.measured, want)
    np.testing.assert_array_equal(dense.measured, want)


def test_measured_depth_by_hand():
    from volume.rgbz import measured_depth

    m = np.array([[0.0, 0.5, 0.7], [0.2, 0.0, 0.4]], np.float32)
    d = np.array([[0.3, 0.5, 0.6], [0.2, 0.9, 0.0]], np.float32)
    np.testing.assert_array_equal(measured_depth(m, d), [[False, True, False], [True, False, False]])


def test_build_model_on_empty_depth_refuses_an_empty_model():
    """Depth empty in every view: the pipeline stops at the pyramid with the reason (volume.build._no_surface)
    instead of returning a model with no surface voxels, no spheres and no mesh, which furrow model used to save
    with exit status 0 (stop 64)."""
    from volume.model import ModelError
    from volume.pipeline import build_model
    from volume.pipeline.config import FuseConfig, PipelineConfig
    from volume.pyramid import LoptConfig

    ss = make_scanset(sphere_scene(), scan_ring(4, 48, 36), depth_hook=lambda i, z: np.zeros_like(z))
    with pytest.raises(ModelError, match="no surface at any level: none of the 4 views has depth left"):
        build_model(ss, PipelineConfig(fuse=FuseConfig(lopt=LoptConfig(max_res=16))))


def test_rgbz_keeps_measured_fringe_and_geometry_fills_the_rest():
    """docs/methods.md §1.4: the RGBz depth is the measured range image; the geometry depth only fills
    unmeasured pixels.  A fringe measured ~2-3 cm outside the sphere (no geometry hit there, far
    from the surface) is kept by default and dropped by the former agreement rule."""
    scene, lv, v, f = _sphere_mesh()
    cams = scan_ring(3, 80, 60)
    geo = raycast_depth(v, f, cams)

    def hook(i, z):
        z = z.copy()
        ring = (z <= 0) & (geo[i] <= 0)
        rows, cols = np.nonzero(geo[i] > 0)
        ring[:, : cols.min() - 10] = False  # a 4-pixel column band 6-10 px left of the silhouette
        ring[:, cols.min() - 6:] = False
        ring[: rows.min()] = False
        ring[rows.max() + 1:] = False
        z[ring] = float(np.median(geo[i][geo[i] > 0]))
        z[30, 40] = 0.0  # one unmeasured pixel inside: geometry fills it
        return z

    ss = make_scanset(scene, cams, depth_hook=hook)
    new, _ = build_rgbz(ss, v, f, lv, RgbzConfig(closing_px=0))
    old, _ = build_rgbz(ss, v, f, lv, RgbzConfig(closing_px=0, keep_measured=False))
    for i, s in enumerate(ss.scans):
        m = s.depth > 0
        fringe = m & (geo[i] <= 0)
        pts = s.camera.unproject(s.camera.pixel_grid()[fringe], s.depth[fringe])
        far = np.abs(scene.sdf(pts)) > 3 * lv.voxel_size  # beyond the former rule's 2 voxels
        assert far.sum() > 20
        np.testing.assert_array_equal(new.depth[i][m], s.depth[m].astype(np.float16))  # half-float storage
        assert np.all(old.depth[i][fringe][far] == 0)  # dropped by the former rule
        assert new.depth[i][30, 40] == geo[i][30, 40].astype(np.float16) and geo[i][30, 40] > 0

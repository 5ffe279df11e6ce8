"""Eq. 1 (L_opt), surface voxels and the pyramid (docs/methods.md §1.1, §1.7)."""

from __future__ import annotations

import numpy as np
import pytest

from tests.scenes import furball_scene, make_scanset, scan_ring, sphere_scene
from volume.build import fuse_levels
from volume.grid import voxel_centers
from volume.pipeline.config import FuseConfig
from volume.pyramid import (
    LoptConfig,
    build_pyramid,
    choose_l_opt,
    discontinuity_fraction,
    discontinuity_mask,
    surface_voxels,
)


def _sphere_sdf(L, r=0.3):
    x = voxel_centers(np.zeros(3) - 0.5, 1.0 / L, L).reshape(L, L, L, 3)
    return (np.linalg.norm(x, axis=-1) - r).astype(np.float32), 1.0 / L


def test_exact_sdf_has_no_discontinuity():
    for L in (8, 16, 32):
        v, w = _sphere_sdf(L)
        assert discontinuity_fraction(v, w, 1.5) == 0.0
        # alpha = 1 still passes: an exact distance is 1-Lipschitz (neighbours differ by <= w)
        assert discontinuity_fraction(v, w, 1.0 + 1e-4) == 0.0


def test_step_is_counted_exactly():
    L, w = 16, 0.1
    v = np.zeros((L, L, L), np.float32)
    v[5:] = 2 * w  # a jump of 2w between i = 4 and i = 5
    m = discontinuity_mask(v, w, 1.5)
    assert m.sum() == 2 * L * L and m[4].all() and m[5].all()
    assert discontinuity_fraction(v, w, 1.5) == pytest.approx(2 / L)
    assert discontinuity_fraction(v, w, 2.5) == 0.0
    valid = np.ones_like(m)
    valid[5] = False
    assert discontinuity_mask(v, w, 1.5, valid).sum() == 0


def test_empty_and_single_voxel_volumes():
    assert discontinuity_fraction(np.full((8, 8, 8), 0.5, np.float32), 0.1, 1.5) == 0.0
    assert discontinuity_fraction(np.zeros((1, 1, 1), np.float32), 0.1, 1.5) == 0.0
    assert len(surface_voxels(np.full((4, 4, 4), 1.0, np.float32), 0.1)) == 0


def test_surface_through_voxel_centres():
    L, w = 16, 0.1
    i = np.arange(L)[:, None, None] * np.ones((1, L, L))
    v = ((i - 7) * w).astype(np.float32)  # plane through the centres of layer i = 7
    s = surface_voxels(v, w)
    assert len(s) == L * L and np.all(s[:, 0] == 7)  # neighbours at +-w > half diagonal (0.866 w)
    assert discontinuity_fraction(v, w, 1.5) == 0.0


def test_choose_l_opt_follows_the_paper_loop():
    assert choose_l_opt({8: 0.0, 16: 0.02, 32: 0.005}, 0.01) == 32
    assert choose_l_opt({8: 0.0, 16: 0.005, 32: 0.02}, 0.01) == 16
    assert choose_l_opt({8: 0.5, 16: 0.2, 32: 0.02}, 0.01) == 8  # nothing passes: the coarsest
    with pytest.raises(ValueError, match="power of two"):
        LoptConfig(max_res=100)
    with pytest.raises(ValueError, match="alpha"):
        LoptConfig(alpha=0.5)
    assert LoptConfig(max_res=64).resolutions == [8, 16, 32, 64]


def test_build_pyramid_levels():
    vols = {L: _sphere_sdf(L)[0] for L in (8, 16, 32)}
    p = build_pyramid(vols, np.zeros(3) - 0.5, 1.0, 16)
    assert p.resolutions == [8, 16] and p.l_opt == 16
    # the sphere's surface voxels scale with L^2
    n8, n16 = (len(lv.surface) for lv in p.levels)
    assert 3.0 < n16 / n8 < 5.0
    assert np.all(np.abs(np.linalg.norm(p.levels[1].centers(), axis=1) - 0.3) <= np.sqrt(3) / 2 / 16 + 1e-9)


@pytest.mark.parametrize("scene_fn, keeps", [(sphere_scene, True), (furball_scene, False)], ids=["smooth", "fur"])
def test_eq1_smooth_keeps_fur_drops(scene_fn, keeps):
    """Paper values (alpha 1.5, t 0.01), max_res 64, noisy holed scans: the smooth sphere keeps
    64^3, the fur ball (strands 1.6 mm thick, 2-4 cm long) drops."""
    ss = make_scanset(scene_fn(), scan_ring(16, 96, 72), noise=0.001, holes=0.03, outliers=0.002)
    cfg = FuseConfig(lopt=LoptConfig(max_res=64))
    _, _, fused, frac, _ = fuse_levels(ss, cfg)
    l_opt = choose_l_opt(frac, cfg.lopt.t)
    if keeps:
        assert l_opt == 64, frac
    else:
        assert l_opt < 64, frac
        assert frac[64] > 3 * cfg.lopt.t, frac


def test_measured_voxels_need_two_views_and_join_the_surface():
    from volume.pyramid import measured_voxels

    o, w, L = np.zeros(3), 0.1, 8
    a = np.array([[0.05, 0.05, 0.05], [0.35, 0.15, 0.75], [0.55, 0.55, 0.55], [-0.1, 0.2, 0.2], [0.9, 0.1, 0.1]])
    b = np.array([[0.09, 0.01, 0.02], [0.55, 0.55, 0.55], [0.3501, 0.1501, 0.7501], [-0.1, 0.2, 0.2]])
    got = measured_voxels([a, b], o, w, L, 2)
    # voxel (0,0,0) and (5,5,5) in both views, (3,1,7) in both; outside points ignored; (9,..) out of range
    np.testing.assert_array_equal(got, [[0, 0, 0], [3, 1, 7], [5, 5, 5]])
    assert len(measured_voxels([a], o, w, L, 2)) == 0
    assert len(measured_voxels([a], o, w, L, 1)) == 3  # (0,0,0), (3,1,7), (5,5,5); the rest is outside
    vols = {L: _sphere_sdf(L)[0] for L in (8, 16)}
    pts = [np.array([[0.45, 0.45, 0.45]])] * 2  # a corner of the cube, far outside the 0.3 m sphere
    p0 = build_pyramid(vols, np.zeros(3) - 0.5, 1.0, 16)
    p1 = build_pyramid(vols, np.zeros(3) - 0.5, 1.0, 16, points=pts)
    for lv0, lv1 in zip(p0.levels, p1.levels):
        assert len(lv1.surface) == len(lv0.surface) + 1
        assert (lv1.surface == lv1.resolution - 1).all(axis=1).any()


def test_measured_voxels_of_every_level_in_one_pass():
    """Each view's points are made once for all levels; the voxels equal one pass per level."""
    from volume.pyramid import measured_voxels, measured_voxels_levels

    rng = np.random.default_rng(3)
    views = [rng.normal(0.0, 0.05, (4000, 3)) for _ in range(5)]
    origin, extent = np.array([-0.12, -0.12, -0.12]), 0.24
    sizes = {L: extent / L for L in (8, 16, 32, 64)}
    both = measured_voxels_levels(iter(views), origin, sizes, 2)  # a one-shot iterator: one pass
    for L, w in sizes.items():
        np.testing.assert_array_equal(both[L], measured_voxels(views, origin, w, L, 2))
        assert len(both[L]) > 0


def test_measured_voxels_mapped_equal_the_reference():
    """volume.pyramid.measured_voxels_mapped (each view's cells through a per-view map: the pipeline's
    pool, PYRAMID_CELLS_MAPPED) against measured_voxels_levels over the views' points in one process
    (the reference): the same voxels at every level, with a map that hands the notes back in view
    order; a map that loses a view's cells changes them."""
    from capture.view_map import serial_map
    from volume.build import ViewPoints
    from volume.pyramid import measured_voxels_levels, measured_voxels_mapped

    ss = make_scanset(sphere_scene(), scan_ring(6, 48, 36), noise=0.002, outliers=0.01)
    origin, extent = np.array([-0.1, -0.1, -0.1]), 0.2
    sizes = {L: extent / L for L in (8, 16, 32, 64)}
    ref = measured_voxels_levels(ViewPoints(ss.scans), origin, sizes, 2)
    got = measured_voxels_mapped(serial_map, ss.scans, origin, sizes, 2)
    for L in sizes:
        np.testing.assert_array_equal(got[L], ref[L])
        assert len(ref[L]) > 0

    def lossy(fn, scans, arg, description=""):  # the last view's cells lost
        views, notes = serial_map(fn, scans, arg, description)
        return views, notes[:-1]

    lost = measured_voxels_mapped(lossy, ss.scans, origin, sizes, 2)
    assert any(len(lost[L]) != len(ref[L]) for L in sizes)


def test_compiled_discontinuity_count_equals_the_mask():
    """volume.pyramid_kernel.count_flagged (discontinuity_fraction's default) against the numpy mask
    (fast=False): the same fraction on noisy volumes with NaN, with and without ``valid``, limits
    on both sides of the noise, flat and one-voxel-thick shapes."""
    rng = np.random.default_rng(7)
    for shape in ((8, 9, 10), (1, 5, 5), (24, 24, 24)):
        v = (rng.normal(size=shape) * 0.01).astype(np.float32)
        v[rng.random(shape) < 0.05] = np.nan
        valid = rng.random(shape) < 0.7
        for mask in (None, valid):
            for alpha in (0.5, 1.5, 3.0):
                got = discontinuity_fraction(v, 0.01, alpha, mask)
                want = discontinuity_fraction(v, 0.01, alpha, mask, fast=False)
                assert got == want, (shape, alpha)
    assert 0.0 < discontinuity_fraction(v, 0.01, 1.5, valid) < 1.0


def test_view_cell_keys_from_the_finest_level_equal_the_reference():
    """volume.pyramid.view_cell_keys bins the points once at the finest level and shifts the cells for
    the coarser ones (and marks them in a bitmap): the same sorted cells as binning at every level
    (view_cell_keys_reference), points on cell faces, outside the cube, NaN and inf included; sizes
    that are not nested, and a finest grid too large for the bitmap, take the other paths, also equal."""
    from volume import pyramid
    from volume.pyramid import nested_finest, view_cell_keys, view_cell_keys_reference

    rng = np.random.default_rng(7)
    extent, origin = 0.3, np.array([-0.15, -0.13, -0.16])
    d = rng.normal(size=(20000, 3))
    pts = 0.1 * d / np.linalg.norm(d, axis=1)[:, None] + rng.normal(0.0, 0.003, (20000, 3))
    faces = origin + extent / 256 * rng.integers(-3, 260, (3000, 3))  # exactly on cell faces, some outside
    pts = np.concatenate([pts, faces, [[np.nan, 0, 0], [np.inf, 0, 0], [0, -np.inf, 0], [1e300, 0, 0]]])
    sizes = {L: extent / L for L in (8, 16, 32, 64, 128, 256)}
    assert nested_finest(sizes) == 256
    with np.errstate(invalid="ignore"):
        cases = [(view_cell_keys(pts, origin, sz), view_cell_keys_reference(pts, origin, sz), sz)
                 for sz in (sizes, {L: sizes[L] for L in (8, 64)}, {16: extent / 16, 32: extent / 31})]
    for got, ref, sz in cases:
        assert set(got) == set(ref)
        for L in sz:
            np.testing.assert_array_equal(got[L], ref[L])
            assert got[L].dtype == ref[L].dtype and len(ref[L]) > 0
    assert nested_finest({16: extent / 16, 32: extent / 31}) is None
    small = pyramid.BITMAP_CELLS
    try:
        pyramid.BITMAP_CELLS = 1000  # every level sorted instead of marked
        with np.errstate(invalid="ignore"):
            got, ref = view_cell_keys(pts, origin, sizes), view_cell_keys_reference(pts, origin, sizes)
    finally:
        pyramid.BITMAP_CELLS = small
    for L in sizes:
        np.testing.assert_array_equal(got[L], ref[L])

"""Footprint-packed scan maps (volume.stream) against the full-frame maps: the same records
where either holds one, the same fused volume voxel for voxel (bit for bit: same float32
arithmetic on the same pixels), and far fewer records on a small object in a large frame."""

from __future__ import annotations

import numpy as np
import pytest

from tests.scenes import furball_scene, make_scanset, ring_cameras
from volume.fusion import FusionConfig, fuse_consensus, scan_maps
from volume.fusion_jit import VOID, pack_maps
from volume.grid import cube_for_bounds
from volume.stream import FOOTPRINT_MARGIN_PX, footprint_rect, pack_scans, packed_fraction


@pytest.fixture(scope="module")
def fur():
    # the object covers a small part of these frames (cameras 0.9 m away)
    return make_scanset(furball_scene(n=150), ring_cameras(8, 160, 120, radius=0.9), noise=0.001, holes=0.05,
                        outliers=0.002)


def test_footprint_rect():
    m = np.zeros((20, 30), bool)
    assert footprint_rect(m, 3) == (0, 0, 0, 0)
    m[5:7, 10:12] = True
    assert footprint_rect(m, 3) == (7, 2, 8, 8)
    m[19, 29] = True
    assert footprint_rect(m, 3) == (7, 2, 23, 18)


def test_packed_footprints_equal_full_frames(fur):
    cfg = FusionConfig()
    full = pack_maps([scan_maps(s, cfg.max_grazing_deg, cfg.smooth_sigma_z) for s in fur.scans])
    crop = pack_scans(fur.scans, cfg.max_grazing_deg, cfg.smooth_sigma_z)
    assert packed_fraction(crop) < 0.5  # the point of it
    np.testing.assert_array_equal(crop.P, full.P)
    for s, scan in enumerate(fur.scans):
        W, H = scan.camera.width, scan.camera.height
        recs = full.pixel[full.start[s]:full.start[s] + W * H].reshape(H, W, -1)
        x0, y0, w, h = crop.rect[s]
        assert w > 0 and h > 0
        mine = crop.pixel[crop.start[s]:crop.start[s] + w * h].reshape(h, w, -1)
        np.testing.assert_array_equal(mine, recs[y0:y0 + h, x0:x0 + w])
        outside = np.ones((H, W), bool)
        outside[y0:y0 + h, x0:x0 + w] = False
        # every pixel outside the rectangle is the shared void record in the full maps too
        np.testing.assert_array_equal(recs[outside], np.broadcast_to(crop.pixel[0], (int(outside.sum()), 8)))
        assert crop.pixel[0, VOID] == 1
    assert FOOTPRINT_MARGIN_PX >= 3


def test_fusion_with_footprints_is_identical(fur):
    cfg = FusionConfig()
    origin, ext = cube_for_bounds(fur.bounds)
    full = [scan_maps(s, cfg.max_grazing_deg, cfg.smooth_sigma_z) for s in fur.scans]
    crop = pack_scans(fur.scans, cfg.max_grazing_deg, cfg.smooth_sigma_z)
    coarse_a = coarse_b = None
    for L in (16, 32):
        a = fuse_consensus(fur, origin, ext / L, L, cfg, full, coarse=coarse_a)
        b = fuse_consensus(fur, origin, ext / L, L, cfg, crop, coarse=coarse_b)
        np.testing.assert_array_equal(a.values, b.values)
        np.testing.assert_array_equal(a.measured, b.measured)
        np.testing.assert_array_equal(a.seen, b.seen)
        assert a.band.sum() > 0
        coarse_a, coarse_b = a, b


def test_maps_at_the_measured_depth_size(fur):
    """A phone's depth resampled up to the colour (metadata depth_size): the maps are those of the
    depth at the measured size (volume.stream.native_scale), and the fused surface is where the
    colour-size maps put it (within a voxel)."""
    from capture.scan import ScanSet
    from volume.stream import depth_only_scan, native_scale

    assert native_scale(fur) == 1.0
    phone = ScanSet(fur.scans, fur.bounds, {**fur.metadata, "depth_size": [40, 30]})
    s = native_scale(phone)
    assert s == pytest.approx(40 / 160)
    cfg = FusionConfig()
    small = pack_scans(phone.scans, cfg.max_grazing_deg, cfg.smooth_sigma_z, scale=s)
    ref = pack_maps([scan_maps(depth_only_scan(x, s), cfg.max_grazing_deg, cfg.smooth_sigma_z) for x in phone.scans])
    np.testing.assert_array_equal(small.P, ref.P)
    assert list(small.W) == [40] * len(phone) and list(small.H) == [30] * len(phone)
    for v in range(len(phone)):
        x0, y0, w, h = small.rect[v]
        mine = small.pixel[small.start[v]:small.start[v] + w * h].reshape(h, w, -1)
        full = ref.pixel[ref.start[v]:ref.start[v] + 40 * 30].reshape(30, 40, -1)
        # float32 rounding only: OpenCV's bilateral filter rounds differently on a rectangle this small
        np.testing.assert_allclose(mine, full[y0:y0 + h, x0:x0 + w], rtol=0, atol=2e-5)


def test_fusion_at_twice_the_measured_depth_size(tmp_path):
    """A capture whose depth was written at a quarter of the colour's size and resampled up when
    read: fusion maps at 2x the measured size (the default) put the surface nearly as well as maps
    at the colour's size, against the exact torus (measured: mean |SDF error| over the surface
    voxels 3.36 mm against 3.07; 3.60 at 1x)."""
    from capture.io import read_scanset, write_transforms
    from tests.scenes import make_scanset, scan_ring, torus_scene, torus_sdf
    from volume.stream import native_scale

    ss = make_scanset(torus_scene(), scan_ring(8, 256, 192))
    phone = read_scanset(write_transforms(ss, tmp_path / "s", depth_size=(64, 48)))
    cfg = FusionConfig()
    assert native_scale(phone, cfg.map_oversample) == pytest.approx(0.5)
    origin, ext = cube_for_bounds(phone.bounds)
    L = 32
    w = ext / L
    err = []
    for scale in (1.0, native_scale(phone, cfg.map_oversample)):
        maps = pack_scans(phone.scans, cfg.max_grazing_deg, cfg.smooth_sigma_z, scale=scale)
        v = fuse_consensus(phone, origin, w, L, cfg, maps).values
        idx = np.argwhere(np.abs(v) < w)
        assert len(idx) > 1000
        err.append(np.mean(np.abs(v[tuple(idx.T)] - torus_sdf(0.06, 0.025)(origin + (idx + 0.5) * w))))
    assert err[0] < 0.5 * w and err[1] < 1.2 * err[0], err

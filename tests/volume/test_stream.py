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

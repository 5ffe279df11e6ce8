"""capture.plate_masks: a plate view's masks on the object's box against the whole frame's (bit for bit)."""

import numpy as np
import pytest

from capture import plate_masks
from capture.plate_masks import view_masks


def _depths(shape):
    """Object depths that stress the box: an object, one on each border and corner, scattered needles,
    one pixel, a dense random mask, none, all, more ring pixels than RING_SAMPLES."""
    rng = np.random.default_rng(4)
    H, W = shape
    out = [np.zeros(shape, bool) for _ in range(9)]
    out[0][H // 3:H // 2, W // 2:W // 2 + W // 8] = True
    out[1][:H // 5, W - W // 9:] = True
    out[2][H - 1, 0] = True
    out[3][rng.random(shape) < 3e-4] = True
    out[4][H // 2, W // 2] = True
    out[5] = rng.random(shape) < 0.3
    out[7][:] = True
    out[8][H // 4:3 * H // 4, 2:W // 3] = True
    return [np.where(m, 1.5, 0.0).astype(np.float32) for m in out]


@pytest.mark.parametrize("shape", [(894, 1192), (97, 131)])
def test_box_masks_equal_the_whole_frames(shape, monkeypatch):
    """view_masks on the box equals the whole frame's source, ring, need and band bit for bit."""
    for d in _depths(shape):
        got = view_masks(d, True)
        monkeypatch.setattr(plate_masks, "MASKS_BOX", False)
        want = view_masks(d, True)
        monkeypatch.setattr(plate_masks, "MASKS_BOX", True)
        for a, b in zip(got, want, strict=True):
            assert a.dtype == b.dtype and a.shape == b.shape
            np.testing.assert_array_equal(a, b)
        assert view_masks(d, False)[3] is None
    assert len(want[1]) > 100 and want[2].any() and not want[0].all()


def test_the_box_needs_its_margin(monkeypatch):
    """A box one radius too tight gives other masks (the test can fail)."""
    from capture import matting_scale

    d = _depths((97, 131))[0]
    want = view_masks(d, True)
    real = matting_scale.object_box
    monkeypatch.setattr(matting_scale, "object_box", lambda m, pad: real(m, pad // 2))
    got = view_masks(d, True)
    assert not all(np.array_equal(a, b) for a, b in zip(got, want, strict=True))


def test_the_common_grid_equals_the_whole_frames(monkeypatch):
    """common_grid equals the whole frames' test then the grid (both of plate_fixed's grids), weights
    at, above and just below 1; a grid taken at another offset differs (the test can fail)."""
    from capture.plate_masks import common_grid

    rng = np.random.default_rng(2)
    weights = [np.where(rng.random((61, 83)) < 0.1, rng.choice([0.0, 0.5, np.nextafter(1.0, 0)], (61, 83)),
                        rng.choice([1.0, 1.0, 2.0], (61, 83))).astype(np.float32) for _ in range(9)]
    for sl in ((slice(None, None, 7), slice(None, None, 7)), (slice(3, None, 7), slice(3, None, 7))):
        got = common_grid(weights, *sl)
        monkeypatch.setattr(plate_masks, "GRID_FIRST", False)
        want = common_grid(weights, *sl)
        monkeypatch.setattr(plate_masks, "GRID_FIRST", True)
        assert got.dtype == want.dtype == bool and np.array_equal(got, want)
        assert want.any() and not want.all()
    assert not np.array_equal(common_grid(weights, slice(1, None, 7), slice(1, None, 7))[:8, :11], want[:8, :11])


def test_the_off_plane_test_at_the_band_equals_the_whole_frames():
    """off_plane_at equals plate_reproject.off_plane & where bit for bit on the orbit scene's views
    (their planes, a tilted one, none), NaN, infinite and zero depths included; with where the whole
    frame it is off_plane itself."""
    from capture.plate_masks import off_plane_at
    from capture.plate_reproject import off_plane
    from tests import plate_scenes as ps

    views, _ = ps.orbit_capture(n=4)
    rng = np.random.default_rng(7)
    for v in views:
        d = np.array(v.depth, np.float32)  # this scene's depth is the object's and the table's
        pts, _ = v.camera.depth_to_points(d)
        planes = [None]
        for n in (np.array([0.0, 0.0, 1.0]), np.array([0.3, -0.2, 0.93])):  # through the points' median height
            planes.append(np.append(n, -np.median(pts @ n)))
        d[rng.random(d.shape) < 0.02] = np.nan
        d[rng.random(d.shape) < 0.02] = np.inf
        where = rng.random(d.shape) < 0.3
        for plane in planes:
            want = off_plane(v.camera, d, plane)
            assert np.array_equal(off_plane_at(v.camera, d, plane, where), want & where)
            assert np.array_equal(off_plane_at(v.camera, d, plane, np.ones_like(where)), want)
            assert 0 < want.mean() < 1  # some depth pixels above each plane (or with depth), some not

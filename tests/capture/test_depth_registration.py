"""capture.depth_registration: the depth's edges against the colour's, on seeded scenes with exact depth."""

from __future__ import annotations

import numpy as np
import pytest

from capture.depth_registration import (
    OFFSET_RADIUS,
    ZOOM_GAIN,
    depth_edges,
    edge_scores,
    offset_verdict,
    shifted_depth,
    zoom_sums,
    zoom_verdict,
    zoomed_depth,
)
from tests.scenes import make_scanset, scan_ring, spheres_scene


@pytest.fixture(scope="module")
def ring():
    return make_scanset(spheres_scene(), scan_ring(8, 160, 120), noise=0.0005)


def _verdict(scans, move=(0, 0)):
    scores = [edge_scores(np.asarray(x.rgb), shifted_depth(x.depth, *move), i) for i, x in enumerate(scans)]
    return offset_verdict(np.sum([s for s, _ in scores], axis=0), len(scores), scores[0][1])


def test_registered_depth_has_no_offset(ring):
    rec = _verdict(ring.scans)
    assert rec["colour_offset_px"] == [0.0, 0.0] and not rec["colour_offset"], rec


@pytest.mark.parametrize("move", [(4, -3), (-6, 0), (0, 5)])
def test_moved_depth_is_found_by_its_offset(ring, move):
    """Every depth map moved by (dx, dy): the colour's edges sit at (-dx, -dy) from the depth's, reported."""
    rec = _verdict(ring.scans, move)
    assert rec["colour_offset"] and rec["colour_offset_px"] == [-move[0], -move[1]], rec
    assert rec["colour_offset_gain"] > 1.05 and "registered" in rec["colour_offset_message"]


def test_a_small_move_is_not_reported(ring):
    """2 px (under OFFSET_MIN_PX) is found but not reported."""
    rec = _verdict(ring.scans, (2, 0))
    assert rec["colour_offset_px"] == [-2.0, 0.0] and not rec["colour_offset"], rec


def test_edges_are_symmetric_and_the_shift_is_exact():
    z = np.zeros((6, 7), np.float32)
    z[2:4, 2:5] = 1.0
    e = depth_edges(z)
    np.testing.assert_array_equal(e, depth_edges(z[::-1, ::-1])[::-1, ::-1])  # no side preferred
    assert e[2, 1] and e[2, 2] and not e[0, 0]
    moved = shifted_depth(z, 2, -1)
    ref = np.zeros_like(z)
    ref[1:3, 4:7] = 1.0
    np.testing.assert_array_equal(moved, ref)
    assert not shifted_depth(z, 7, 0).any()


def test_too_few_edges_score_nothing():
    z = np.ones((40, 40), np.float32)  # measured everywhere, flat: no edge
    scores, scale = edge_scores(np.zeros((40, 40, 3), np.uint8), z)
    assert scores is None and scale == 1.0
    assert OFFSET_RADIUS >= 3


def _zoom(scans, zoom, depth_zoom=None, move=(0, 0)):
    """zoom_verdict of the colour's gradient at the depth's edges drawn ``zoom`` closer to the principal point,
    summed over ``scans`` whose depth maps were first drawn ``depth_zoom`` closer and then moved by ``move``."""
    tot = 0
    for i, x in enumerate(scans):
        c = x.camera.K[:2, 2]
        z = x.depth
        if depth_zoom is not None:
            z = shifted_depth(zoomed_depth(z, c, x.camera.width, depth_zoom), *move)
        tot = tot + zoom_sums(np.asarray(x.rgb), z, c, zoom, i)
    return zoom_verdict(tot, zoom, scans[0].camera.width)


@pytest.mark.parametrize("k", [1.15, 0.88])
def test_a_depth_map_zoomed_from_its_colour_is_told_from_a_focal_length(ring, k):
    """Depth maps drawn k times as far from the principal point as their colour (a depth camera with its own field
    of view): the colour's gradient is higher at their edges drawn back by k than where they are (ZOOM_GAIN or
    more), with no shift; the registered depth scores less drawn either way, whatever the shift (a focal length
    wrong for colour and depth alike)."""
    z = _zoom(ring.scans, k, depth_zoom=1 / k)
    assert z["depth_zoom"] and z["depth_zoom_gain"] >= ZOOM_GAIN and z["depth_zoom_shift_px"] == [0.0, 0.0], z
    for zoom in (k, 1 / k):
        z = _zoom(ring.scans, zoom)
        assert not z["depth_zoom"] and z["depth_zoom_gain"] < 1.0, z


def test_a_zoomed_depth_beside_its_colour_is_found_with_its_shift(ring):
    """Depth maps zoomed 1.15x and then moved (6, -6) px (a depth camera of its own, beside the colour's): drawn back,
    the colour's edges sit (-6, +6) / 1.15 px from them (to a pixel)."""
    z = _zoom(ring.scans, 1.15, depth_zoom=1 / 1.15, move=(6, -6))
    assert z["depth_zoom"], z
    assert np.allclose(z["depth_zoom_shift_px"], [-6 / 1.15, 6 / 1.15], atol=1.0), z


def test_zoomed_depth_against_the_pixel_by_pixel_reference():
    """zoomed_depth is the nearest depth at centre + zoom (p - centre), 0 outside; the centre is given in pixels of
    an image ``width`` wide and scaled to the depth map's own size."""
    rng = np.random.default_rng(0)
    z = rng.uniform(0.5, 1.0, (9, 12)).astype(np.float32)
    for zoom, c, width in ((1.3, (5.0, 4.0), 12), (0.7, (3.5, 2.0), 12), (1.1, (10.0, 8.0), 24)):
        got = zoomed_depth(z, np.array(c), width, zoom)
        f = 12 / width
        ref = np.zeros_like(z)
        for y in range(9):
            for x in range(12):
                sy = int(np.rint(c[1] * f + zoom * (y - c[1] * f)))
                sx = int(np.rint(c[0] * f + zoom * (x - c[0] * f)))
                if 0 <= sy < 9 and 0 <= sx < 12:
                    ref[y, x] = z[sy, sx]
        np.testing.assert_array_equal(got, ref)
    np.testing.assert_array_equal(zoomed_depth(z, np.array([5.0, 4.0]), 12, 1.0), z)

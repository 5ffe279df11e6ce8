"""capture.depth_disparity: disparity stored where depth belongs, on a seeded ring of three spheres with exact depth;
the inverted sample against the sample of the map read back pixel by pixel."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from capture.depth_agreement import AgreementConfig, view_sample
from capture.depth_disparity import DISPARITY_Z, disparity_check, inverted_sample, pose_distance, read_disparity
from tests.scenes import agreement_inputs, make_scanset, scan_ring, spheres_scene

CFG = AgreementConfig()
K = 0.2  # metres squared: the disparity values 0.35-0.6 where the depths are 0.33-0.57 m, plausible as depth


@pytest.fixture(scope="module")
def ring():
    return make_scanset(spheres_scene(), scan_ring(12, 96, 72), noise=0.0005)


def _disparity(scans, k=K):
    return [replace(s, depth=read_disparity(s.depth, k)) for s in scans]  # k / z: its own inverse


def _check(scans):
    samples, cams, best = agreement_inputs(scans, CFG)
    return disparity_check(samples, cams, CFG, best)


def test_pose_distance_is_the_ring_radius(ring):
    assert pose_distance([s.camera for s in ring.scans]) == pytest.approx(0.45, rel=1e-9)
    one = [ring.scans[0].camera] * 3  # every optical axis the same line: 1 m in front of them
    assert pose_distance(one) == pytest.approx(1.0, rel=1e-9)


def test_right_depth_is_read_as_stored(ring):
    rec = _check(ring.scans)
    assert rec["status"] == "as stored" and rec["z"] < 0 and rec["share"] < rec["share_as_stored"], rec


@pytest.mark.parametrize("k", [K, 1.0])
def test_disparity_is_named_with_its_constant(ring, k):
    """Disparity at K (values like depth) and at 1 / metres (an iPhone's): named, the constant found within 1 %,
    and read so the points agree as the right capture's do."""
    rec = _check(_disparity(ring.scans, k))
    assert rec["status"] == "disparity" and rec["z"] >= DISPARITY_Z, rec
    assert rec["constant"] == pytest.approx(k, rel=0.01), rec
    assert rec["share"] == pytest.approx(_check(ring.scans)["share_as_stored"], abs=0.03), rec
    assert "read as disparity" in rec["message"], rec


def test_read_disparity_undoes_it(ring):
    for s, d in zip(ring.scans, _disparity(ring.scans)):
        back = read_disparity(d.depth, K)
        v = s.depth > 0
        assert np.array_equal(back > 0, v) and np.allclose(back[v], s.depth[v], rtol=1e-6)
    nan = read_disparity(np.array([[np.nan, 0.0, 0.5]], np.float32), K)
    assert np.isnan(nan[0, 0]) and nan[0, 1] == 0 and nan[0, 2] == pytest.approx(0.4)


def test_inverted_sample_equals_the_sample_of_the_read_map(ring):
    """The sample's points read as k / d equal the points of the map read as k / d pixel by pixel (the same pixels:
    the measured ones are the same), and its small map the read map's."""
    for i, s in enumerate(_disparity(ring.scans)[:4]):
        got = inverted_sample(view_sample(s.depth, s.camera, CFG.points, i), K)
        want = view_sample(read_disparity(s.depth, K), s.camera, CFG.points, i)
        assert got[2] == want[2]
        assert np.allclose(got[0], want[0], rtol=1e-5, atol=1e-9)
        assert np.allclose(got[1], want[1], rtol=1e-5, atol=0)

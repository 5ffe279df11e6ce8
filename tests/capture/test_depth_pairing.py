"""capture.depth_pairing: each depth file held against its own colour image and its neighbours', on seeded scenes."""

from __future__ import annotations

import zlib
from dataclasses import replace

import numpy as np
import pytest

from capture.depth_pairing import (
    PAIR_NEIGHBOURS,
    PAIR_RADIUS,
    edge_fit,
    pairing_data,
    pairing_verdict,
    pairing_views,
)
from tests.scenes import make_scanset, scan_ring, spheres_scene


@pytest.fixture(scope="module")
def ring():
    return make_scanset(spheres_scene(), scan_ring(16, 128, 96), noise=0.0005)


def _verdict(scans):
    cand, need = pairing_views([s.camera for s in scans], list(range(len(scans))))
    data = {k: pairing_data(scans[k].rgb, scans[k].depth, zlib.crc32(scans[k].name.encode())) for k in need}
    return pairing_verdict(data, cand)


def test_right_files_fit_their_own_colour(ring):
    rec = _verdict(ring.scans)
    assert not rec["mispaired"] and rec["pairing_views"] == 16, rec
    assert rec["pairing_gain"] < 1.0 and rec["pairing_other_best"] <= 4, rec


@pytest.mark.parametrize("k", [1, -1])
def test_each_frame_given_its_neighbours_depth_is_mispaired(ring, k):
    """Frame i given frame i + k's depth file (a stream that dropped a frame): named, with its message."""
    n = len(ring.scans)
    scans = [replace(s, depth=ring.scans[(i + k) % n].depth) for i, s in enumerate(ring.scans)]
    rec = _verdict(scans)
    assert rec["mispaired"] and rec["pairing_other_best"] >= 14 and rec["pairing_gain"] >= 1.05, rec
    assert "depth_file_path" in rec["pairing_message"]
    assert rec["pairing_shift"] == -k, rec  # frame i's depth is in the file of frame i - k


def test_edge_fit_is_the_best_shifted_mean_of_the_gradient():
    rng = np.random.default_rng(3)
    G = rng.random((40, 50)).astype(np.float32)
    ys, xs = rng.integers(PAIR_RADIUS, 40 - PAIR_RADIUS, 60), rng.integers(PAIR_RADIUS, 50 - PAIR_RADIUS, 60)
    want = max(np.mean([G[y + dy, x + dx] for y, x in zip(ys, xs)])
               for dy in range(-PAIR_RADIUS, PAIR_RADIUS + 1) for dx in range(-PAIR_RADIUS, PAIR_RADIUS + 1))
    assert edge_fit(G, ys, xs) == pytest.approx(want, rel=1e-6)
    assert np.isnan(edge_fit(G, ys[:10], xs[:10]))  # too few edges to judge


def test_candidates_are_the_view_and_its_nearest_in_direction(ring):
    cams = [s.camera for s in ring.scans]
    cand, need = pairing_views(cams, [0, 5])
    assert cand[0][0] == 0 and len(cand[0]) == 1 + PAIR_NEIGHBOURS
    assert set(cand[0][1:3]) == {1, 15} and set(cand[5][1:3]) == {4, 6}  # a ring: the two beside it first
    assert need == sorted(set(cand[0]) | set(cand[5]))

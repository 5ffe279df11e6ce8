"""capture.depth_view_scales: each view's depth at its own scale (a monocular network's drift), on a seeded ring of
three spheres with exact depth; the vectorised agreement against capture.depth_agreement.pair_hits."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from capture.depth_agreement import AgreementConfig, pair_hits, view_sample
from capture.depth_view_scales import VIEW_SCALE_Z, _agrees, scaled_samples, view_scale_check
from tests.scenes import agreement_inputs, make_scanset, pair_hit_cases, scan_ring, spheres_scene

CFG = AgreementConfig()


@pytest.fixture(scope="module")
def ring():
    return make_scanset(spheres_scene(), scan_ring(16, 128, 96), noise=0.0005)


def _drift(n: int, k: float, seed: int = 3) -> np.ndarray:
    return np.exp(np.random.default_rng(seed).uniform(np.log(1 - k), np.log(1 + k), n))


def _check(scans):
    samples, cams, best = agreement_inputs(scans, CFG)
    return view_scale_check(samples, cams, CFG, best)


def test_right_depth_agrees_at_one_scale(ring):
    rec = _check(ring.scans)
    assert rec["status"] == "one scale" and rec["z"] < VIEW_SCALE_Z and rec["spread"] < 0.005, rec


def test_drifting_depth_is_named_with_each_views_factor(ring):
    """Every view's depth times its own factor within 15 %: named, each factor undoing its view's within 1 %, and
    the points then agreeing as the right capture's do."""
    drift = _drift(len(ring.scans), 0.15)
    rec = _check([replace(s, depth=(s.depth * f).astype(np.float32)) for s, f in zip(ring.scans, drift)])
    assert rec["status"] == "view scales" and rec["z"] >= VIEW_SCALE_Z, rec
    err = np.log(np.asarray(rec["factors"]) * drift)
    assert np.abs(err).max() < 0.01, err
    assert rec["share"] == pytest.approx(_check(ring.scans)["share"], abs=0.03), rec
    assert "its own scale" in rec["message"], rec


def test_agrees_at_equal_scales_is_pair_hits(ring):
    scans, s = ring.scans, np.array([0.96, 1.0, 1.03])
    for i, j, a, b, want in pair_hit_cases(scans, CFG.points, ((0, 1), (5, 4), (9, 10)), s, CFG.rel):
        assert np.array_equal(_agrees(a[0], s, scans[i].camera, scans[j].camera, b, s, CFG.rel), want)


def test_agrees_with_two_scales_is_the_depth_maps_scaled(ring):
    """View i's depth times a and view j's times b, against the maps themselves scaled and sampled again."""
    scans = ring.scans
    for i, j, a, b in ((0, 1, 0.9, 1.1), (7, 6, 1.05, 0.97)):
        si = view_sample(scans[i].depth * a, scans[i].camera, CFG.points, i)
        sj = view_sample(scans[j].depth * b, scans[j].camera, CFG.points, j)
        want, _ = pair_hits(si[0], scans[i].camera, scans[j].camera, sj[1], sj[2], np.ones(1), CFG.rel)
        raw_i = view_sample(scans[i].depth, scans[i].camera, CFG.points, i)
        raw_j = view_sample(scans[j].depth, scans[j].camera, CFG.points, j)
        got = _agrees(raw_i[0], np.array([a]), scans[i].camera, scans[j].camera, raw_j, np.array([b]), CFG.rel)
        assert np.mean(got == want) > 0.995  # float32 maps: a point on the 1 % edge may fall either way


def test_scaled_samples_scale_points_and_maps(ring):
    smp = [view_sample(s.depth, s.camera, 50, i) for i, s in enumerate(ring.scans[:3])]
    out = scaled_samples(smp, np.array([0.5, 1.0, 2.0]))
    for (p, m, st), (q, n, su), k in zip(smp, out, (0.5, 1.0, 2.0)):
        assert st == su and np.allclose(q, p * k) and np.allclose(n, m * k)

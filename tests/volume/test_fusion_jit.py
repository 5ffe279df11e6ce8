"""The numba fusion passes (volume.fusion_jit) against the numpy reference passes (volume.fusion).

Both do the same float32 arithmetic in a different order (numpy: matmul / einsum; numba:
scalar), so a voxel whose projection lands within rounding of a pixel edge, or a sample pair
within rounding of an agreement threshold, may differ.  Stated tolerances: at most 0.1 % of
the pass-1 counts differ, by one vote; at most 0.2 % of the band voxels change their pass-2
decision; the per-voxel float64 loop (consensus_reference) agrees with the numba pass on all
but 0.5 % of the voxels tried.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from tests.scenes import furball_scene, make_scanset
from tests.scenes import scan_ring as ring_cameras
from volume.completion import complete_sdf
from volume.fusion import (
    NEAR_SLACK,
    PROJ_FACTOR,
    FusionConfig,
    _centers_of,
    carve_field,
    carve_votes,
    completed,
    consensus_band,
    fuse_consensus,
    gather_samples,
    scan_maps,
)
from volume.fusion_jit import consensus_jit, pack_maps
from volume.fusion_reference import consensus_reference
from volume.grid import cube_for_bounds
from volume.pyramid import discontinuity_fraction

L = 32


@pytest.fixture(scope="module")
def fur():
    """A noisy fur ball (holes, outliers): many near samples that disagree."""
    ss = make_scanset(furball_scene(n=150), ring_cameras(12, 96, 72), noise=0.001, holes=0.05, outliers=0.005)
    origin, ext = cube_for_bounds(ss.bounds)
    cfg = FusionConfig(backend="numpy")
    maps = [scan_maps(s, cfg.max_grazing_deg, cfg.smooth_sigma_z) for s in ss.scans]
    return ss, origin, ext, cfg, maps


def test_pass1_votes_match_numpy(fur):
    ss, origin, ext, cfg, maps = fur
    w = ext / L
    for voxels in (None, np.arange(0, L ** 3, 3, dtype=np.int64)):
        a = carve_votes(maps, origin, w, L, cfg.trunc(w), cfg.agree(w), voxels, backend="numpy")
        b = carve_votes(maps, origin, w, L, cfg.trunc(w), cfg.agree(w), voxels, backend="numba")
        for name, x, y in zip(("free", "nodata", "occluded", "seen", "near"), a, b):
            assert x.shape == y.shape and y.dtype == np.uint8
            assert x.sum() > 0, name
            diff = np.abs(x.astype(np.int32) - y)
            assert np.mean(diff > 0) <= 1e-3 and diff.max() <= 1, name
    assert PROJ_FACTOR > 0 and NEAR_SLACK > 0


def _band(fur):
    ss, origin, ext, cfg, maps = fur
    w = ext / L
    coarse = fuse_consensus(ss, origin, 2 * w, L // 2, cfg, maps)
    _, seen, near = carve_field(maps, origin, w, L, cfg, coarse)
    cand = np.nonzero(near)[0]
    return cand, seen[cand].astype(np.int32), w


def test_pass2_matches_numpy_and_the_per_voxel_reference(fur):
    ss, origin, ext, cfg, maps = fur
    cand, n_obs, w = _band(fur)
    assert len(cand) > 2000
    trunc = cfg.trunc(w)
    xc = _centers_of(cand, origin, w, L)
    a = consensus_band(maps, xc, trunc, cfg, w, n_obs)
    b = consensus_jit(pack_maps(maps), cand, origin, w, L, n_obs, trunc, PROJ_FACTOR, cfg.agree(w),
                      cfg.agree_normal_deg, cfg.quorum)
    same = (a[0] == b[0]) & (a[3] == b[3]) & ((a[2] == b[2]) | ~a[0])
    assert np.mean(~same) <= 2e-3
    assert a[0].sum() > 100 and a[3].sum() > a[0].sum()  # both outcomes occur
    close = same & (np.abs(a[4] - b[4]) <= 1e-6) & ((np.abs(a[1] - b[1]) <= 1e-6) | ~a[0])
    assert np.mean(close) >= 0.995
    # the float64 per-voxel loop, on a sample of voxels
    pick = np.random.default_rng(0).choice(len(cand), 400, replace=False)
    r = consensus_reference(*gather_samples(maps, xc[pick], trunc), n_obs[pick], cfg, w)
    agree = (r[0] == b[0][pick]) & (r[3] == b[3][pick]) & (np.abs(r[4] - b[4][pick]) <= 1e-5)
    agree &= (np.abs(r[1] - b[1][pick]) <= 1e-5) | ~r[0]
    assert np.mean(agree) >= 0.995


def test_fused_levels_match_numpy_backend(fur):
    ss, origin, ext, cfg, maps = fur
    packed = pack_maps(maps)
    out = {}
    for backend, m in (("numpy", maps), ("numba", packed)):
        c = replace(cfg, backend=backend)
        coarse = None
        for res in (8, 16, L):
            coarse = fuse_consensus(ss, origin, ext / res, res, c, m, coarse=coarse)
        out[backend] = coarse
    a, b = out["numpy"], out["numba"]
    assert np.mean(a.band != b.band) <= 1e-3 and np.mean(a.near_mask != b.near_mask) <= 1e-3
    assert np.mean(np.abs(a.values - b.values) > 1e-5) <= 0.01
    fa = discontinuity_fraction(a.measured, a.voxel_size, 1.5, a.measured_mask)
    fb = discontinuity_fraction(b.measured, b.voxel_size, 1.5, b.measured_mask)
    assert fb == pytest.approx(fa, rel=0.02, abs=1e-4)


def test_deferred_completion_equals_the_direct_one(fur):
    ss, origin, ext, cfg, maps = fur
    w = ext / 16
    direct = fuse_consensus(ss, origin, w, 16, cfg, maps)
    lazy = fuse_consensus(ss, origin, w, 16, cfg, maps, complete=False)
    assert lazy.values is None and lazy.pending is not None
    np.testing.assert_array_equal(lazy.measured, direct.measured)  # what Eq. 1 reads is there already
    done = completed(lazy, cfg.backend)
    assert done.pending is None and completed(done) is done
    np.testing.assert_array_equal(done.values, direct.values)


def test_edt_completion_matches_scipy():
    """The multi-label ``edt`` transform against scipy's, one transform per side (float32 rounding)."""
    rng = np.random.default_rng(3)
    n, w = 40, 0.004
    g = np.indices((n, n, n)).transpose(1, 2, 3, 0) - n / 2
    outside = (np.linalg.norm(g, axis=-1) > 11) & (np.abs(g[..., 0] - 7) > 3)  # a ball with a slot cut
    band = rng.random((n, n, n)) < 0.02
    bvals = np.where(outside, 1, -1) * rng.uniform(0, w, (n, n, n)).astype(np.float32)
    a = complete_sdf(bvals, band, outside, w, "numpy")
    b = complete_sdf(bvals, band, outside, w, "numba")
    assert b.dtype == np.float32 and np.array_equal(b[band], bvals[band])
    np.testing.assert_allclose(b, a, rtol=0, atol=1e-6 * n * w)
    for empty in (np.ones_like(outside), np.zeros_like(outside)):  # one sign only: the same far value
        none = np.zeros_like(band)
        np.testing.assert_array_equal(complete_sdf(bvals, none, empty, w, "numba"),
                                      complete_sdf(bvals, none, empty, w, "numpy"))


def test_edt_threads_give_the_same_distances(monkeypatch):
    """volume.completion.EDT_THREADS: the edt transform on two threads (and three) against one thread
    (the reference), bit for bit, on a volume whose lines differ."""
    import volume.completion as comp

    rng = np.random.default_rng(5)
    n, w = 48, 0.004
    g = np.indices((n, n, n)).transpose(1, 2, 3, 0) - n / 2
    outside = (np.linalg.norm(g * [1.0, 1.3, 0.8], axis=-1) > 13) ^ (rng.random((n, n, n)) < 0.01)
    band = rng.random((n, n, n)) < 0.02
    bvals = np.where(outside, 1, -1) * rng.uniform(0, w, (n, n, n)).astype(np.float32)
    out = {}
    for threads in (1, 2, 3):
        monkeypatch.setattr(comp, "EDT_THREADS", threads)
        assert comp.edt_threads() == threads
        out[threads] = complete_sdf(bvals, band, outside, w, "numba")
    for threads in (2, 3):
        np.testing.assert_array_equal(out[threads].view(np.uint32), out[1].view(np.uint32))


def test_backend_is_validated():
    with pytest.raises(ValueError, match="backend"):
        FusionConfig(backend="cuda")


def test_passes_on_threads_equal_one_thread(fur, monkeypatch):
    """volume.fusion_jit's chunks of voxels side by side (FUSE_THREADS, issue 32 round 6): the same
    votes and consensus, bit for bit, as one thread (each voxel's are its own)."""
    from volume import fusion_jit
    from volume.fusion_jit import carve_votes_jit

    ss, origin, ext, cfg, maps = fur
    cand, n_obs, w = _band(fur)
    pm = pack_maps(maps)
    runs = []
    for threads, chunk in ((1, 1 << 19), (3, 1001)):
        monkeypatch.setattr(fusion_jit, "FUSE_THREADS", threads)
        monkeypatch.setattr(fusion_jit, "BLOCK", 4096 if threads == 1 else 97)
        votes = carve_votes_jit(pm, origin, w, L, cfg.trunc(w), cfg.agree(w), None, PROJ_FACTOR, NEAR_SLACK, chunk)
        band = consensus_jit(pm, cand, origin, w, L, n_obs, cfg.trunc(w), PROJ_FACTOR, cfg.agree(w),
                             cfg.agree_normal_deg, cfg.quorum)
        runs.append(votes + band)
    assert runs[1][4].sum() > 0 and runs[1][5].sum() > 100
    for a, b in zip(*runs, strict=True):
        assert a.dtype == b.dtype and np.array_equal(a, b)

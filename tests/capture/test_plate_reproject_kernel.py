"""The compiled plate samples (capture.plate_reproject_kernel) against the numpy reference
(capture.plate_reproject.gather_samples with fast=False), sample for sample.

Tolerance: the same samples.  The kernel follows numpy's operations one for one (its docstring);
the rotation follows this machine's OpenBLAS, so on another BLAS a sample within one rounding of a
tap's edge or of the depth test may differ: at most MAX_DIFFERENT of the samples, and every sample
both paths keep within COLOUR_TOL (linear).  Measured here: 0 different, 0.0 apart.
"""

from __future__ import annotations

import numpy as np
import pytest

from capture.plate_reproject import DEPTH_TOL, PlateSource, gather_samples
from tests import scenes

#: Share of samples whose kept / not kept may differ (another BLAS), and colour tolerance of the rest.
MAX_DIFFERENT = 1e-4
COLOUR_TOL = 1e-6


def _source(rng, width=160, height=120, dtype=np.float32):
    cam = scenes.ring_cameras(1, width, height, radius=0.5, elevations=(25.0,), fov_deg=55.0, phase_deg=17.0)[0]
    bg = rng.random((height, width)) > 0.15
    bg[40:80, 60:100] = False  # the object's region
    pts = cam.unproject(cam.pixel_grid().reshape(-1, 2), np.full(width * height, 0.9)).reshape(height, width, 3)
    z = cam.world_to_cam(pts)[..., 2].astype(np.float32)
    depth = np.where(rng.random((height, width)) < 0.2, 0.0, z * rng.uniform(0.99, 1.01, z.shape)).astype(np.float32)
    depth[:10] = 50.0  # far: a wall beyond the focus
    linear = rng.random((height, width, 3)).astype(dtype)  # the pipeline's views are float16
    return cam, PlateSource(cam, linear, bg, depth, np.array([1.1, 0.9, 1.05]), 0.8)


def _points(rng, cam, n=60000):
    """World points seen by ``cam`` (most inside its image, at the depth it measured or not), some
    behind it, some outside its image, some at infinity."""
    px = np.stack([rng.uniform(-20, cam.width + 20, n), rng.uniform(-20, cam.height + 20, n)], 1)
    z = np.where(rng.random(n) < 0.5, 0.9 * rng.uniform(0.98, 1.02, n), rng.uniform(-1.0, 3.0, n))
    z[rng.random(n) < 0.1] = 1e6
    return cam.unproject(px, z)


@pytest.mark.parametrize("dtype", [np.float16, np.float32])
@pytest.mark.parametrize("kind", ["plane", "room", "far"])
def test_compiled_samples_are_numpys(kind, dtype):
    rng = np.random.default_rng(11)
    cam, src = _source(rng, dtype=dtype)
    pts = _points(rng, cam)
    gain_i = np.array([0.95, 1.0, 1.2])
    want = gather_samples(pts, kind, src, gain_i, fast=False)
    got = gather_samples(pts, kind, src, gain_i, fast=True)
    assert 0.05 < np.isfinite(want[:, 0]).mean() < 0.95  # the case tests both outcomes
    _same(got, want)


def _same(got, want):
    kept_w, kept_g = np.isfinite(want[:, 0]), np.isfinite(got[:, 0])
    assert np.mean(kept_w != kept_g) <= MAX_DIFFERENT, np.mean(kept_w != kept_g)
    both = kept_w & kept_g
    np.testing.assert_allclose(got[both], want[both], rtol=0, atol=COLOUR_TOL)


def test_the_depth_test_is_the_references_at_its_edge():
    """Points exactly at the depth tolerance's edge and the far threshold: both paths decide alike."""
    rng = np.random.default_rng(5)
    cam, src = _source(rng)
    px = np.stack([rng.uniform(0, cam.width - 1, 4000), rng.uniform(0, cam.height - 1, 4000)], 1)
    d = src.depth[np.clip(np.floor(px[:, 1] + 0.5).astype(int), 0, cam.height - 1),
                  np.clip(np.floor(px[:, 0] + 0.5).astype(int), 0, cam.width - 1)].astype(np.float64)
    z = np.where(d > 0, d / (1.0 + DEPTH_TOL * rng.choice([-1.0, 1.0], len(d))), 0.5)
    pts = cam.unproject(px, z)
    for kind in ("plane", "room", "far"):
        want = gather_samples(pts, kind, src, np.ones(3), fast=False)
        got = gather_samples(pts, kind, src, np.ones(3), fast=True)
        assert 0.05 < np.isfinite(want[:, 0]).mean() < 0.95, kind
        _same(got, want)


@pytest.mark.parametrize("dtype", [np.float16, np.float32])
def test_compiled_plate_is_numpys(dtype):
    """reproject_plate in one compiled pass (hypotheses in order, every source's sample, the median)
    against numpy's, on three sources (two float16 of the same size, one not) over random points."""
    from capture.plate_reproject import reproject_plate

    rng = np.random.default_rng(2)
    sources = [_source(rng, dtype=dtype)[1] for _ in range(3)]
    cam = sources[0].camera
    pix = np.stack([rng.integers(0, cam.width, 30000), rng.integers(0, cam.height, 30000)], 1)
    room = np.where(rng.random((cam.height, cam.width)) < 0.3, 0.0, rng.uniform(0.85, 0.95, (cam.height, cam.width)))
    plane = np.array([0.0, 0.0, 1.0, 0.12])
    gain_i = np.array([1.0, 0.9, 1.1])
    want = reproject_plate(cam, pix, gain_i, sources, plane, room, fast=False)
    got = reproject_plate(cam, pix, gain_i, sources, plane, room, fast=True)
    assert 0.05 < want[1].mean() < 0.95 and (want[2] > 1).any()  # known and not, and medians of several
    assert np.mean(want[1] != got[1]) <= MAX_DIFFERENT
    both = want[1] & got[1]
    np.testing.assert_allclose(got[0][both], want[0][both], rtol=0, atol=COLOUR_TOL)
    assert np.mean(want[2] != got[2]) <= MAX_DIFFERENT


def test_compiled_panorama_plates_are_numpys(monkeypatch):
    """The orbit scene's panorama plates (tests/plate_scenes.py) with the compiled samples and without."""
    import capture.plate_reproject as pr
    from capture.plate import PlateConfig, background_plates
    from tests import plate_scenes as ps

    views, _ = ps.orbit_capture()
    plane = np.array([0.0, 0.0, 1.0, -ps.TABLE_Z])
    out = {}
    for fast in (False, True):
        monkeypatch.setattr(pr, "GATHER_COMPILED", fast)
        out[fast] = background_plates(views, PlateConfig(mode="panorama"), plane)
    for a, b in zip(out[False][0], out[True][0], strict=True):
        assert np.mean(a.known != b.known) <= MAX_DIFFERENT
        np.testing.assert_allclose(b.background, a.background, rtol=0, atol=COLOUR_TOL)
    assert out[False][1] == out[True][1]


@pytest.mark.parametrize("fast", [True, False])
@pytest.mark.parametrize("dropped", [True, False])
def test_blown_out_samples_do_not_count_for_a_darker_view(monkeypatch, fast, dropped):
    """A source's blown-out pixels (CLIP_LEVEL) lend no sample to a view of a darker exposure
    (CLIPPED_SOURCES_DROPPED: the true background there is brighter than the clipped value times the gain
    ratio says), and lend it as before to a view of the same or a brighter exposure; with the switch off
    (the rule before) they count everywhere, and the first assert fails."""
    import capture.plate_reproject as pr

    monkeypatch.setattr(pr, "CLIPPED_SOURCES_DROPPED", dropped)
    rng = np.random.default_rng(2)
    cam, src = _source(rng, dtype=np.float16)
    lin = np.asarray(src.linear, np.float32).copy() * 0.5
    lin[:, : cam.width // 2] = 1.0  # the left half blown out
    src = PlateSource(cam, lin.astype(np.float16), src.background, src.depth, np.ones(3), src.focus_far)
    pts = _points(rng, cam)
    uv, _ = cam.project(pts)
    left = uv[:, 0] < cam.width // 2 - 2
    darker = gather_samples(pts, "far", src, np.array([1.0, 1.25, 1.0]), fast=fast)  # g_j / g_i 0.8 in green
    same = gather_samples(pts, "far", src, np.ones(3), fast=fast)
    assert (np.isfinite(darker[left, 0]).sum() == 0) == dropped
    assert np.isfinite(same[left, 0]).sum() > 100  # the same exposure: blown out, as before
    right = ~left & (uv[:, 0] > cam.width // 2 + 2)
    np.testing.assert_array_equal(np.isfinite(darker[right, 0]), np.isfinite(same[right, 0]))


def test_compiled_median_and_count_are_numpys():
    """Each pixel's median and sample count (capture.plate_reproject_kernel.median_count) against numpy's
    (nan_median over the sources, isfinite summed), bit for bit: 1-8 sources, pixels with none, ties and
    equal values among the samples; odd and even counts."""
    from capture.plate_reproject import nan_median
    from capture.plate_reproject_kernel import median_count

    rng = np.random.default_rng(5)
    K, N = 8, 20000
    s = rng.integers(0, 50, (K, N, 3)).astype(np.float32) / 49.0  # few distinct values: ties
    s[:, : N // 2] = rng.random((K, N // 2, 3), dtype=np.float32)
    s[rng.random((K, N)) < rng.random(N)] = np.nan  # every share of missing sources, all of them on some pixels
    med, cnt = np.empty((N, 3), np.float32), np.empty(N, np.int64)
    median_count(s, med, cnt)
    have = np.isfinite(s[..., 0])
    got = have.any(axis=0)
    assert 0.02 < np.mean(~got) < 0.5 and len(set(cnt[got] % 2)) == 2
    np.testing.assert_array_equal(cnt, have.sum(axis=0))
    np.testing.assert_array_equal(med[got], nan_median(s[:, got]))
    assert np.isnan(med[~got]).all()


@pytest.mark.parametrize("dtype", [np.float16, np.float32])
def test_plate_with_the_compiled_median_is_numpys(monkeypatch, dtype):
    """reproject_plate with MEDIAN_COMPILED on and off: the same colours, known pixels and counts, bit for bit."""
    import capture.plate_reproject as pr

    rng = np.random.default_rng(3)
    sources = [_source(rng, dtype=dtype)[1] for _ in range(4)]
    cam = sources[0].camera
    pix = np.stack([rng.integers(0, cam.width, 30000), rng.integers(0, cam.height, 30000)], 1)
    room = np.where(rng.random((cam.height, cam.width)) < 0.3, 0.0, rng.uniform(0.85, 0.95, (cam.height, cam.width)))
    out = {}
    for on in (False, True):
        monkeypatch.setattr(pr, "MEDIAN_COMPILED", on)
        plane = np.array([0.0, 0.0, 1.0, 0.12])
        out[on] = pr.reproject_plate(cam, pix, np.array([1.0, 0.9, 1.1]), sources, plane, room)
    assert 0.05 < out[True][1].mean() < 0.95 and (out[True][2] > 2).any()
    for a, b in zip(out[False], out[True], strict=True):
        np.testing.assert_array_equal(a, b)


def test_the_kernel_comes_from_numbas_cache_in_a_new_process(tmp_path):
    """A second process finds gather_kernel in numba's on-disk cache instead of compiling it again (it took
    the texel reader as a function argument, whose numba type differs in every process: 0.8-0.95 s of
    compiling in every `furrow model`, and one more cache entry each time)."""
    import json
    import os
    import subprocess
    import sys
    from pathlib import Path

    code = (
        "import json, numpy as np\n"
        "from tests.capture.test_plate_reproject_kernel import _source, _points\n"
        "from capture.plate_reproject import gather_samples\n"
        "from capture.plate_reproject_kernel import gather_kernel\n"
        "rng = np.random.default_rng(0)\n"
        "for dtype in (np.float16, np.float32):\n"
        "    cam, src = _source(rng, dtype=dtype)\n"
        "    gather_samples(_points(rng, cam, 1000), 'far', src, np.array([1.0, 1.25, 1.0]), fast=True)\n"
        "s = gather_kernel.stats\n"
        "print(json.dumps([sum(s.cache_hits.values()), sum(s.cache_misses.values())]))\n")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    root = str(Path(__file__).resolve().parents[2])
    runs = [json.loads(subprocess.run([sys.executable, "-c", code], env=env, cwd=root, check=True,
                                      capture_output=True, text=True).stdout.splitlines()[-1]) for _ in range(2)]
    assert runs[0][1] == 2  # the first process compiles both kinds of view (and writes them to the cache)
    assert runs[1] == [2, 0]  # the second loads both and compiles nothing

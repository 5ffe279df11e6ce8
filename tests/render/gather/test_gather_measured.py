"""Gather's measured depth first (render/gather/reference.py step 1): the points whose depth the
capture measured win the z-buffer over the geometry's fill; by hand, on the GPU against the twin
(test_gather's tolerances), and the same frames from the compact and the dense store."""

from __future__ import annotations

import numpy as np
import pytest

from capture.camera import Camera, make_K
from render.gather import reference as gr
from render.points import reference as pr
from tests import scenes as scene
from tests.render.gather.test_gather import assert_frame_matches_twin
from volume.model import RgbzImages

EYES = [(2, 17.0), (7, 10.0)]


def _fill_mask(depth: np.ndarray, seed: int = 0, block: int = 6, share: float = 0.4) -> np.ndarray:
    """(N, H, W) bool measured mask: seeded ``block`` x ``block`` pixel tiles (``share`` of them) are
    the fill, the rest of the depth measured."""
    rng = np.random.default_rng(seed)
    n, H, W = depth.shape
    tiles = rng.random((n, -(-H // block), -(-W // block))) >= share
    return np.repeat(np.repeat(tiles, block, 1), block, 2)[:, :H, :W] & (depth > 0)


@pytest.fixture(scope="module")
def model():
    m = scene.build_model(scene.ring_cameras(12))
    r = m.rgbz
    from dataclasses import replace

    # push the fill 4 cm towards its camera: it lies in front of measured points of the other view
    meas = _fill_mask(np.asarray(r.depth))
    d = np.asarray(r.depth, np.float32)
    d = np.where(meas | (d <= 0), d, d - 0.04).astype(np.float32)
    return replace(m, rgbz=RgbzImages(np.asarray(r.rgb, np.float32), d, r.cameras, measured=meas))


def _eye(i, phase):
    return scene.ring_cameras(12, phase_deg=phase, elevations=(12,))[i]


def _twin(eye, m, cfg):
    r = m.rgbz
    clouds = pr.back_project(r.cameras, r.rgb, r.depth)
    return gr.gather_frame(eye, clouds, r.cameras, r.rgb, r.depth, m.bounds.mean(0), cfg, measured=r.measured)


def test_measured_first_by_hand():
    """A measured point behind a fill point in the same pixel keeps the pixel; where only fill lands,
    the fill's depth."""
    cam = Camera(make_K(20.0, 20.0, 9.5, 7.5), np.eye(4), 20, 16, "c")
    meas = np.zeros((1, 16, 20), np.float32)
    fill = np.zeros((1, 16, 20), np.float32)
    meas[0, 5, 5] = 1.0
    fill[0, 5, 5] = 0.5
    fill[0, 10, 12] = 0.7
    rgb = np.ones((1, 16, 20, 3), np.float32)
    cm, cf = pr.back_project([cam], rgb, meas), pr.back_project([cam], rgb, fill)
    z, n = gr.measured_first_depth(cam, cm, cf, 1)
    assert n == 3 and z[5, 5] == pytest.approx(1.0) and z[10, 12] == pytest.approx(0.7)
    assert np.count_nonzero(z) == 2
    z1, _ = gr.front_depth(cam, cm + cf, 1)  # one z-buffer: the fill in front wins
    assert z1[5, 5] == pytest.approx(0.5)


@pytest.mark.parametrize("i,phase", EYES)
def test_gpu_matches_twin_with_measured(gl_ctx, model, i, phase):
    from render.gather.gl import GatherRenderer

    eye = _eye(i, phase)
    cfg = gr.GatherConfig()
    rgb, cov, depth, n = _twin(eye, model, cfg)
    old = _twin(eye, model, gr.GatherConfig(measured_first=False))
    both = (cov > 0) & (old[1] > 0)
    moved = both & (np.abs(depth - old[2]) > 0.01)
    assert moved.sum() > 0.02 * both.sum(), "the fill hides measured points in one z-buffer"
    assert np.all(depth[moved] > old[2][moved])  # where the rule acts, the measured point lies behind
    with GatherRenderer.from_model(gl_ctx, model, config=cfg) as r:
        fr = r.render(eye)
    assert fr.stats.facets == n > 0
    assert_frame_matches_twin(fr, rgb, cov, depth)
    with GatherRenderer.from_model(gl_ctx, model, config=gr.GatherConfig(measured_first=False)) as r:
        assert_frame_matches_twin(r.render(eye), *old[:3])


def test_compact_store_renders_the_dense_frames_with_measured(gl_ctx, model):
    from render.gather.gl import GatherRenderer

    comp = scene.compact(model, margin=0)
    np.testing.assert_array_equal(comp.rgbz.measured, model.rgbz.measured)
    frames = []
    for m in (comp, scene.densified(comp)):
        with GatherRenderer.from_model(gl_ctx, m) as r:
            frames.append([r.render(_eye(i, p)) for i, p in EYES])
    for a, b in zip(*frames):
        assert a.mask.sum() > 300
        for x, y in ((a.rgb, b.rgb), (a.alpha, b.alpha), (a.depth, b.depth)):
            np.testing.assert_array_equal(x, y)

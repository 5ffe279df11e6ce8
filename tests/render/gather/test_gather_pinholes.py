"""Gather's single-pixel depth holes (render/gather/reference.py, fill_pinholes): by hand, and the
GLSL against the twin where the splats leave many of them (1 x 1 splats)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from render.gather import reference as gr
from render.points import reference as pr
from tests import scenes as scene
from tests.render.gather.test_gather import assert_frame_matches_twin


def test_fill_pinholes_by_hand():
    z = np.full((6, 7), 0.5)
    z[2, 3] = 0.0                                    # a pinhole: 4 neighbours 0.5, 0.5, 0.5, 0.504
    z[2, 4] = 0.504
    z[4, 1] = 0.0                                    # at a depth edge: neighbours 0.5 and 0.52
    z[5, 1] = 0.52
    z[0, 5] = 0.0                                    # on the border
    z[4, 4:6] = 0.0                                  # two pixels wide
    out = gr.fill_pinholes(z, 0.01)
    assert out[2, 3] == pytest.approx(0.501, abs=1e-6)
    assert out[4, 1] == 0 and out[0, 5] == 0 and np.all(out[4, 4:6] == 0)
    assert np.array_equal(np.delete(out.ravel(), 2 * 7 + 3), np.delete(z.ravel(), 2 * 7 + 3))
    assert gr.fill_pinholes(z, 0.03)[4, 1] == pytest.approx(0.505, abs=1e-6)   # the edge within a wider spread
    assert gr.fill_pinholes(z, 0.0) is z                                       # off: unchanged
    assert gr.fill_pinholes(np.zeros((2, 2)), 0.01).sum() == 0                 # too small to hold one


def test_config_refuses_a_negative_spread():
    with pytest.raises(ValueError, match="pinhole_spread_m"):
        gr.GatherConfig(pinhole_spread_m=-0.01)


@pytest.fixture(scope="module")
def model():
    return scene.build_model(scene.ring_cameras(12))


@pytest.mark.parametrize("resample", ["linear", "cubic"])
def test_gpu_fills_the_twins_pinholes(gl_ctx, model, resample):
    """1 x 1 splats of 96 x 72 views seen by a 120 x 90 eye leave pinholes (about 100): the twin fills some (the frame
    without the fill leaves them empty), the GPU draws the twin's frame, filled pixels included,
    within test_gather's tolerances, and without the fill the GPU leaves them empty too."""
    from render.gather.gl import GatherRenderer

    eye = scene.ring_cameras(12, width=120, height=90, phase_deg=10.0, elevations=(12,))[3]
    cfg = gr.GatherConfig(splat_px=1, resample=resample)
    off = dataclasses.replace(cfg, pinhole_spread_m=0.0)
    clouds = pr.back_project(model.rgbz.cameras, model.rgbz.rgb, model.rgbz.depth)
    args = (eye, clouds, model.rgbz.cameras, model.rgbz.rgb, model.rgbz.depth, model.bounds.mean(0))
    rgb, a, depth, _ = gr.gather_frame(*args, cfg)
    _, a0, _, _ = gr.gather_frame(*args, off)
    filled = (a > 0) & (a0 == 0)
    assert filled.sum() >= 50, "the 1 x 1 splats leave pinholes the fill takes"
    assert np.all(a0[a == 0] == 0), "the fill only adds pixels"
    with GatherRenderer.from_model(gl_ctx, model, config=cfg) as r:
        fr = r.render(eye)
    with GatherRenderer.from_model(gl_ctx, model, config=off) as r0:
        fr0 = r0.render(eye)
    assert_frame_matches_twin(fr, rgb, a, depth)
    assert np.mean(fr.mask[filled]) > 0.9 and np.mean(fr0.mask[filled]) < 0.1
    both = fr.mask & filled
    same = np.abs(fr.depth[both] - depth[both]) <= 1e-5 * depth[both]
    assert same.mean() >= 0.9   # a neighbour's depth may differ where llvmpipe breaks a splat's tie (test_gather)

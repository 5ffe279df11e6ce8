"""Gather's fine depth (GatherConfig.fine_depth, render.gather.fine_depth): 1-pixel splats first, by hand; the GPU
against the twin with it on and off; "auto" by the kept mattes' share of partial pixels."""

from __future__ import annotations

import numpy as np
import pytest

from render.gather import fine_depth as fd
from render.gather import reference as gr
from render.points import reference as pr
from tests import scenes as scene
from tests.render.gather.test_gather import assert_frame_matches_twin, twin_and_gpu_with_matte


def test_fine_depth_by_hand():
    """A near point at (2, 3) and a far one at (1, 2), inside the near one's 2 x 2 splat: the splats give the far
    point's pixel the near z, fine depth gives it its own; pixels only a wide splat covers keep it."""
    eye = scene.ring_cameras(1, 8, 6, elevations=(0.0,), azimuths=(0.0,))[0]
    uv, z = np.array([[2.0, 3.0], [1.0, 2.0]]), np.array([0.40, 0.50])
    cloud = pr.Cloud(eye.unproject(uv, z), np.zeros((2, 3)))
    wide, n = gr.front_depth(eye, [cloud], 2)
    fine, n_fine = gr.front_depth(eye, [cloud], 2, fine=True)
    assert n == n_fine == 2
    assert wide[2, 1] == pytest.approx(0.40) and fine[2, 1] == pytest.approx(0.50)   # (x 1, y 2): the far point's own
    for y, x, want in ((3, 2, 0.40), (2, 2, 0.40), (1, 0, 0.50), (3, 1, 0.40)):
        assert wide[y, x] == pytest.approx(want) and fine[y, x] == pytest.approx(want), (y, x)
    assert np.array_equal(wide > 0, fine > 0)   # the same coverage
    np.testing.assert_array_equal(gr.front_depth(eye, [cloud], 1, fine=True)[0], gr.front_depth(eye, [cloud], 1)[0])


@pytest.fixture(scope="module")
def alpha_model():
    m = scene.build_model(scene.ring_cameras(12))
    return scene.with_alpha(m, scene.soft_matte(m.rgbz.depth))


@pytest.mark.parametrize("mode, i, phase", [("on", 2, 17.0), ("on", 7, 10.0), ("off", 7, 10.0)])
def test_gpu_matches_twin_with_fine_depth(gl_ctx, alpha_model, mode, i, phase):
    m = alpha_model
    eye = scene.ring_cameras(12, phase_deg=phase, elevations=(12,))[i]
    (rgb, a, depth), fr, back = twin_and_gpu_with_matte(gl_ctx, m, eye, gr.GatherConfig(fine_depth=mode))
    assert fd.use_fine(mode, m.rgbz.alpha) == (mode == "on")
    assert_frame_matches_twin(fr, rgb, a, depth, back)
    if mode == "on":   # it changes the frame: the twin's depth differs from the wide splats' somewhere
        clouds = pr.back_project(m.rgbz.cameras, m.rgbz.rgb, m.rgbz.depth)
        wide = gr.gather_frame(eye, clouds, m.rgbz.cameras, m.rgbz.rgb, m.rgbz.depth, m.bounds.mean(0),
                               gr.GatherConfig(fine_depth="off"), alpha=m.rgbz.alpha)[2]
        assert np.count_nonzero(np.abs(wide - depth) > 1e-6) > 20


def test_auto_by_the_share_of_partial_pixels():
    rng = np.random.default_rng(0)
    crown = [np.where(rng.random((20, 30)) < 0.5, rng.uniform(0.1, 0.9, (20, 30)), 0.0) for _ in range(5)]
    body = [np.where(rng.random((20, 30)) < 0.5, np.where(rng.random((20, 30)) < 0.8, 1.0, 0.5), 0.0)
            for _ in range(5)]
    assert fd.partial_share(crown) == pytest.approx(1.0) and fd.partial_share(body) == pytest.approx(0.2, abs=0.05)
    assert fd.use_fine("auto", crown) and not fd.use_fine("auto", body)
    assert fd.use_fine("auto", lambda k: crown[k], 5) and not fd.use_fine("auto", lambda k: body[k], 5)
    assert not fd.use_fine("auto", None)   # no matte: the wide splats
    assert fd.use_fine("on", None) and not fd.use_fine("off", crown)
    assert np.isnan(fd.partial_share([np.zeros((4, 4)), None]))
    with pytest.raises(ValueError, match="fine_depth"):
        gr.GatherConfig(fine_depth="sometimes")

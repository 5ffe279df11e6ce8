"""Gather's coverage held to the mass of its kept views' mattes (render.gather.alpha_mass): the pieces by hand, the
excess measured leave-one-out, the GPU against the twin, and the straight colour kept."""

from __future__ import annotations

import numpy as np
import pytest

from render.gather import alpha_mass as am
from render.gather import reference as gr
from render.points import reference as pr
from tests import scenes as scene
from tests.render.gather.test_gather import COLOUR_TOL, COVERAGE_MISMATCH_FRAC, DEPTH_RTOL
from tests.render.gather.test_gather_back import _twin, trunk_model  # noqa: F401  (a fixture)

#: The rule on (GatherConfig.alpha_mass; off by default: docs/novel_views.md "Gather's alpha mass").
ON = gr.GatherConfig(alpha_mass="on")


def _frame(rng):
    """A 40 x 50 frame: an opaque block, partial pixels around it, empty edges."""
    a = np.zeros((40, 50), np.float32)
    a[10:30, 10:40] = rng.uniform(0.05, 0.95, (20, 30)).astype(np.float32)
    a[15:25, 20:30] = 1.0
    return a


def test_normalise_by_hand():
    """a - d a (1 - a) with d such that the frame sums to its drawn sum / f: 0 and 1 stay, every other pixel moves
    by d a (1 - a); f at most 1 + MIN_EXCESS, a pull over MAX_PULL or a frame without partial pixels are left as
    drawn (d = 0)."""
    a = _frame(np.random.default_rng(0))
    total, q = float(a.sum(dtype=float)), (a * (1 - a)).astype(np.float64)
    f = total / (total - 0.2 * q.sum())  # the pull 0.2 takes exactly this much
    b, d = am.normalise(a, f)
    assert d == pytest.approx(0.2, rel=1e-6) and float(b.sum(dtype=float)) == pytest.approx(total / f, rel=1e-5)
    np.testing.assert_allclose(b, a - 0.2 * q, atol=1e-6)
    ends = (a == 0) | (a == 1)
    np.testing.assert_array_equal(b[ends], a[ends])
    assert np.all(b >= 0) and np.all(b <= a)
    for g in (0.9, 1.0, 1.0 + am.MIN_EXCESS):
        c, d1 = am.normalise(a, g)
        assert d1 == 0.0 and c is a
    big = total / (total - (am.MAX_PULL + 0.05) * q.sum())
    assert am.normalise(a, big)[1] == 0.0
    solid = (a > 0).astype(np.float32)
    assert am.normalise(solid, 1.2)[1] == 0.0


def test_pull_keeps_the_straight_colour():
    """alpha_mass.pull: the alpha as :func:`normalise` pulls it, the premultiplied colour scaled with it pixel by
    pixel (rgb / alpha unchanged where alpha > 0; 0 stays 0); as drawn where there is nothing to pull."""
    rng = np.random.default_rng(1)
    a = _frame(rng)
    F = rng.uniform(0.0, 1.0, a.shape + (3,)).astype(np.float32)
    rgb = F * a[..., None]
    f = 1.06
    rgb2, a2, d = am.pull(rgb, a, f)
    np.testing.assert_array_equal(a2, am.normalise(a, f)[0])
    assert d > 0 and float(rgb2.sum()) < float(rgb.sum())
    drawn = a > 0
    np.testing.assert_allclose(rgb2[drawn] / a2[drawn][:, None], F[drawn], rtol=1e-5, atol=1e-6)
    np.testing.assert_array_equal(rgb2[~drawn], 0)
    rgb3, a3, d3 = am.pull(rgb, a, 1.0)
    assert d3 == 0.0 and rgb3 is rgb and a3 is a


def test_excess_is_the_median_ratio():
    """f = the median of drawn / own mass over the views with both positive; 1 with fewer than MIN_LOO."""
    assert am.excess([106.0, 110.0, 103.0, 0.0], [100.0, 100.0, 100.0, 100.0]) == pytest.approx(1.06)
    assert am.excess([106.0, 110.0], [100.0, 100.0]) == 1.0
    assert am.loo_views(5) == [0, 1, 2, 3, 4]
    v = am.loo_views(36)
    assert len(v) == am.LOO_VIEWS and v[0] == 0 and v[-1] == 35 and np.all(np.diff(v) >= 2)


def test_an_excess_under_one_changes_nothing(gl_ctx):
    """A few spheres with soft mattes, 6 kept views 60 degrees apart: drawn from the others, a kept view holds
    less alpha than its own matte (the twin's f 0.91), so every frame keeps the alpha it was drawn with."""
    from render.gather.gl import GatherRenderer

    cams = scene.ring_cameras(12)
    base = scene.build_model(cams[0::2])
    m = scene.with_alpha(base, scene.soft_matte(base.rgbz.depth, seed=None))
    r = m.rgbz
    f = am.loo_excess_reference(None, list(r.cameras), np.asarray(r.rgb), np.asarray(r.depth), m.bounds.mean(0),
                                ON, np.asarray(r.alpha))
    assert f < 1.0
    with GatherRenderer.from_model(gl_ctx, m, config=ON) as ren, \
            GatherRenderer.from_model(gl_ctx, m, config=gr.GatherConfig(alpha_mass="off")) as ren0:
        for eye in cams[1::2]:
            fr, fr0 = ren.render(eye), ren0.render(eye)
            assert fr.stats.alpha_pull == 0.0
            np.testing.assert_array_equal(fr.alpha, fr0.alpha)
            np.testing.assert_array_equal(fr.rgb, fr0.rgb)
    assert ren.excess == pytest.approx(f, abs=0.01)


def test_gpu_matches_twin_and_keeps_the_colour(gl_ctx, trunk_model):  # noqa: F811
    """The trunk scene (tests/render/gather/test_gather_back.py; kept views 40 degrees apart, each drawn from the
    others holds 1.28 x its own matte's alpha): the GPU's excess against the twin's (within 0.01), its frame's alpha
    against the twin's given the same excess (within COLOUR_TOL where their depths agree, plus 2e-3: each frame's
    pull is measured on its own pixels, which differ at a few splat-edge ties, test_gather's
    COVERAGE_MISMATCH_FRAC); the colour pulled with the alpha, its straight colour the same with the rule as without."""
    from render.gather.gl import GatherRenderer

    m, eye, _ = trunk_model
    r = m.rgbz
    cfg, off = ON, gr.GatherConfig(alpha_mass="off")
    f = am.loo_excess_reference(None, list(r.cameras), np.asarray(r.rgb), np.asarray(r.depth), m.bounds.mean(0), cfg,
                                np.asarray(r.alpha))
    assert f > 1.2
    clouds = pr.back_project(r.cameras, r.rgb, r.depth)
    rgb, a, depth, _ = gr.gather_frame(eye, clouds, r.cameras, np.asarray(r.rgb), np.asarray(r.depth),
                                       m.bounds.mean(0), cfg, np.asarray(r.alpha), None, f)
    rgb0, a0, _, _ = _twin(m, eye, off)
    q = a0 * (1 - a0)
    part = q > 0.05
    pull = float(np.median((a0 - a)[part] / q[part]))
    assert 0 < pull <= am.MAX_PULL and np.allclose(a, a0 - pull * q, atol=1e-5)
    drawn = a0 > 0
    np.testing.assert_allclose(rgb[drawn] / a[drawn][:, None], rgb0[drawn] / a0[drawn][:, None], rtol=1e-4, atol=1e-6)
    with GatherRenderer.from_model(gl_ctx, m, config=cfg) as ren, \
            GatherRenderer.from_model(gl_ctx, m, config=off) as ren0:
        fr, fr0 = ren.render(eye), ren0.render(eye)
    assert ren.excess == pytest.approx(f, abs=0.01) and ren0.excess is None
    assert fr.stats.alpha_pull == pytest.approx(pull, abs=5e-3) and fr0.stats.alpha_pull is None
    both0 = fr0.alpha > 0
    np.testing.assert_allclose(fr.rgb[both0] / fr.alpha[both0][:, None], fr0.rgb[both0] / fr0.alpha[both0][:, None],
                               rtol=1e-4, atol=1e-6)
    assert np.mean(fr.mask != (a > 0)) <= COVERAGE_MISMATCH_FRAC
    both = fr.mask & (a > 0)
    same = both & (np.abs(fr.depth - depth) <= DEPTH_RTOL * depth)
    assert same.sum() >= 0.97 * both.sum()
    np.testing.assert_allclose(fr.alpha[same], a[same], atol=COLOUR_TOL + 2e-3)
    np.testing.assert_allclose(fr.rgb[same], rgb[same], atol=COLOUR_TOL + 2e-3)


def test_auto_pulls_only_where_every_view_was_matted_on_a_backdrop(gl_ctx, trunk_model):  # noqa: F811
    """GatherConfig.alpha_mass "auto": the renderer pulls a model whose every kept view was matted against a
    backdrop (model.json's surroundings.matte.methods: {"backdrop": N}) as "on" does, and draws any other (a plate
    among the methods, or no record) as "off" does."""
    from dataclasses import replace

    from render.gather.gl import GatherRenderer

    m, eye, _ = trunk_model
    def methods(x):
        return {"surroundings": {"matte": {"methods": x}}}
    assert am.backdrop_matted(methods({"backdrop": 4}))
    assert not am.backdrop_matted(methods({"backdrop": 3, "plate": 1})) and not am.backdrop_matted({})
    frames = {}
    for name, params in (("backdrop", methods({"backdrop": 4})), ("plate", methods({"plate": 4})), ("none", {})):
        with GatherRenderer.from_model(gl_ctx, replace(m, params=params), config=gr.GatherConfig(alpha_mass="auto")) \
                as r:
            frames[name] = (r.pulls, r.render(eye))
    with GatherRenderer.from_model(gl_ctx, m, config=ON) as r_on, \
            GatherRenderer.from_model(gl_ctx, m, config=gr.GatherConfig(alpha_mass="off")) as r_off:
        on, off = r_on.render(eye), r_off.render(eye)
    assert frames["backdrop"][0] and not frames["plate"][0] and not frames["none"][0]
    np.testing.assert_array_equal(frames["backdrop"][1].alpha, on.alpha)
    for name in ("plate", "none"):
        np.testing.assert_array_equal(frames[name][1].alpha, off.alpha)
    assert np.abs(on.alpha - off.alpha).max() > 0.01

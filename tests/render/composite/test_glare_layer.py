"""Glare (docs/methods.md §4): light-source / light-reflection / specular maps, streak pairs, the GL
fan layer (render/composite/glare_layer.py) vs its numpy twin, and streak energy conservation."""

from __future__ import annotations

import numpy as np
import pytest

from render.shading.brdf import blinn_phong_normalized
from render.shading.envmap import bundled_envmap, procedural_sky
from render.shading.glare import GlareConfig
from render.shading.glare_maps import (
    LightSources,
    glare_sources,
    light_reflection_map,
    light_source_map,
    light_sources,
    make_streaks,
    rasterize_streaks_reference,
    remove_excess,
    specular_parameter_map,
    streak_energy_on_screen,
)
from render.shading.lights import LUMA

#: GL (float32 vertices, float32 blending) vs the numpy twin, relative to the image's peak:
#: measured 3e-6 (s = 1) to 3e-5 (s = 2).
TWIN_REL_TOL = 1e-4
#: Rasterised streak light vs the highlight excess, supersample 4: measured < 0.05% for pairs
#: 1-17 px wide (n = 10 ... 1000); point sampling (s = 1) of 1 px wide pairs: 4.2%, s = 2: 0.5%.
ENERGY_TOL_S4 = 0.01


def _random_sources(n, W, H, seed=0, n_exp=100.0, lo=2.0, hi=60.0, margin=10):
    rng = np.random.default_rng(seed)
    img = np.full((H, W, 3), 0.2)
    rows = rng.integers(margin, H - margin, n)
    cols = rng.integers(margin, W - margin, n)
    img[rows, cols] = rng.uniform(lo, hi, (n, 3))
    return img, glare_sources(img, 1.0, default_n=n_exp)


# -- maps --------------------------------------------------------------------------------------
def test_light_source_map_keeps_only_bright_texels():
    env = procedural_sky(64)
    lsm = light_source_map(env, 50.0)
    lum = env.data @ LUMA
    assert np.all(lsm.data[lum < 50.0] == 0)
    np.testing.assert_array_equal(lsm.data[lum >= 50.0], env.data[lum >= 50.0])
    src = light_sources(lsm, height=32)
    # area resampling keeps the power: sum E_j = sum L Omega of the light-source map
    np.testing.assert_allclose(src.irradiance.sum(0), lsm.total_power(), rtol=1e-5)
    # the sources sit at the sun
    from render.shading.envmap import SUN_DIR, SUN_RADIUS
    w = src.irradiance @ LUMA
    mean_dir = (src.dirs * w[:, None]).sum(0)
    assert np.degrees(np.arccos(mean_dir @ SUN_DIR / np.linalg.norm(mean_dir))) < np.degrees(SUN_RADIUS)


def test_light_reflection_map_matches_brute_force():
    """Against the sum over every light-source texel of the full-resolution map."""
    env = bundled_envmap("forest")
    lsm = light_source_map(env)
    full = light_sources(lsm, height=lsm.height, max_sources=10**6)
    # views and normals around the mirror configuration of the sun
    sun = full.dirs[np.argmax(full.irradiance @ LUMA)]
    rng = np.random.default_rng(1)
    v = np.array([0.0, -1.0, 0.3])
    v /= np.linalg.norm(v)
    h = (sun + v) / np.linalg.norm(sun + v)
    nrm = h + rng.normal(0, 0.05, (8, 3))
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    spec = specular_parameter_map((1, 8), k_s=0.7, n=np.array([[5, 20, 50, 100, 200, 400, 50, 20]], float))
    got = light_reflection_map(nrm[None], np.broadcast_to(v, (1, 8, 3)), spec, light_sources(lsm))
    # brute force, independent: every texel of the map, Eq. 4
    d = lsm.pixel_directions().reshape(-1, 3)
    E = (lsm.data.astype(np.float64) * lsm.pixel_solid_angles()[..., None]).reshape(-1, 3)
    live = (E @ LUMA) > 0
    d, E = d[live], E[live]
    ref = np.zeros((8, 3))
    for k in range(8):
        hh = d + v
        hh /= np.linalg.norm(hh, axis=1, keepdims=True)
        lobe = 0.7 * blinn_phong_normalized(hh @ nrm[k], spec[0, k, 1]) * (d @ nrm[k] > 0)
        ref[k] = lobe @ E
    assert ref.max() > 0.1
    # sources resampled to 128 rows (1.4 degrees): lobes of n <= 400 (>= 5 degrees) keep 3%
    np.testing.assert_allclose(got[0], ref, rtol=0.03, atol=1e-3 * ref.max())


def test_specular_parameter_map_and_zero_ks():
    mask = np.zeros((4, 5), bool)
    mask[1:3, 1:4] = True
    spec = specular_parameter_map((4, 5), 0.5, 80.0, mask)
    assert spec.shape == (4, 5, 2) and spec.dtype == np.float32
    assert np.all(spec[~mask] == 0) and np.all(spec[mask] == [0.5, 80.0])
    with pytest.raises(ValueError):
        specular_parameter_map((2, 2), -1.0, 10.0)
    n = np.tile([0, 0, 1.0], (4, 5, 1))
    src = LightSources(np.array([[0, 0, 1.0]]), np.array([[1.0, 1.0, 1.0]]))
    lrm = light_reflection_map(n, n, spec, src)
    assert np.all(lrm[~mask] == 0)
    # N = L = V: the peak of Eq. 4, k_s E (n + 2) / (8 pi)
    np.testing.assert_allclose(lrm[mask], 0.5 * 82 / (8 * np.pi), rtol=1e-12)


# -- sources and streaks -----------------------------------------------------------------------
def test_glare_sources_and_removal_keep_pixels_in_place():
    img = np.zeros((6, 7, 3))
    img[2, 5] = [9.0, 3.0, 1.0]
    img[4, 1] = [0.5, 0.5, 0.5]
    src = glare_sources(img, 1.0)
    np.testing.assert_array_equal(src.centres, [[5.0, 2.0]])  # (u, v) OpenCV
    out = remove_excess(img, src)
    assert out[2, 5] @ LUMA == pytest.approx(1.0)  # down to display white, hue kept
    np.testing.assert_allclose(out[2, 5] / out[2, 5].sum(), img[2, 5] / img[2, 5].sum())
    np.testing.assert_allclose(out.sum((0, 1)) + src.excess.sum(0), img.sum((0, 1)))
    masked = glare_sources(img, 1.0, mask=np.zeros((6, 7), bool))
    assert len(masked.centres) == 0


def test_streak_pairs_carry_the_excess_analytically():
    img, src = _random_sources(30, 200, 150)
    st = make_streaks(src, GlareConfig())
    assert len(st) == 30 * GlareConfig().n_dirs
    np.testing.assert_allclose(st.energy.sum(0), src.excess.sum(0), rtol=1e-12)
    np.testing.assert_allclose(st.colour * (st.length * st.width)[:, None] / 3, st.energy, rtol=1e-12)
    assert st.width.min() >= 1.0 - 1e-12
    # Eq. 7: above n_g the length grows with the peak intensity, by the eyelash factor per direction
    from render.shading.glare import eyelash_factor, streak_directions
    ang = streak_directions(src.centres[:, 0], GlareConfig())
    L = st.length.reshape(30, -1) / eyelash_factor(ang)
    order = np.argsort(src.intensity)
    assert np.all(np.diff(L[order, 0]) >= -1e-9)


def test_quadrature_twin_matches_analytic_energy():
    """rasterize_streaks_reference at a fine supersampling converges to the analytic light."""
    img, src = _random_sources(5, 80, 60, seed=3)
    st = make_streaks(src, GlareConfig())
    e = streak_energy_on_screen(st, 80, 60)
    ref = rasterize_streaks_reference(st, 80, 60, supersample=8).sum((0, 1))
    np.testing.assert_allclose(ref, e, rtol=2e-3)


@pytest.mark.gl
@pytest.mark.parametrize("s", [1, 2, 4])
def test_gl_layer_matches_numpy_twin(gl_ctx, s):
    from render.composite.glare_layer import GlareLayer

    img, src = _random_sources(12, 160, 120, seed=s)
    st = make_streaks(src, GlareConfig())
    with GlareLayer(gl_ctx, 160, 120, s) as layer:
        got = layer.render(st)
    ref = rasterize_streaks_reference(st, 160, 120, s)
    assert ref.max() > 1.0
    assert np.abs(got - ref).max() < TWIN_REL_TOL * ref.max()


@pytest.mark.gl
@pytest.mark.parametrize("n_exp", [10.0, 100.0, 1000.0])
def test_gl_streak_energy_conserved(gl_ctx, n_exp):
    """The summed streak light read back from GL equals the highlight excess (all pairs on
    screen here): within ENERGY_TOL_S4 at the default supersampling."""
    from render.composite.glare_layer import GlareLayer

    img, src = _random_sources(40, 320, 240, seed=7, n_exp=n_exp, margin=60)
    st = make_streaks(src, GlareConfig())
    e = streak_energy_on_screen(st, 320, 240)
    np.testing.assert_allclose(e, src.excess.sum(0), rtol=1e-9)  # nothing falls off screen
    with GlareLayer(gl_ctx, 320, 240, 4) as layer:
        light = layer.render(st)
    np.testing.assert_allclose(light.sum((0, 1)), src.excess.sum(0), rtol=ENERGY_TOL_S4)


@pytest.mark.gl
def test_apply_glare_keeps_frame_energy_and_centres_streaks(gl_ctx):
    from render.composite.pipeline import apply_glare_gl

    img = np.full((120, 160, 3), 0.1)
    img[40, 100] = [40.0, 30.0, 20.0]
    st = {}
    out = apply_glare_gl(gl_ctx, img, 1.0, stats=st)
    assert st["bright_pixels"] == 1
    np.testing.assert_allclose(out.sum((0, 1)), img.sum((0, 1)), rtol=ENERGY_TOL_S4 * 0.1)
    g = np.abs(out - 0.1).sum(-1)
    g[40, 100] = 0
    r = (g * np.arange(120)[:, None]).sum() / g.sum()
    c = (g * np.arange(160)[None]).sum() / g.sum()
    assert abs(r - 40) < 1.0 and abs(c - 100) < 1.0  # the streaks are centred on the highlight
    assert g.max() > 0 and (g > 1e-3).sum() > 20  # and spread over many pixels


@pytest.mark.gl
def test_gl_layer_twin_at_the_border(gl_ctx):
    """Pairs leaving the frame at every edge (the layer's scissor box is clipped to the frame)."""
    from render.composite.glare_layer import GlareLayer

    img = np.full((60, 80, 3), 0.1)
    for r, c in ((0, 0), (0, 79), (59, 0), (59, 79), (30, 1)):
        img[r, c] = [30.0, 20.0, 25.0]
    st = make_streaks(glare_sources(img, 1.0), GlareConfig())
    with GlareLayer(gl_ctx, 80, 60, 2) as layer:
        got = layer.render(st)
    ref = rasterize_streaks_reference(st, 80, 60, 2)
    assert np.abs(got - ref).max() < TWIN_REL_TOL * ref.max()
    e = streak_energy_on_screen(st, 80, 60)
    assert np.all(e < 0.9 * st.energy.sum(0))  # a good part left the frame
    np.testing.assert_allclose(got.sum((0, 1)), e, rtol=0.02)

"""Dominant lights (power-exact extraction) and the energy-preserving Blinn-Phong (docs/methods.md §4)."""

from __future__ import annotations

import numpy as np
import pytest

from render.shading.brdf import blinn_phong_energy, blinn_phong_normalized, blinn_phong_raw_energy, half_vector
from render.shading.envmap import EnvMap, bundled_envmap, procedural_sky
from render.shading.lights import LIGHT_MAX_RADIUS, _extract, dominant_lights, env_minus_lights, lights_irradiance
from render.shading.sh import irradiance_brute
from tests.render.shading.glsl_harness import eval_glsl


def _two_disc_env(h=128):
    env0 = EnvMap(np.zeros((h, 2 * h, 3), np.float32))
    d = env0.pixel_directions()
    img = np.full(d.shape, 0.5)
    a = np.array([0.3, 0.4, 0.8]); a /= np.linalg.norm(a)
    b = np.array([-0.6, -0.2, 0.3]); b /= np.linalg.norm(b)
    ra, rb = np.radians(5), np.radians(8)
    img[d @ a >= np.cos(ra)] = [200.0, 150.0, 100.0]
    img[d @ b >= np.cos(rb)] = [20.0, 20.0, 30.0]
    return EnvMap(img.astype(np.float32)), (a, ra, [199.5, 149.5, 99.5]), (b, rb, [19.5, 19.5, 29.5])


def test_dominant_lights_on_known_discs():
    env, A, B = _two_disc_env()
    dirs, power, sa = dominant_lights(env, 4)
    assert len(dirs) == 2  # only two bright regions exist; k is an upper bound
    for i, (c, r, excess) in enumerate([A, B]):
        assert np.degrees(np.arccos(np.clip(dirs[i] @ c, -1, 1))) < 0.5
        cap = 2 * np.pi * (1 - np.cos(r))  # analytic disc solid angle (pixelisation ~ few %)
        np.testing.assert_allclose(sa[i], cap, rtol=0.06)
        # grey-ish uniform disc: directional power = excess * integral of cos over the cap
        cap_cos = np.pi * np.sin(r) ** 2  # integral of (w.c) over the cap = pi sin^2 r
        np.testing.assert_allclose(power[i], np.array(excess) * cap_cos, rtol=0.06)
        np.testing.assert_allclose(power[i] / sa[i], np.array(excess) * (1 + np.cos(r)) / 2, rtol=0.01)


@pytest.mark.parametrize("name", ["sunset", "studio", "procedural"])
def test_lights_plus_residual_reproduce_irradiance(name):
    from render.shading.lights import LUMA

    env = procedural_sky(64) if name == "procedural" else bundled_envmap(name).resized(64)
    lights, _ = _extract(env, 4)
    res = env_minus_lights(env, 4)
    excess = env.data.astype(np.float64) - res.data
    assert excess.min() >= 0  # removed light only, nothing added
    # the directional power is at most the removed power and close to it (compact regions)
    removed = np.einsum("hwc,hw->c", excess, env.pixel_solid_angles())
    assert np.all(lights.power.sum(0) <= removed * (1 + 1e-9))
    assert np.all(lights.power.sum(0) >= removed * 0.97)
    # wherever a normal sees every light region whole, directional lights + residual is exact in
    # luminance and within 1% per channel
    rng = np.random.default_rng(0)
    n = rng.normal(size=(4000, 3)); n /= np.linalg.norm(n, axis=1, keepdims=True)
    s = np.sin(LIGHT_MAX_RADIUS + np.radians(5))
    ok = np.all(np.abs(n @ lights.dirs.T) > s, axis=1)
    assert ok.sum() > 50
    got = lights_irradiance(lights, n[ok]) + irradiance_brute(res, n[ok])
    ref = irradiance_brute(env, n[ok])
    np.testing.assert_allclose(got @ LUMA, ref @ LUMA, rtol=1e-9)
    np.testing.assert_allclose(got, ref, rtol=1e-2)  # measured max 0.89% (sunset, red/blue sky)


def test_procedural_sun_is_the_first_light():
    from render.shading.envmap import SUN_DIR, SUN_RADIUS

    dirs, power, sa = dominant_lights(procedural_sky(128), 2)
    assert np.degrees(np.arccos(dirs[0] @ SUN_DIR)) < 0.5
    from render.shading.envmap import SUN_RADIANCE

    # region = the disc plus its partly covered edge pixels (pixel = 1.4 deg here)
    px = np.pi / 128
    assert 2 * np.pi * (1 - np.cos(SUN_RADIUS)) * 0.95 < sa[0] < 2 * np.pi * (1 - np.cos(SUN_RADIUS + 1.5 * px))
    # ... but the power is that of the disc (sky radiance near the sun is ~1, i.e. < 0.5% of it)
    np.testing.assert_allclose(power[0], SUN_RADIANCE * np.pi * np.sin(SUN_RADIUS) ** 2, rtol=0.02)


def test_uniform_map_has_no_lights():
    dirs, power, sa = dominant_lights(EnvMap(np.ones((32, 64, 3), np.float32)), 3)
    assert dirs.shape == (0, 3) and power.shape == (0, 3) and sa.shape == (0,)


def test_bundled_lights_are_separated():
    dirs, power, _ = dominant_lights(bundled_envmap("studio").resized(128), 4)
    assert len(dirs) == 4
    cos = dirs @ dirs.T - 2 * np.eye(len(dirs))
    assert cos.max() < np.cos(LIGHT_MAX_RADIUS)
    assert np.all(power > 0)


# --- Blinn-Phong -------------------------------------------------------------------------------
@pytest.mark.parametrize("n", [1, 10, 100, 1000])
def test_normalized_lobe_integrates_to_eq5(n):
    """Numerically integrate the normalised lobe over the hemisphere of view directions V with
    L = N, building the half vector explicitly (independent of the closed form)."""
    from scipy.integrate import quad

    N = np.array([0.0, 0.0, 1.0])

    def integrand(theta):
        v = np.array([np.sin(theta), 0.0, np.cos(theta)])
        c = half_vector(N, v) @ N
        return float(blinn_phong_normalized(c, n)) * np.sin(theta) * 2 * np.pi  # azimuth symmetric

    w = 2 * np.arccos(0.5 ** (1.0 / n))  # lobe width in theta: help quad find the peak
    val = quad(integrand, 0, np.pi / 2, points=[w, 4 * w], epsabs=0, epsrel=1e-11, limit=200)[0]
    np.testing.assert_allclose(val, 1 - (np.sqrt(2) / 2) ** (n + 2), rtol=1e-8)
    np.testing.assert_allclose(blinn_phong_energy(n), val, rtol=1e-8)
    np.testing.assert_allclose(blinn_phong_raw_energy(n), val * 8 * np.pi / (n + 2), rtol=1e-8)


def test_normalized_lobe_2d_grid_integral():
    # a second, brute 2-D route: sum over a fine equirect grid of view directions
    env = EnvMap(np.zeros((1024, 2048, 3), np.float32))
    d = env.pixel_directions()[:512]
    om = env.pixel_solid_angles()[:512]
    c = half_vector(np.array([0, 0, 1.0]), d)[..., 2]
    for n in (1, 10, 100):
        np.testing.assert_allclose((blinn_phong_normalized(c, n) * om).sum(), blinn_phong_energy(n), rtol=1e-4)


def test_blinn_phong_no_nan_extremes():
    c = np.array([-1, -1e-9, 0, 1e-300, 1e-9, 0.5, 1 - 1e-12, 1.0])
    for n in (0, 1e-3, 1, 1e4, 1e6):
        v = blinn_phong_normalized(c, n)
        assert np.all(np.isfinite(v)) and np.all(v >= 0)
    assert blinn_phong_normalized(1.0, 1e6) == pytest.approx((1e6 + 2) / (8 * np.pi))


@pytest.mark.gl
def test_brdf_glsl_twin(gl_ctx):
    rng = np.random.default_rng(1)
    c = rng.uniform(-0.2, 1, 2000).astype(np.float32)
    c[:10] = 1.0
    n = (10 ** rng.uniform(0, 4, 2000)).astype(np.float32)
    out = eval_glsl(gl_ctx, ["shading_brdf.glsl"],
                    "vec4(blinn_phong_normalized(x.x, x.y), blinn_phong_energy(x.y), 0.0, 1.0)",
                    np.stack([c, n], 1))
    ref = blinn_phong_normalized(c.astype(np.float64), n.astype(np.float64))
    peak = (n + 2) / (8 * np.pi)
    # float32 exp(n log c): absolute exponent error ~ n * 1e-7 -> relative error ~ n * 1e-7
    tol = 1e-5 + 2e-7 * n.astype(np.float64)
    assert np.all(np.abs(out[:, 0] - ref) <= tol * np.maximum(ref, 1e-6 * peak))
    np.testing.assert_allclose(out[:, 1], blinn_phong_energy(n.astype(np.float64)), rtol=1e-5)

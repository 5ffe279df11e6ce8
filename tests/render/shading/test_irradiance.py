"""Diffuse irradiance: SH basis and projection, SH9 (and its honest error on real maps), the
exact irradiance table (issue 2: <= 1% vs a brute-force integral), and their GLSL twins."""

from __future__ import annotations

import numpy as np
import pytest

from render.shading.envmap import BUNDLED_NAMES, EnvMap, bundled_envmap
from render.shading.irradiance import irradiance_lookup, irradiance_table, irradiance_table_brute, irradiance_texture
from render.shading.sh import (
    cosine_lobe_coefficients,
    irradiance_brute,
    sh9_glsl_uniform,
    sh9_irradiance,
    sh9_project,
    sh_basis,
    sh_irradiance,
    sh_project,
)
from tests.render.shading.glsl_harness import eval_glsl

#: issue 2: irradiance within 1% relative, per channel, over 100 random normals.
IRRADIANCE_REL_TOL = 0.01


def _rand_dirs(n, seed=0):
    d = np.random.default_rng(seed).normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def test_sh9_basis_matches_textbook_constants():
    d = _rand_dirs(500)
    x, y, z = d.T
    ref = np.stack([np.full_like(x, 0.5 / np.sqrt(np.pi)), np.sqrt(3 / (4 * np.pi)) * y,
                    np.sqrt(3 / (4 * np.pi)) * z, np.sqrt(3 / (4 * np.pi)) * x,
                    0.5 * np.sqrt(15 / np.pi) * x * y, 0.5 * np.sqrt(15 / np.pi) * y * z,
                    0.25 * np.sqrt(5 / np.pi) * (3 * z * z - 1), 0.5 * np.sqrt(15 / np.pi) * x * z,
                    0.25 * np.sqrt(15 / np.pi) * (x * x - y * y)], -1)
    np.testing.assert_allclose(sh_basis(d, 2), ref, atol=1e-14)


def test_sh_basis_orthonormal():
    env = EnvMap(np.zeros((256, 512, 3), np.float32))
    y = sh_basis(env.pixel_directions(), 5).reshape(-1, 36)
    gram = np.einsum("pi,pj,p->ij", y, y, env.pixel_solid_angles().reshape(-1))
    np.testing.assert_allclose(gram, np.eye(36), atol=2e-4)


def test_cosine_lobe_coefficients_vs_numeric_legendre():
    from numpy.polynomial import legendre
    from scipy.integrate import quad

    a = cosine_lobe_coefficients(8)
    for l in range(9):
        c = np.zeros(l + 1)
        c[l] = 1
        num = 2 * np.pi * quad(lambda t, c=c: t * legendre.legval(t, c), 0, 1, epsabs=1e-14)[0]
        np.testing.assert_allclose(a[l], num, atol=1e-12)


def test_sh_irradiance_exact_for_band_limited_radiance():
    # L(w) = a + B w + quadratic (band <= 2): SH9 irradiance must equal the brute-force integral
    env0 = EnvMap(np.zeros((256, 512, 3), np.float32))
    d = env0.pixel_directions()
    L = 2.0 + d @ np.array([[0.5, 0.1, -0.3], [0.2, 0.4, 0.0], [0.3, -0.2, 0.6]]) + 0.4 * d[..., :1] * d[..., 2:]
    env = EnvMap(L.astype(np.float32))
    n = _rand_dirs(100, 1)
    np.testing.assert_allclose(sh9_irradiance(sh9_project(env), n), irradiance_brute(env, n), rtol=2e-4)


@pytest.mark.parametrize("name", BUNDLED_NAMES)
def test_irradiance_table_within_1_percent_of_brute_force(name):
    """issue 2: exact irradiance table vs the brute-force per-pixel integral of the FULL
    resolution (512x1024) real HDR map, 100 random normals, every channel <= 1% relative."""
    env = bundled_envmap(name)
    n = _rand_dirs(100, 7)
    ref = irradiance_brute(env, n)
    got = irradiance_lookup(irradiance_table(env), n)
    rel = np.abs(got - ref) / ref
    assert rel.max() <= IRRADIANCE_REL_TOL, f"{name}: max rel {rel.max():.4f}"


def test_sh9_error_on_real_maps_is_reported_not_hidden():
    """SH9 is NOT 1%-accurate on real maps (measured max 19-73% on the bundled maps at 100
    random normals). This pins down that the numbers the docs quote are real, and that SH of
    higher order converges toward the brute force."""
    env = bundled_envmap("studio").resized(128)
    n = _rand_dirs(100, 7)
    ref = irradiance_brute(env, n)
    errs = [float((np.abs(sh_irradiance(sh_project(env, l), n) - ref) / ref).max()) for l in (2, 8, 16)]
    assert errs[0] > 0.1  # SH9 really is poor here: do not use it where 1% matters
    assert errs[0] > errs[1] > errs[2]


def test_irradiance_table_fft_equals_brute_force_quadrature():
    env = bundled_envmap("sunset").resized(64)
    for h, f in [(8, 1), (16, 2), (12, 3)]:
        fast = irradiance_table(env, h, f)
        slow = irradiance_table_brute(env, h, f)
        np.testing.assert_allclose(fast, slow, rtol=1e-9, atol=1e-12 * slow.max())


@pytest.mark.gl
def test_sh9_glsl_twin(gl_ctx):
    rng = np.random.default_rng(3)
    coeffs = rng.normal(size=(9, 3)) * 0.3
    coeffs[0] += 3.0  # E > 0 here; the clamp at 0 is tested separately below
    n = _rand_dirs(1000, 4)
    ref = sh9_irradiance(coeffs, n)
    assert ref.min() > 0
    out = eval_glsl(gl_ctx, ["sh9.glsl"], "vec4(sh9_irradiance(x.xyz), 1.0)", n.astype(np.float32),
                    uniforms={"u_sh9": [tuple(map(float, r)) for r in sh9_glsl_uniform(coeffs)]})
    np.testing.assert_allclose(out[:, :3], ref, rtol=1e-5, atol=1e-5 * np.abs(ref).max())
    # ringing below zero is clamped to 0 in both twins
    neg = -sh9_glsl_uniform(coeffs) / np.array([np.pi] + [2 * np.pi / 3] * 3 + [np.pi / 4] * 5)[:, None]
    ref = sh9_irradiance(neg, n)
    assert ref.max() == 0.0
    out = eval_glsl(gl_ctx, ["sh9.glsl"], "vec4(sh9_irradiance(x.xyz), 1.0)", n.astype(np.float32),
                    uniforms={"u_sh9": [tuple(map(float, r)) for r in sh9_glsl_uniform(neg)]})
    assert np.all(out[:, :3] == 0.0)


@pytest.mark.gl
def test_envmap_glsl_twin(gl_ctx):
    from render.shading.envmap import dir_to_uv, uv_to_dir

    d = _rand_dirs(1000, 5)
    uv = dir_to_uv(d)
    ok = (uv[:, 0] > 1e-4) & (uv[:, 0] < 1 - 1e-4)  # away from the seam where u wraps 1 -> 0
    out = eval_glsl(gl_ctx, ["shading_envmap.glsl"], "vec4(env_dir_to_uv(x.xyz), 0.0, 1.0)",
                    d.astype(np.float32))
    np.testing.assert_allclose(out[ok, :2], uv[ok], atol=2e-6)
    back = eval_glsl(gl_ctx, ["shading_envmap.glsl"], "vec4(env_uv_to_dir(x.xy), 1.0)",
                     uv.astype(np.float32))
    np.testing.assert_allclose(back[:, :3], uv_to_dir(uv.astype(np.float32)), atol=2e-6)
    # irradiance table through a hardware LINEAR texture vs the numpy bilinear lookup
    table = irradiance_table(bundled_envmap("forest").resized(64), 32)
    tex = irradiance_texture(gl_ctx, table)
    try:
        got = eval_glsl(gl_ctx, ["shading_envmap.glsl"], "vec4(env_irradiance(u_table, x.xyz), 1.0)",
                        d.astype(np.float32), textures={"u_table": tex},
                        prelude="uniform sampler2D u_table;\n")
    finally:
        tex.release()
    ref = irradiance_lookup(table, d)
    # GPUs interpolate with 8-bit sub-texel weights: allow 1/256 of the local texel spread
    np.testing.assert_allclose(got[:, :3], ref, rtol=3e-3, atol=1e-6 * ref.max())

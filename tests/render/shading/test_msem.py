"""Multi-scale environment map (docs/methods.md §2): g(|t|), the fast build vs the brute force, and the
GLSL 3-D texture twin. Errors are in 1/256 of the map's white level (msem.white_level)."""

from __future__ import annotations

import numpy as np
import pytest

from render.shading.envmap import EnvMap, bundled_envmap, procedural_sky
from render.shading.msem import (
    MSEM_INTENSITY_LEVELS,
    convolve_phong,
    msem_brute,
    msem_build,
    msem_lambda,
    msem_lookup,
    msem_texture,
    white_level,
)
from tests.render.shading.glsl_harness import eval_glsl


def test_g_matches_eq13_and_clamps_at_zero():
    s = 64
    r = np.array([0.05, 0.1, 0.5, 1.0, 1.7])
    direct = -np.log(MSEM_INTENSITY_LEVELS) / np.log(np.cos(np.arctan(2 / (r * s))))
    np.testing.assert_allclose(msem_lambda(r, s), direct, rtol=1e-9)
    tiny = msem_lambda(np.array([0.0, 1e-300, 1e-12, 1e-6]), s)
    # Lambda -> 0 only like ln(I) / ln(2 / (|t| s)): finite, positive, increasing, 0 at 0
    assert tiny[0] == 0.0 and np.all(np.isfinite(tiny)) and np.all(np.diff(tiny) > 0)
    assert tiny[1] < 0.02 and tiny[-1] < 0.6
    grid = np.linspace(0, 2, 2001)
    g = msem_lambda(grid, s)
    assert np.all(np.diff(g) > 0)
    # voxel resolvability (Eq. 11): cos^Lambda(psi_voxel) = 1/I at every radius
    psi = np.arctan(2 / (r * s))
    np.testing.assert_allclose(np.cos(psi) ** msem_lambda(r, s), 1 / MSEM_INTENSITY_LEVELS, rtol=1e-9)


def test_convolution_is_the_brute_force_quadrature():
    env = bundled_envmap("sunset").resized(24)
    d = env.pixel_directions().reshape(-1, 3)
    om = env.pixel_solid_angles().reshape(-1)
    L = env.data.reshape(-1, 3).astype(np.float64)
    # (lam = 0 is the bare hemisphere gate: its boundary passes exactly through pixel centres of
    # an equirect grid, so 0 vs 1e-17 decides -- not a meaningful comparison)
    for lam in (0.5, 3.0, 40.0, 900.0):
        fast = convolve_phong(env, lam, th=0.0).reshape(-1, 3)
        c = d @ d.T
        with np.errstate(divide="ignore"):
            w = np.where(c > 0, np.exp(lam * np.log(np.where(c > 0, c, 1))), 0) * om
        ref = (w @ L) / w.sum(1, keepdims=True)
        np.testing.assert_allclose(fast, ref, rtol=1e-8, atol=1e-10 * ref.max())


def test_constant_map_gives_constant_msem():
    env = EnvMap(np.full((32, 64, 3), 0.7, np.float32))
    vol = msem_build(env, 16).volume
    np.testing.assert_allclose(vol, 0.7, rtol=1e-5)


# maps whose highlights stay within ~10x white; a sun hundreds of times brighter than white
# breaks the mean-below-1/256 target near it (furrow/bench/shading.py reports it), see msem.py
@pytest.mark.parametrize("name", ["courtyard", "forest"])
def test_fast_build_vs_brute_force(name):
    env = procedural_sky(64) if name == "procedural" else bundled_envmap(name).resized(64)
    s = 24
    b = msem_build(env, s, th=0.001)
    rng = np.random.default_rng(0)
    idx = rng.integers(0, s, (600, 3))
    idx = idx[np.linalg.norm((idx + 0.5) / s * 2 - 1, axis=1) <= 1.0][:400]  # the lookup domain
    ref = msem_brute(env, s, idx)
    got = b.volume[idx[:, 0], idx[:, 1], idx[:, 2]]
    err = np.abs(got - ref) / white_level(env) * 256
    assert err.mean() < 1.0, err.mean()  # issue 6 target: mean below 1/256
    assert np.percentile(err, 99) < 16.0, np.percentile(err, 99)


def test_threshold_error_grows_with_th():
    env = bundled_envmap("forest").resized(32)
    lam = 200.0
    exact = convolve_phong(env, lam, 0.0)
    errs = [np.abs(convolve_phong(env, lam, th) - exact).mean() for th in (0.001, 0.01, 0.1)]
    assert errs[0] < errs[1] < errs[2]


@pytest.mark.gl
def test_msem_glsl_twin(gl_ctx):
    env = bundled_envmap("studio").resized(32)
    vol = msem_build(env, 16).volume
    rng = np.random.default_rng(1)
    r = rng.normal(size=(2000, 3)); r /= np.linalg.norm(r, axis=1, keepdims=True)
    sm = rng.uniform(0, 1, 2000)
    sm[:20] = 1.0
    sm[20:40] = 0.0
    ref = msem_lookup(vol, r, sm)
    tex = msem_texture(gl_ctx, vol)
    try:
        out = eval_glsl(gl_ctx, ["shading_msem.glsl"], "vec4(msem_radiance(u_msem, x.xyz, x.w), 1.0)",
                        np.concatenate([r, sm[:, None]], 1).astype(np.float32),
                        textures={"u_msem": tex}, prelude="uniform sampler3D u_msem;\n")
    finally:
        tex.release()
    # GPUs filter with 8-bit sub-texel weights: 1/256 of the local voxel spread
    scale = np.abs(vol).max()
    np.testing.assert_allclose(out[:, :3], ref, atol=scale / 256, rtol=0)
    assert np.abs(out[:, :3] - ref).mean() < 1e-4 * scale

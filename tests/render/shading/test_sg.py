"""Spherical Gaussians (docs/methods.md §3) against numerical integration, over the hard cases of
docs/methods.md §5 (hypothesis: lambda 1e-3..1e5, antipodal axes, no NaN or inf)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from render.shading.envmap import EnvMap
from render.shading.sg import (
    COS_LOBE_LAMBDA,
    COS_LOBE_MU,
    fh_exact,
    fh_fit,
    fh_printed_001,
    fh_quad,
    fit_cosine_lobe,
    sg_eval,
    sg_hemi_integral,
    sg_inner_product,
    sg_integral,
    sg_irradiance,
    sg_product,
    warp_ndf_sg,
)
from tests.render.shading.glsl_harness import eval_glsl

#: our fitted f_h vs the exact integral, in units of f_h(pi/2, lambda) (measured max 1.4e-3)
FH_FIT_TOL = 2e-3

lams = st.floats(1e-3, 1e5)
units = st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1)).filter(
    lambda v: 1e-3 < np.linalg.norm(v)).map(lambda v: np.array(v) / np.linalg.norm(v))


def _grid(h=512):
    e = EnvMap(np.zeros((h, 2 * h, 3), np.float32))
    return e.pixel_directions().reshape(-1, 3), e.pixel_solid_angles().reshape(-1)


@settings(max_examples=300, deadline=None, derandomize=True)
@given(units, lams, units, lams, st.booleans())
def test_product_pointwise_and_finite(p1, l1, p2, l2, antipodal):
    if antipodal:
        p2, l2 = -p1, l1
    axis, lam, mu = sg_product(p1, l1, 1.0, p2, l2, 1.0)
    assert np.all(np.isfinite(axis)) and np.isfinite(lam) and np.isfinite(mu)
    assert 0 <= mu <= 1 and lam >= 0
    np.testing.assert_allclose(np.linalg.norm(axis), 1, atol=1e-12)
    rng = np.random.default_rng(0)
    d = rng.normal(size=(64, 3)); d /= np.linalg.norm(d, axis=1, keepdims=True)
    d = np.vstack([d, p1, p2, axis])
    # compare the log of the product with the log of the product SG (exponents can be -1e5)
    lhs = -l1 * 0.5 * np.sum((d - p1) ** 2, 1) - l2 * 0.5 * np.sum((d - p2) ** 2, 1)
    # (amplitudes below the normal float64 range, ~1e-308, are subnormal: their log loses digits)
    rhs = np.log(mu) - lam * 0.5 * np.sum((d - axis) ** 2, 1) if mu > 1e-300 else None
    if rhs is not None:
        np.testing.assert_allclose(rhs, lhs, atol=1e-9 * (l1 + l2) + 1e-12)
    else:  # underflow of the amplitude: the product itself is below 1e-300 everywhere
        assert np.all(lhs < -690)


def test_product_antipodal_equal_sharpness_is_constant():
    p = np.array([0.0, 0.6, 0.8])
    for l in (1e-3, 1.0, 50.0, 1e5):
        axis, lam, mu = sg_product(p, l, 2.0, -p, l, 3.0)
        assert lam == 0.0 and np.all(np.isfinite(axis))
        np.testing.assert_allclose(mu, 6.0 * np.exp(-2 * l), rtol=1e-12)


@settings(max_examples=200, deadline=None, derandomize=True)
@given(lams)
def test_integrals_finite_and_monotone(l):
    i = sg_integral(l)
    h = sg_hemi_integral(l)
    assert np.isfinite(i) and np.isfinite(h) and 0 < h <= i <= 4 * np.pi
    assert h >= i / 2


@pytest.mark.parametrize("lam", [1e-3, 0.5, 5.0, 80.0])
def test_integrals_vs_numeric(lam):
    d, om = _grid(1024)
    p = np.array([0.3, -0.5, 0.8]); p /= np.linalg.norm(p)
    g = sg_eval(d, p, lam)
    np.testing.assert_allclose((g * om).sum(), sg_integral(lam), rtol=1e-5)
    np.testing.assert_allclose((g * om * (d @ p >= 0)).sum(), sg_hemi_integral(lam), rtol=2e-3)
    q = np.array([-0.2, 0.9, 0.1]); q /= np.linalg.norm(q)
    g2 = sg_eval(d, q, 3.0, 2.0)
    np.testing.assert_allclose((g * g2 * om).sum(), sg_inner_product(p, lam, 1.0, q, 3.0, 2.0), rtol=1e-5)


def test_cosine_lobe_fit_matches_published_constants():
    lam, mu = fit_cosine_lobe()
    # the published (2.133, 1.170) is an L2 fit of the same thing: ours agrees within 1%
    np.testing.assert_allclose([lam, mu], [COS_LOBE_LAMBDA, COS_LOBE_MU], rtol=0.01)


@pytest.mark.parametrize("td", [-np.pi, -np.pi / 2, -1.0, -0.05, 0.0, 0.05, 1.0, np.pi / 2, np.pi])
@pytest.mark.parametrize("lam", [1e-3, 0.3, 3.0, 30.0, 1e3, 1e5])
def test_fh_exact_vs_quad(td, lam):
    ref = fh_quad(td, lam)
    h = sg_hemi_integral(lam)
    assert abs(fh_exact(td, lam) - ref) <= 1e-7 * h
    assert abs(fh_fit(td, lam) - ref) <= FH_FIT_TOL * h


def test_fh_special_values():
    for lam in (1e-3, 1.0, 100.0):
        np.testing.assert_allclose(fh_exact(np.pi / 2, lam), sg_hemi_integral(lam), rtol=1e-9)
        # opposite hemisphere: 2 pi / lam (e^-lam - e^-2lam)
        np.testing.assert_allclose(fh_exact(-np.pi / 2, lam),
                                   2 * np.pi / lam * (np.exp(-lam) - np.exp(-2 * lam)), rtol=1e-9)
        # half of the lobe visible at theta_d = 0, by symmetry: half the sphere integral
        np.testing.assert_allclose(fh_exact(0.0, lam), sg_integral(lam) / 2, rtol=1e-9)


@settings(max_examples=120, deadline=None, derandomize=True)
@given(st.floats(-4, 4), lams)
def test_fh_fit_no_nan_and_accurate(td, lam):
    f = fh_fit(td, lam)
    h = sg_hemi_integral(lam)
    assert np.isfinite(f) and -1e-12 <= f <= h * (1 + 1e-9)
    assert abs(f - fh_exact(td, lam)) <= FH_FIT_TOL * h


def test_printed_fit_001_is_wrong_as_printed():
    # as printed (docs/methods.md §3 warns): k(lambda) > 0 for lambda < ~8.8, so f_h DEcreases as more of
    # the lobe becomes visible (wrong trend, error > 20% of f_h(pi/2)); for sharp lobes the trend
    # is right but the slope is off (error > 10x our fit's). Ours stays within FH_FIT_TOL.
    td = np.linspace(-1.5, 1.5, 31)
    for lam, min_err in ((1.0, 0.2), (3.0, 0.2), (100.0, 10 * FH_FIT_TOL)):
        ex = fh_exact(td, lam)
        h = sg_hemi_integral(lam)
        assert np.abs(fh_printed_001(td, lam) - ex).max() > min_err * h
        assert np.abs(fh_fit(td, lam) - ex).max() < FH_FIT_TOL * h


def test_sg_irradiance_of_one_lobe_vs_numeric():
    d, om = _grid(512)
    p = np.array([0.0, 0.0, 1.0])
    n = np.array([[0, 0, 1.0], [1, 0, 0.0], [0, 0.6, -0.8]])
    for lam in (2.0, 50.0):
        ref = (sg_eval(d, p, lam)[:, None] * np.maximum(d @ n.T, 0) * om[:, None]).sum(0)
        got = sg_irradiance(p[None], [lam], [[1.0]], n)[:, 0]
        # the code: exactly the integral of G times the cosine SG
        cos_sg = COS_LOBE_MU * np.exp(COS_LOBE_LAMBDA * (d @ n.T - 1))
        np.testing.assert_allclose(got, (sg_eval(d, p, lam)[:, None] * cos_sg * om[:, None]).sum(0), rtol=1e-4)
        # the model: the cosine-as-one-SG approximation overshoots a light on the normal by up
        # to COS_LOBE_MU - 1 = 17% (sharp lights); measured +14.5% at lambda 50, -0.3% at 2
        assert 0.99 < got[0] / ref[0] < COS_LOBE_MU
    assert np.all(np.isfinite(got))


def test_ward_and_cook_torrance_lobes():
    from render.shading.sg import cook_torrance_ndf_sg, ward_ndf_sg

    n = np.array([0, 0, 1.0])
    th = np.linspace(0, 0.25, 50)
    h = np.stack([np.sin(th), 0 * th, np.cos(th)], 1)
    for a in (0.05, 0.1, 0.2):
        c = np.cos(th)
        ward = np.exp(-np.tan(th) ** 2 / a**2) / (np.pi * a**2 * c**3)
        ax, lam, mu = ward_ndf_sg(n, a)
        approx = sg_eval(h, ax, lam, mu)
        # relative to the peak, within the lobe (ward > 1% of peak)
        k = ward > 0.01 * ward[0]
        assert np.abs(approx[k] - ward[k]).max() < 0.1 * ward[0]
        ax, lam, mu = cook_torrance_ndf_sg(n, a)
        np.testing.assert_allclose(lam, 2 / a**2)


def test_warp_ndf():
    n = np.array([0, 0, 1.0])
    o = np.array([np.sin(0.4), 0, np.cos(0.4)])
    pw, lw, mw = warp_ndf_sg(n, 100.0, 1.0, o)
    np.testing.assert_allclose(pw, [-np.sin(0.4), 0, np.cos(0.4)], atol=1e-12)  # mirror of o
    np.testing.assert_allclose(lw, 100.0 / (4 * np.cos(0.4)))


@pytest.mark.gl
def test_sg_glsl_twin(gl_ctx):
    from render.shading.sg import fh_glsl_params, fh_texture

    rng = np.random.default_rng(2)
    n = 600
    p1 = rng.normal(size=(n, 3)); p1 /= np.linalg.norm(p1, axis=1, keepdims=True)
    p2 = rng.normal(size=(n, 3)); p2 /= np.linalg.norm(p2, axis=1, keepdims=True)
    p2[:50] = -p1[:50]
    l1 = 10 ** rng.uniform(-3, 3, n)
    l2 = 10 ** rng.uniform(-3, 3, n)
    l2[:50] = l1[:50]
    # (p1, lambda1) is the per-fragment input; (p2, lambda2) comes from a second texture
    x = np.concatenate([p1, l1[:, None]], 1).astype(np.float32)
    ref = []
    for i in range(n):
        _, lam, mu = sg_product(p1[i], l1[i], 1.0, p2[i], l2[i], 1.0)
        ref.append([lam, np.log(mu) if mu > 0 else -np.inf, sg_integral(lam, mu), sg_hemi_integral(l1[i])])
    ref = np.array(ref)
    tex2 = gl_ctx.texture((n, 1), 4, np.concatenate([p2, l2[:, None]], 1).astype(np.float32).tobytes(), dtype="f4")
    fh_tex = fh_texture(gl_ctx)
    try:
        out = eval_glsl(
            gl_ctx, ["shading_sg.glsl"],
            "eval_case(x, texelFetch(u_b, ivec2(int(gl_FragCoord.x) + 256 * int(gl_FragCoord.y), 0), 0))",
            x, textures={"u_b": tex2},
            prelude="uniform sampler2D u_b;\n"
                    "vec4 eval_case(vec4 a, vec4 b) {\n"
                    "  SG g1; g1.axis = a.xyz; g1.lambda = a.w; g1.mu = vec3(1.0);\n"
                    "  SG g2; g2.axis = b.xyz; g2.lambda = b.w; g2.mu = vec3(1.0);\n"
                    "  SG m = sg_product(g1, g2);\n"
                    "  return vec4(m.lambda, log(m.mu.x), sg_integral(m).x, sg_hemi_integral(a.w));\n}\n")
        td = rng.uniform(-2, 2, n)
        lam = 10 ** rng.uniform(-3, 5, n)
        fh = eval_glsl(gl_ctx, ["shading_sg.glsl"], "vec4(sg_fh(x.x, x.y), 0.0, 0.0, 1.0)",
                       np.stack([td, lam], 1).astype(np.float32), textures={"u_fh_table": fh_tex},
                       uniforms={"u_fh_params": fh_glsl_params()}, defines={"SG_FH_TABLE": 1})
    finally:
        tex2.release()
        fh_tex.release()
    np.testing.assert_allclose(out[:, 0], ref[:, 0], rtol=2e-5, atol=1e-5)
    ok = np.isfinite(ref[:, 1]) & (ref[:, 1] > -80)
    # float32 log-amplitude: absolute error ~ 1e-7 * (l1 + l2)
    err = np.abs(out[ok, 1] - ref[ok, 1])
    assert np.all(err <= 2e-6 * (l1 + l2)[ok] + 1e-5), err.max()
    rel = np.abs(out[ok, 2] - ref[ok, 2]) / ref[ok, 2]
    assert np.all(rel <= 2e-4 + 2e-6 * (l1 + l2)[ok]), rel.max()
    np.testing.assert_allclose(out[:, 3], ref[:, 3], rtol=1e-5)
    f = fh_fit(td.astype(np.float32).astype(np.float64), lam.astype(np.float32).astype(np.float64))
    h = sg_hemi_integral(lam)
    assert np.all(np.abs(fh[:, 0] - f) <= 1e-3 * h)


def test_env_fit_recovers_known_lobes_and_k_from_target():
    from render.shading.sg_fit import fit_env_sg, fit_env_sg_target

    g = EnvMap(np.zeros((32, 64, 3), np.float32))
    d = g.pixel_directions().reshape(-1, 3)
    axes = np.array([[0.3, 0.2, 0.93], [-0.7, 0.7, 0.1], [0.1, -0.9, -0.4]])
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    lams = np.array([30.0, 8.0, 3.0])
    mus = np.array([[5.0, 4.0, 3.0], [0.5, 1.0, 1.5], [0.3, 0.3, 0.2]])
    from render.shading.sg import sg_mixture_eval
    env = EnvMap((0.05 + sg_mixture_eval(d, axes, lams, mus)).reshape(32, 64, 3).astype(np.float32))
    fit = fit_env_sg(env, 4)
    assert fit.rel_error < 0.02, fit.rel_error
    # the brightest lobe is found where it is, with its sharpness
    i = int(np.argmax(fit.mus.sum(1)))
    assert np.degrees(np.arccos(np.clip(fit.axes[i] @ axes[0], -1, 1))) < 2.0
    np.testing.assert_allclose(fit.lams[i], 30.0, rtol=0.15)
    tgt = fit_env_sg_target(env, 0.05, ks=(1, 2, 4))
    assert tgt.rel_error <= 0.05
    ladder = (1, 2, 4)
    prev = ladder[ladder.index(tgt.k) - 1] if tgt.k > 1 else None
    if prev is not None:  # the smallest K that meets the target
        assert fit_env_sg(env, prev).rel_error > 0.05
    assert np.all(np.isfinite(fit.axes)) and np.all(fit.mus >= 0)

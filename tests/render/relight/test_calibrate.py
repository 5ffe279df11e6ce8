"""The relighting transfer fitted to the capture (render.relight.calibrate).  The capture colours of these
tests are made by an independent reference -- the transfer integrated by brute force over a Fibonacci
sphere of the analytic sun-and-sky radiance, with the kernels and the phase function written out here --
not by render.shading.transfer's tables and SG lobes, which the fit uses (kernel "auto" through the GL
pass: test_relight.py::test_auto_kernel_twin)."""

from __future__ import annotations

import numpy as np

from render.relight import calibrate as cb
from render.shading import transfer as rl
from render.shading.envmap import EnvMap
from tests import scenes as scene

#: Multiplicative noise on the synthetic capture colours (sensor noise, 2 %).
NOISE = 0.02
#: Directions of the reference quadrature (a Fibonacci sphere, equal weights).
QUAD_DIRS = 3000
#: The reference kernels K(c), c = n . w (lambert, wrap, half-lambert, uniform: transfer.MIX_BASIS's order).
REF_KERNELS = (lambda c: np.maximum(c, 0.0), lambda c: np.maximum(c + 0.5, 0.0) / 1.5,
               lambda c: ((np.clip(c, -1, 1) + 1) / 2) ** 2, lambda c: np.ones_like(c))
#: Rec. 709 luminance.
LUMA = np.array([0.2126, 0.7152, 0.0722])
#: The analytic maps of these tests: a softer, wider sun than tests.scenes' default.
SUN = dict(sun=(0.6, -0.3, 0.5), ambient=0.2, sky=0.3, power=30.0, sharpness=40.0)


def _radiance(d, sun, ambient, sky, power, sharpness):
    """(N, 3) the sun-and-sky radiance of tests.scenes.sun_sky_env, written out, at unit directions d (N, 3)."""
    s = np.asarray(sun, np.float64) / np.linalg.norm(sun)
    blue = ambient + sky * np.maximum(d[:, 2:3], 0) * np.array([0.6, 0.8, 1.0])
    return blue + power * np.exp(sharpness * (d @ s - 1))[:, None] * np.array([1.0, 0.9, 0.7])


def _fibonacci(n: int) -> np.ndarray:
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    phi = np.pi * (1 + 5 ** 0.5) * i
    r = np.sqrt(1 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], 1)


def reference_transfer(normals, views, weights, beta: float, g: float, light) -> np.ndarray:
    """(P,) luminance of E_K(n) + beta F(n, v) by brute force: sum over QUAD_DIRS directions w of
    K(n.w) L(w) (1 + beta HG_g(-v.w)) 4 pi / QUAD_DIRS, K = sum_j weights_j REF_KERNELS_j, HG the
    Henyey-Greenstein phase times 4 pi; ``light`` the radiance function (N, 3) -> (N, 3)."""
    if not beta:   # no phase term: a function of the normal alone, computed once per distinct normal
        uniq, back = np.unique(normals, axis=0, return_inverse=True)
        if len(uniq) < len(normals):
            return reference_transfer(uniq, uniq, weights, 0.0, g, light)[back.ravel()]
    d = _fibonacci(QUAD_DIRS)
    lw = light(d) @ LUMA * (4 * np.pi / QUAD_DIRS)
    out = np.empty(len(normals))
    for s in range(0, len(normals), 2000):
        c = normals[s:s + 2000] @ d.T
        k = sum(w * f(c) for w, f in zip(weights, REF_KERNELS) if w)
        if beta:   # the phase term only where it counts (exact: beta = 0 multiplies it away)
            q = 1 + g * g - 2 * g * -(views[s:s + 2000] @ d.T)
            k = k * (1 + beta * (1 - g * g) / (q * np.sqrt(q)))
        out[s:s + 2000] = k @ lw
    return out


def _capture(weights, beta: float, g: float, light, seed: int = 0) -> cb.CaptureSamples:
    """A unit sphere seen from 16 cameras on two rings; each pixel's luminance = a random colour per voxel
    of the fit's cube x the reference transfer (weights, beta, g) under ``light``, 2 % noise."""
    rng = np.random.default_rng(seed)
    n = rng.normal(size=(12_000, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    az = np.radians(np.arange(16) * 22.5)
    el = np.radians(np.where(np.arange(16) % 2, 35.0, -10.0))
    cams = 4.0 * np.stack([np.cos(az) * np.cos(el), np.sin(az) * np.cos(el), np.sin(el)], 1)
    xs, vs, ks = [], [], []
    for k, c in enumerate(cams):
        v = c - n
        v /= np.linalg.norm(v, axis=1, keepdims=True)
        seen = np.sum(v * n, 1) > 0.1
        xs.append(n[seen])
        vs.append(v[seen])
        ks.append(np.full(int(seen.sum()), k))
    x, v = np.concatenate(xs), np.concatenate(vs)
    t = reference_transfer(x, v, weights, beta, g, light)
    L = cb.GROUP_RES
    ijk = np.clip(np.floor((x + 1.2) / (2.4 / L)).astype(np.int64), 0, L - 1)
    albedo = np.random.default_rng(seed + 1).uniform(0.1, 1.0, L ** 3)[(ijk[:, 0] * L + ijk[:, 1]) * L + ijk[:, 2]]
    y = albedo * t * np.exp(NOISE * rng.normal(size=len(x)))
    return cb.CaptureSamples(x, v, x.copy(), y, np.concatenate(ks))


def _fit(samples, env, **kw):
    return cb.fit_transfer(samples, env, (0, 0, 1), np.full(3, -1.2), 2.4, regularise=0.0, **kw)


def test_fit_gives_back_the_transfer_that_made_the_colours():
    """The forward scattering and the kernel exactly: the fit integrates the forward term over the map's pixels
    (calibrate.forward_quadrature).  With the map's SG lobes as point lights, as before, the fit depended on
    where L-BFGS-B left the broad lobes, which depends on the CPU's BLAS kernels: an AVX-512 machine fitted
    beta 0.5 here, an AVX2 one 1.0 (OPENBLAS_CORETYPE=SkylakeX / Haswell)."""
    light = lambda d: _radiance(d, **SUN)
    truth = ([0.0, 0.25, 0.5, 0.25], 1.0, 0.5)
    fit = _fit(_capture(*truth, light), scene.sun_sky_env(128, **SUN))
    assert fit.candidate[1:] == fit.best[1:] == (1.0, 0.5), (fit.best, fit.plausible[:3])
    assert np.allclose(rl.mix_weights(fit.kernel), truth[0]), fit.kernel
    # the evidence is plain: the default is far outside the noise, and explains views it did not see far worse
    d = cb.key(*cb.DEFAULT_TRANSFER)
    assert d not in fit.plausible and fit.scores[d] - fit.score > 5 * fit.se[d]
    assert fit.score < 0.25 * fit.scores[d]


def test_view_independent_colours_fit_no_forward_scattering():
    light = lambda d: _radiance(d, **{**SUN, "sun": (-0.2, 0.7, 0.3)})
    env = scene.sun_sky_env(128, **{**SUN, "sun": (-0.2, 0.7, 0.3)})
    samples = _capture([1, 0, 0, 0], 0.0, 0.8, light, seed=5)
    fit = _fit(samples, env, basis=tuple(rl.MIX_BASIS))
    assert fit.best[:2] == (rl.mix_kernel([1, 0, 0, 0]), 0.0)
    # without lambert in the basis (the default), the nearest: view-independent still
    assert _fit(samples, env).forward == 0.0


def test_a_capture_light_from_everywhere_keeps_the_default_kernel():
    """Under light of one radiance from every direction every kernel gives every orientation the same light:
    the capture cannot tell the kernels apart (the candidates within noise span them all), and the fit keeps
    the default's kernel rather than whichever fits the noise best; the colours do not change with the view,
    which it does see (no forward scattering)."""
    flat = EnvMap(np.full((32, 64, 3), 0.5, np.float32), "flat")
    samples = _capture([0, 0, 0.5, 0.5], 0.0, 0.8, lambda d: np.full((len(d), 3), 0.5), seed=2)
    fit = _fit(samples, flat)
    kernels = {c[0] for c in fit.plausible}
    assert len(kernels) >= 10 and fit.candidate[:2] == (cb.DEFAULT_TRANSFER[0], 0.0), (len(kernels), fit.candidate)
    assert fit.best != fit.candidate   # the best by a hair is another kernel: noise, not evidence


def test_simplex_weights():
    w = cb.simplex_weights(4, 4)
    assert len(w) == 35 and np.allclose(w.sum(1), 1.0) and (w >= 0).all()
    assert len({tuple(r) for r in w}) == 35


def test_view_folds_are_sectors():
    x = np.zeros((16, 3))
    az = np.radians(np.arange(16) * 22.5)
    v = np.stack([np.cos(az), np.sin(az), np.zeros(16)], 1)
    fold = cb.view_folds(cb.CaptureSamples(x, v, v, np.ones(16), np.arange(16)), (0, 0, 1), 4)
    assert sorted(np.bincount(fold).tolist()) == [4, 4, 4, 4]
    assert all(len(set(fold[(np.arange(4) + 4 * k + s) % 16])) <= 2 for k in range(4) for s in range(4))


#: forward_quadrature against the brute-force reference: largest and median relative error per g of
#: calibrate.FORWARD_GS (measured 0.04 / 0.002 at g 0.5, 0.13 / 0.002 at 0.8, 0.25 / 0.044 at 0.9, where the
#: phase is narrower than the 11-degree pixels; the SG lobes as point lights were off by a median of 9-58 %).
QUAD_TOL = {0.5: (0.08, 0.005), 0.8: (0.2, 0.008), 0.9: (0.35, 0.07)}


def test_forward_quadrature_is_the_brute_force_integral():
    """The fit's forward term F_K,g(n, v) over the map's pixels against the reference integrated over a
    Fibonacci sphere of the analytic radiance (beta 1 minus beta 0), for each basis kernel the fit uses."""
    light = lambda d: _radiance(d, **SUN)
    rng = np.random.default_rng(3)
    n, v = (x / np.linalg.norm(x, axis=1, keepdims=True) for x in rng.normal(size=(2, 300, 3)))
    env = scene.sun_sky_env(128, **SUN)
    for w in ([0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]):
        q = cb.forward_quadrature(env, (0, 0, 1), [rl.mix_kernel(w)], n, v, cb.FORWARD_GS)[0]
        for gi, g in enumerate(cb.FORWARD_GS):
            ref = reference_transfer(n, v, w, 1.0, g, light) - reference_transfer(n, v, w, 0.0, g, light)
            err = np.abs(q[gi] / ref - 1)
            assert err.max() <= QUAD_TOL[g][0] and np.median(err) <= QUAD_TOL[g][1], (w, g, err.max(), np.median(err))


def test_basis_transfers_do_not_hang_on_the_sg_fit():
    """Two SG fits of one map (where L-BFGS-B stops differs between machines) give the same basis transfers."""
    from render.shading.sg_fit import fit_env_sg

    env = scene.sun_sky_env(64, **SUN)
    samples = _capture([0, 1, 0, 0], 1.0, 0.8, lambda d: _radiance(d, **SUN))
    sub = cb.CaptureSamples(*(a[::40] for a in (samples.points, samples.views, samples.normals,
                                                 samples.luminance, samples.view_index)))
    a = cb.basis_transfers(sub, env, (0, 0, 1), fit_env_sg(env, rl.RELIGHT_SG_K, maxiter=40), cb.FIT_BASIS)
    b = cb.basis_transfers(sub, env, (0, 0, 1), fit_env_sg(env, rl.RELIGHT_SG_K, maxiter=1000), cb.FIT_BASIS)
    for x, y in zip(a, b):
        assert np.array_equal(x, y)

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
    d = _fibonacci(QUAD_DIRS)
    lw = light(d) @ LUMA * (4 * np.pi / QUAD_DIRS)
    out = np.empty(len(normals))
    for s in range(0, len(normals), 2000):
        c = normals[s:s + 2000] @ d.T
        k = sum(w * f(c) for w, f in zip(weights, REF_KERNELS) if w)
        if beta:   # the phase term only where it counts (exact: beta = 0 multiplies it away)
            k = k * (1 + beta * (1 - g * g) / (1 + g * g - 2 * g * -(views[s:s + 2000] @ d.T)) ** 1.5)
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
    """The forward scattering exactly, the kernel to one step of the grid: the fit's forward term takes each SG
    lobe of the map as a point light (transfer.forward_transfer) where the reference integrates the phase over
    the sky, so a neighbouring mixture of the near-alike wrap and half-lambert kernels can fit a little better."""
    light = lambda d: _radiance(d, **SUN)
    truth = ([0.0, 0.25, 0.5, 0.25], 1.0, 0.5)
    fit = _fit(_capture(*truth, light), scene.sun_sky_env(128, **SUN))
    assert fit.candidate[1:] == fit.best[1:] == (1.0, 0.5), (fit.best, fit.plausible[:3])
    assert 0.5 * np.abs(rl.mix_weights(fit.kernel) - np.array(truth[0])).sum() <= 0.5 + 1e-9, fit.kernel
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

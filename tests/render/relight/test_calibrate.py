"""The relighting transfer fitted to the capture (render.relight.calibrate): colours made by a known
transfer times a per-voxel colour must give that transfer back (kernel "auto" through the GL pass:
test_relight.py::test_auto_kernel_twin)."""

from __future__ import annotations

from functools import partial

import numpy as np

from render.relight import calibrate as cb
from render.shading import transfer as rl
from render.shading.envmap import EnvMap
from tests import scenes as scene

#: Multiplicative noise on the synthetic capture colours (sensor noise, 2 %).
NOISE = 0.02


#: The capture / new maps of these tests: a softer, wider sun than tests.scenes' default.
_sun_sky = partial(scene.sun_sky_env, sun=(0.6, -0.3, 0.5), ambient=0.2, sky=0.3, power=30.0, sharpness=40.0)


def _capture(kernel: str, beta: float, g: float, env: EnvMap, seed: int = 0) -> cb.CaptureSamples:
    """A unit sphere seen from 16 cameras on two rings; each pixel's luminance = a random colour per voxel
    of the fit's cube x the transfer (kernel, beta, g) under ``env`` (no regularisation), 2 % noise."""
    rng = np.random.default_rng(seed)
    n = rng.normal(size=(40_000, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    az = np.radians(np.arange(16) * 22.5)
    el = np.radians(np.where(np.arange(16) % 2, 35.0, -10.0))
    cams = 4.0 * np.stack([np.cos(az) * np.cos(el), np.sin(az) * np.cos(el), np.sin(el)], 1)
    xs, vs, ns, ks = [], [], [], []
    for k, c in enumerate(cams):
        v = c - n
        v /= np.linalg.norm(v, axis=1, keepdims=True)
        seen = np.sum(v * n, 1) > 0.1
        xs.append(n[seen])
        vs.append(v[seen])
        ns.append(n[seen])
        ks.append(np.full(int(seen.sum()), k))
    x, v, nn = np.concatenate(xs), np.concatenate(vs), np.concatenate(ns)
    lt = rl.relight_lighting(env, kernel=kernel)
    t = rl.unoccluded_transfer(lt, nn) + beta * rl.forward_transfer(lt, nn, v, g)
    L = cb.GROUP_RES
    ijk = np.clip(np.floor((x + 1.2) / (2.4 / L)).astype(np.int64), 0, L - 1)
    albedo = np.random.default_rng(seed + 1).uniform(0.1, 1.0, L ** 3)[(ijk[:, 0] * L + ijk[:, 1]) * L + ijk[:, 2]]
    y = albedo * (t @ cb.LUMA) * np.exp(NOISE * rng.normal(size=len(x)))
    return cb.CaptureSamples(x, v, nn, y, np.concatenate(ks))


def test_fit_gives_back_the_transfer_that_made_the_colours():
    env = _sun_sky()
    truth = (rl.mix_kernel([0.0, 0.25, 0.5, 0.25]), 1.0, 0.5)
    samples = _capture(*truth, env)
    fit = cb.fit_transfer(samples, env, (0, 0, 1), np.full(3, -1.2), 2.4, regularise=0.0)
    assert (fit.kernel, fit.forward, fit.forward_g) == truth
    # and the margin is real: the default fixed transfer explains the colours far worse
    wrap = fit.best_fixed(rl.mix_kernel([0, 1, 0, 0]), rl.FORWARD_SCATTER, rl.FORWARD_G)
    assert fit.score < 0.5 * wrap, (fit.score, wrap)
    assert fit.score < 2 * NOISE ** 2  # what is left is the noise


def test_view_independent_colours_fit_no_forward_scattering():
    env = _sun_sky(sun=(-0.2, 0.7, 0.3))
    samples = _capture(rl.mix_kernel([1, 0, 0, 0]), 0.0, 0.8, env, seed=5)
    fit = cb.fit_transfer(samples, env, (0, 0, 1), np.full(3, -1.2), 2.4, regularise=0.0, basis=tuple(rl.MIX_BASIS))
    assert (fit.kernel, fit.forward) == (rl.mix_kernel([1, 0, 0, 0]), 0.0)
    # without lambert in the basis (the default), the nearest: view-independent still
    assert cb.fit_transfer(samples, env, (0, 0, 1), np.full(3, -1.2), 2.4, regularise=0.0).forward == 0.0


def test_simplex_weights():
    w = cb.simplex_weights(4, 4)
    assert len(w) == 35 and np.allclose(w.sum(1), 1.0) and (w >= 0).all()
    assert len({tuple(r) for r in w}) == 35

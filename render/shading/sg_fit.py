"""Fit an environment map with K spherical Gaussians (docs/methods.md §3; seed 004: L-BFGS-B).

Loss: solid-angle-weighted squared radiance error over the sphere, relative to the map's
energy, ``sum Omega |sum_k G_k - L|^2 / sum Omega |L|^2`` on the map area-resampled to
``FIT_HEIGHT`` rows. Parameters: unnormalised axes (3K), log sharpness (K), amplitudes (3K,
bounded >= 0); analytic gradient; scipy L-BFGS-B. Initialisation is greedy: each new lobe sits
on the brightest remaining residual pixel. K can be chosen from an error target
(:func:`fit_env_sg_target`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from render.shading.envmap import EnvMap
from render.shading.lights import LUMA

#: Height of the map the fit runs on (the fit is of low-frequency lighting).
FIT_HEIGHT = 32
#: Sharpness bounds of the fitted lobes.
FIT_LAMBDA_RANGE = (0.5, 2000.0)
#: L-BFGS-B iteration cap.
FIT_MAXITER = 300
#: K values tried by fit_env_sg_target, in order.
K_LADDER = (1, 2, 4, 6, 10, 16, 24, 32, 48, 64, 96, 128)


@dataclass(frozen=True)
class SGFit:
    """K lobes: axes (K,3) unit, lams (K,), mus (K,3) linear RGB radiance; rel_error: the fit's
    relative L2 radiance error on the fit grid; seconds: fit time."""

    axes: np.ndarray
    lams: np.ndarray
    mus: np.ndarray
    rel_error: float
    seconds: float

    @property
    def k(self) -> int:
        return len(self.lams)


def _pack(v, loglam, mu):
    return np.concatenate([v.ravel(), loglam, mu.ravel()])


def _unpack(x, k):
    return x[:3 * k].reshape(k, 3), x[3 * k:4 * k], x[4 * k:].reshape(k, 3)


def _loss_grad(x, k, dirs, omega, target, norm):
    v, loglam, mu = _unpack(x, k)
    vn = np.linalg.norm(v, axis=1, keepdims=True)
    p = v / vn
    lam = np.exp(loglam)
    cosang = dirs @ p.T  # (P, K)
    e = np.exp(lam[None, :] * (cosang - 1.0))
    model = e @ mu
    r = (model - target) * omega[:, None]  # (P, 3) weighted residual
    loss = float(np.sum((model - target) ** 2 * omega[:, None]) / norm)
    g_mu = 2 * e.T @ r / norm
    rm = r @ mu.T  # (P, K): sum_c r_c mu_kc
    g_lam = 2 * np.sum(rm * e * (cosang - 1.0), axis=0) * lam / norm
    g_p = 2 * ((rm * e).T @ dirs) * lam[:, None] / norm  # (K, 3)
    g_v = (g_p - np.sum(g_p * p, axis=1, keepdims=True) * p) / vn
    return loss, _pack(g_v, g_lam, g_mu)


def fit_env_sg(env: EnvMap, k: int, fit_height: int = FIT_HEIGHT, maxiter: int = FIT_MAXITER,
               seed_fit: SGFit | None = None) -> SGFit:
    """Fit ``k`` SG lobes to ``env`` (see module doc). ``seed_fit`` (fewer lobes) seeds the
    first lobes; the rest are placed greedily."""
    from scipy.optimize import minimize

    t0 = time.perf_counter()
    src = env.resized(fit_height) if env.height != fit_height else env
    dirs = src.pixel_directions().reshape(-1, 3)
    omega = src.pixel_solid_angles().reshape(-1)
    target = src.data.reshape(-1, 3).astype(np.float64)
    norm = float(np.sum(target**2 * omega[:, None]))
    if norm == 0:
        raise ValueError(f"fit_env_sg: environment {env.name!r} is black")
    lam0 = float(np.clip(k * 2.0, FIT_LAMBDA_RANGE[0], 200.0))
    axes, lams, mus = [], [], []
    if seed_fit is not None:
        axes, lams, mus = list(seed_fit.axes), list(seed_fit.lams), list(seed_fit.mus)
    res = target.copy()
    if axes:
        res -= np.exp(np.array(lams)[None] * (dirs @ np.array(axes).T - 1)) @ np.array(mus)
    while len(axes) < k:
        i = int(np.argmax(res @ LUMA))
        mu = np.maximum(res[i], 0.0)
        axes.append(dirs[i])
        lams.append(lam0)
        mus.append(mu)
        res -= np.exp(lam0 * (dirs @ dirs[i] - 1))[:, None] * mu
    x0 = _pack(np.array(axes), np.log(np.array(lams)), np.array(mus))
    lo, hi = np.log(FIT_LAMBDA_RANGE[0]), np.log(FIT_LAMBDA_RANGE[1])
    x0[3 * k:4 * k] = np.clip(x0[3 * k:4 * k], lo, hi)
    bounds = [(None, None)] * (3 * k) + [(lo, hi)] * k + [(0.0, None)] * (3 * k)
    with _one_blas_thread():  # L-BFGS-B's tiny BLAS calls crawl with many threads on a busy CPU
        r = minimize(_loss_grad, x0, args=(k, dirs, omega, target, norm), jac=True,
                     method="L-BFGS-B", bounds=bounds, options={"maxiter": maxiter})
    v, loglam, mu = _unpack(r.x, k)
    return SGFit(v / np.linalg.norm(v, axis=1, keepdims=True), np.exp(loglam), mu,
                 float(np.sqrt(r.fun)), time.perf_counter() - t0)


def _one_blas_thread():
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # optional: only a speed matter
        import contextlib
        return contextlib.nullcontext()
    return threadpool_limits(limits=1, user_api="blas")


def fit_env_sg_target(env: EnvMap, target_rel_error: float, ks=K_LADDER, **kw) -> SGFit:
    """The smallest K of ``ks`` whose fit reaches ``target_rel_error`` (else the largest K's fit);
    each fit is seeded with the previous one."""
    fit = None
    for k in ks:
        fit = fit_env_sg(env, k, seed_fit=fit, **kw)
        if fit.rel_error <= target_rel_error:
            break
    return fit

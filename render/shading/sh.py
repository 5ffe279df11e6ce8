"""Real spherical harmonics of environment radiance, and diffuse irradiance from them
(Ramamoorthi & Hanrahan 2001, "An efficient representation for irradiance environment maps").

Basis: real SH without the Condon-Shortley phase (the graphics convention), index
``k = l (l + 1) + m`` for ``l = 0..lmax, m = -l..l``; for ``lmax = 2`` these are the familiar
nine: 0.282095, 0.488603 (y, z, x), 1.092548 (xy, yz), 0.315392 (3z^2 - 1), 1.092548 xz,
0.546274 (x^2 - y^2). Directions are world coordinates (+z up), independent of the equirect
layout.

Irradiance (cosine-weighted integral of radiance over the hemisphere around n)::

    E(n) = integral L(w) max(0, n.w) dw = sum_lm A_l L_lm Y_lm(n)

with A_0 = pi, A_1 = 2 pi / 3, A_l = 0 for odd l > 1, and for even l
A_l = 2 pi (-1)^(l/2 - 1) / ((l + 2)(l - 1)) * l! / (2^l ((l/2)!)^2).

SH9 (lmax 2) is smooth and cheap but cannot follow a small bright source across the terminator
of the cosine lobe; the measured errors are in ``furrow/bench/shading.py`` and the tests. For <= 1%
accuracy use :mod:`render.shading.irradiance` (dominant lights + SH of the remainder).
GLSL twin: ``render/shaders/sh9.glsl`` (``u_sh9[9]`` holds ``A_l * L_lm``, i.e. the output of
:func:`sh9_glsl_uniform`).
"""

from __future__ import annotations

from math import factorial, pi, sqrt

import numpy as np

from render.shading.envmap import EnvMap


def sh_count(lmax: int) -> int:
    """Number of coefficients up to and including band lmax: (lmax + 1)^2."""
    return (int(lmax) + 1) ** 2


def sh_basis(dirs, lmax: int = 2) -> np.ndarray:
    """(..., 3) unit directions -> (..., (lmax+1)^2) float64 real SH values."""
    d = np.asarray(dirs, np.float64)
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    out = np.empty(d.shape[:-1] + (sh_count(lmax),))
    xy = x + 1j * y
    pw = np.ones_like(xy)  # (x + i y)^m = sin^m(theta) e^{i m phi}
    for m in range(lmax + 1):
        # Q_l^m(z) = P_l^m(z) / sin^m(theta) (no Condon-Shortley phase)
        q_prev = None
        q = np.full_like(z, float(_double_factorial(2 * m - 1)))
        for l in range(m, lmax + 1):
            if l == m + 1:
                q_prev, q = q, z * (2 * m + 1) * q
            elif l > m + 1:
                q_prev, q = q, ((2 * l - 1) * z * q - (l + m - 1) * q_prev) / (l - m)
            k = sqrt((2 * l + 1) / (4 * pi) * factorial(l - m) / factorial(l + m))
            if m == 0:
                out[..., l * (l + 1)] = k * q
            else:
                out[..., l * (l + 1) + m] = sqrt(2) * k * q * pw.real
                out[..., l * (l + 1) - m] = sqrt(2) * k * q * pw.imag
        pw = pw * xy
    return out


def _double_factorial(n: int) -> int:
    r = 1
    while n > 1:
        r *= n
        n -= 2
    return r


def cosine_lobe_coefficients(lmax: int) -> np.ndarray:
    """(lmax+1,) A_l: SH coefficients of the clamped cosine kernel (convolution weights)."""
    a = np.zeros(lmax + 1)
    for l in range(lmax + 1):
        if l == 0:
            a[l] = pi
        elif l == 1:
            a[l] = 2 * pi / 3
        elif l % 2 == 0:
            a[l] = (2 * pi * (-1) ** (l // 2 - 1) / ((l + 2) * (l - 1))
                    * factorial(l) / (2**l * factorial(l // 2) ** 2))
    return a


def sh_project(env: EnvMap, lmax: int = 2) -> np.ndarray:
    """((lmax+1)^2, 3) float64 radiance SH coefficients, L_lm = sum_px L Y_lm Omega
    (solid-angle weighted pixel-centre quadrature)."""
    h = env.height
    dirs = env.pixel_directions()
    w = env.pixel_solid_angles()
    out = np.zeros((sh_count(lmax), 3))
    step = max(1, 65536 // env.width)  # rows per chunk, bounded memory
    for r in range(0, h, step):
        y = sh_basis(dirs[r:r + step], lmax)
        out += np.einsum("hwk,hwc,hw->kc", y, env.data[r:r + step].astype(np.float64), w[r:r + step])
    return out


def sh_irradiance(coeffs, normals, lmax: int | None = None) -> np.ndarray:
    """(N, 3) irradiance E(n) from radiance SH coefficients ((lmax+1)^2, 3) at unit normals,
    clamped at 0 (truncated SH rings below zero opposite bright sources; sh9.glsl clamps too)."""
    c = np.asarray(coeffs, np.float64)
    if lmax is None:
        lmax = int(round(sqrt(c.shape[0]))) - 1
    if c.shape[0] != sh_count(lmax):
        raise ValueError(f"sh_irradiance: {c.shape[0]} coefficients is not (lmax+1)^2")
    a = cosine_lobe_coefficients(lmax)
    al = np.concatenate([np.full(2 * l + 1, a[l]) for l in range(lmax + 1)])
    n = np.asarray(normals, np.float64)
    return np.maximum(sh_basis(n, lmax) @ (c * al[:, None]), 0.0)


def sh9_project(env: EnvMap) -> np.ndarray:
    """(9, 3) float64 radiance SH coefficients (bands 0-2) of ``env``."""
    return sh_project(env, 2)


def sh9_irradiance(coeffs, normals) -> np.ndarray:
    """(N, 3) irradiance from (9, 3) radiance SH coefficients (Ramamoorthi-Hanrahan)."""
    c = np.asarray(coeffs, np.float64)
    if c.shape != (9, 3):
        raise ValueError(f"sh9_irradiance: coefficients must be (9, 3), got {c.shape}")
    return sh_irradiance(c, normals, 2)


def sh9_glsl_uniform(coeffs) -> np.ndarray:
    """(9, 3) float32 values for ``uniform vec3 u_sh9[9]`` of sh9.glsl: the radiance
    coefficients already multiplied by the cosine-lobe weights A_l, so that the shader is
    ``E(n) = sum_k u_sh9[k] * Y_k(n)``."""
    c = np.asarray(coeffs, np.float64)
    if c.shape != (9, 3):
        raise ValueError(f"sh9_glsl_uniform: coefficients must be (9, 3), got {c.shape}")
    a = cosine_lobe_coefficients(2)
    al = np.array([a[0], a[1], a[1], a[1], a[2], a[2], a[2], a[2], a[2]])
    return (c * al[:, None]).astype(np.float32)


def irradiance_brute(env: EnvMap, normals) -> np.ndarray:
    """Reference: (N, 3) float64 E(n) = sum over every pixel of L max(0, n.w) Omega."""
    n = np.atleast_2d(np.asarray(normals, np.float64))
    d = env.pixel_directions().reshape(-1, 3)
    lw = env.data.reshape(-1, 3).astype(np.float64) * env.pixel_solid_angles().reshape(-1, 1)
    out = np.zeros((n.shape[0], 3))
    for s in range(0, n.shape[0], 256):
        out[s:s + 256] = np.maximum(n[s:s + 256] @ d.T, 0) @ lw
    return out

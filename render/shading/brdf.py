"""Energy-preserving Blinn-Phong (docs/methods.md §4, Kakimoto et al. Eq. 1-5).

Blinn's highlight I_s = k_s I_l (N.H)^n loses energy as n grows: with the light along the
normal (L = N) and H the half vector of L and the view V, the highlight integrated over all view
directions V of the hemisphere (d omega_V, no extra cosine) is

    T_s(n) = k_s I_l * 8 pi / (n + 2) * (1 - (sqrt(2)/2)^(n + 2))            (Eq. 5)

because alpha = angle(N, H) = theta_V / 2. The normalised lobe (Eq. 4)

    I_s = k_s I_l * (n + 2) / (8 pi) * cos^n(alpha)

therefore reflects ``1 - (sqrt(2)/2)^(n + 2)`` of the light: nearly all of it for any n, and
its peak grows with n. GLSL twin: ``render/shaders/shading_brdf.glsl``.
"""

from __future__ import annotations

import numpy as np

_HALF_SQRT2 = np.sqrt(2.0) / 2.0


def blinn_phong_normalized(cos_alpha, n) -> np.ndarray:
    """(n + 2) / (8 pi) * cos^n(alpha) for cos_alpha > 0, else 0 (Eq. 4 without k_s I_l).
    cos_alpha = N.H; n >= 0 the Phong exponent (broadcast). Underflows to 0, never NaN."""
    c = np.asarray(cos_alpha, np.float64)
    n = np.asarray(n, np.float64)
    if np.any(n < 0):
        raise ValueError("blinn_phong_normalized: exponent n must be >= 0")
    pos = c > 0
    with np.errstate(divide="ignore", under="ignore"):
        val = np.where(pos, np.exp(n * np.log(np.where(pos, c, 1.0))), 0.0)
    return (n + 2.0) / (8.0 * np.pi) * val


def blinn_phong_energy(n) -> np.ndarray:
    """Energy of the normalised lobe over the hemisphere of views for L = N (Eq. 5 times the
    Eq. 4 normalisation): 1 - (sqrt(2)/2)^(n + 2)."""
    n = np.asarray(n, np.float64)
    return 1.0 - _HALF_SQRT2 ** (n + 2.0)


def blinn_phong_raw_energy(n) -> np.ndarray:
    """T_s(n) / (k_s I_l) of Eq. 5: energy of the un-normalised lobe cos^n(alpha),
    8 pi / (n + 2) * (1 - (sqrt(2)/2)^(n + 2))."""
    n = np.asarray(n, np.float64)
    return 8.0 * np.pi / (n + 2.0) * blinn_phong_energy(n)


def half_vector(l, v) -> np.ndarray:
    """(..., 3) unit half vector of unit light and view directions (undefined for l = -v:
    returns l there)."""
    l = np.asarray(l, np.float64)
    v = np.asarray(v, np.float64)
    s = l + v
    nrm = np.linalg.norm(s, axis=-1, keepdims=True)
    return np.where(nrm > 1e-12, s / np.where(nrm > 1e-12, nrm, 1.0), l)

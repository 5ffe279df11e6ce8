"""Hair / fur fibre scattering with the R, TT and TRT lobes (numpy, float64 reference).

The model is the energy-conserving hair BSDF of Chiang, Bitterli, Tappan and Burley 2016, "A
Practical and Controllable Hair and Fur Model for Production Path Tracing" (the model of pbrt-v3's
``HairBSDF`` and Blender's Principled Hair), built on Marschner, Jensen, Cammarano, Worley and
Hanrahan 2003, "Light Scattering from Human Hair Fibers" (the R / TT / TRT decomposition) and on
d'Eon, Francois, Hill, Letteri and Aubry 2011, "An Energy-Conserving Hair Reflectance Model" (the
longitudinal lobe M_p).  For a fibre with tangent T, outgoing direction wo and incident wi:

    S(wo, wi, h) = sum_{p=0..2} M_p(theta_i, theta_o') A_p(h) N_p(phi, h)  +  M_3 A_3 / (2 pi)

where theta = angles from the normal plane (sin theta = w . T), phi = the azimuth between wo and wi
around T, h in [-1, 1] the offset across the fibre; theta_o' is theta_o turned by the cuticle-scale
tilt (-2 alpha for R, alpha for TT, 4 alpha for TRT).  M_p is d'Eon's normalised longitudinal lobe
(variance v_p from beta_m), A_p the attenuation (Fresnel at the entry angle, absorption sigma_a
along the refracted chord, the residual p >= 3 summed as a geometric series), N_p a trimmed
logistic around the deflection Phi(p, h) = 2 p gamma_t - 2 gamma_o + p pi (scale from beta_n).

S already includes the cosine: the radiance scattered towards wo is L_o = integral S L_i d omega_i,
and for a directional light of irradiance E (on a surface facing it) L_o = S E.  Energy: with no
absorption the integral of S over the sphere is 1 for every wo and h (white furnace, tested).

Seen from afar a fibre is narrower than a pixel, so the renderer uses the width average
``S_far = 1/2 integral_{-1}^{1} S dh`` (Gauss-Legendre in h, :func:`fibre_scattering`); only |phi|
matters there.  Colour: ``sigma_a`` from a desired fur colour by Chiang et al.'s inversion
(:func:`sigma_a_from_colour`, which gives that colour to a *volume* of fibres, multiple scattering
included).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Gauss-Legendre nodes across the fibre width for the width-averaged lobe (error against 2000
#: nodes measured in tests/render/shading/test_hair.py: below 2% of the peak at beta_n = 0.3).
WIDTH_NODES = 16
#: Residual lobes: p = 0, 1, 2 explicit, p >= 3 summed.
P_MAX = 3


@dataclass(frozen=True)
class HairParams:
    """Fibre parameters of the Chiang et al. 2016 hair model."""

    beta_m: float = 0.3
    """Longitudinal roughness in (0, 1] (pbrt-v3's default 0.3)."""
    beta_n: float = 0.3
    """Azimuthal roughness in (0, 1] (pbrt-v3's default 0.3)."""
    alpha_deg: float = 2.0
    """Tilt of the cuticle scales (degrees; human hair 2-3)."""
    eta: float = 1.55
    """Index of refraction of the fibre (keratin)."""

    def __post_init__(self) -> None:
        if not (0 < self.beta_m <= 1 and 0 < self.beta_n <= 1):
            raise ValueError(f"hair: beta_m and beta_n must be in (0, 1], got {self.beta_m}, {self.beta_n}")
        if not 1.0 < self.eta < 3.0 or not abs(self.alpha_deg) < 15:
            raise ValueError(f"hair: eta must be in (1, 3) and |alpha| < 15 degrees, got {self.eta}, {self.alpha_deg}")

    def variances(self) -> np.ndarray:
        """(4,) longitudinal variances v_0..v_3 (Chiang et al. eq. 7: v_1 = v_0 / 4, v_2+ = 4 v_0)."""
        b = self.beta_m
        v0 = (0.726 * b + 0.812 * b * b + 3.7 * b**20) ** 2
        return np.array([v0, 0.25 * v0, 4 * v0, 4 * v0])

    def azimuthal_scale(self) -> float:
        """Logistic scale s of N_p (Chiang et al. eq. 8)."""
        b = self.beta_n
        return float(np.sqrt(np.pi / 8) * (0.265 * b + 1.194 * b * b + 5.372 * b**22))


def sigma_a_from_colour(colour, beta_n: float = 0.3) -> np.ndarray:
    """Absorption coefficient (per unit fibre radius) giving a fur volume the linear ``colour``
    (Chiang et al. 2016 eq. 9); ``colour`` is clipped to [1e-4, 1 - 1e-4]."""
    c = np.clip(np.asarray(colour, np.float64), 1e-4, 1 - 1e-4)
    b = beta_n
    den = 5.969 - 0.215 * b + 2.532 * b**2 - 10.73 * b**3 + 5.574 * b**4 + 0.245 * b**5
    return (np.log(c) / den) ** 2


def longitudinal(cos_i, cos_o, sin_i, sin_o, v: float) -> np.ndarray:
    """d'Eon et al. 2011's M_p = exp(-b) I0(a) / (2 v sinh(1 / v)) with a = cos_i cos_o / v,
    b = sin_i sin_o / v; normalised so that integral M cos(theta_i) d theta_i = 1.  Evaluated in
    logs with the exponentially scaled I0 (scipy's ``i0e``), exact for every variance (pbrt-v3's
    10-term I0 series loses ~2 % near a = 12)."""
    from scipy.special import i0e

    a = np.asarray(cos_i, np.float64) * np.asarray(cos_o, np.float64) / v
    b = np.asarray(sin_i, np.float64) * np.asarray(sin_o, np.float64) / v
    return np.exp(np.log(i0e(a)) + a - b - 1 / v - np.log(v) - np.log1p(-np.exp(-2 / v)))


def fresnel_dielectric(cos_i, eta: float) -> np.ndarray:
    """Unpolarised Fresnel reflectance entering a dielectric of index ``eta`` from air."""
    c = np.clip(np.asarray(cos_i, np.float64), 0.0, 1.0)
    s_t = np.sqrt(np.maximum(1 - c * c, 0.0)) / eta
    c_t = np.sqrt(np.maximum(1 - s_t * s_t, 0.0))
    r_par = (eta * c - c_t) / (eta * c + c_t)
    r_perp = (c - eta * c_t) / (c + eta * c_t)
    return 0.5 * (r_par**2 + r_perp**2)


def attenuation(cos_o, h, sigma_a, eta: float) -> np.ndarray:
    """A_0..A_3 with shape (4, ..., 3): Fresnel at the entry angle, absorption along the chord."""
    cos_o = np.asarray(cos_o, np.float64)
    h = np.asarray(h, np.float64)
    sin_o = np.sqrt(np.maximum(1 - cos_o**2, 0))
    sin_t = sin_o / eta
    cos_t = np.sqrt(np.maximum(1 - sin_t**2, 0))
    etap = np.sqrt(np.maximum(eta * eta - sin_o**2, 0)) / np.maximum(cos_o, 1e-12)
    cos_gt = np.sqrt(np.maximum(1 - (h / etap) ** 2, 0))
    T = np.exp(-np.asarray(sigma_a, np.float64) * (2 * cos_gt / np.maximum(cos_t, 1e-12))[..., None])
    f = fresnel_dielectric(cos_o * np.sqrt(np.maximum(1 - h * h, 0)), eta)[..., None]
    a0 = np.broadcast_to(f, T.shape)
    a1 = (1 - f) ** 2 * T
    a2 = a1 * T * f
    a3 = a2 * f * T / (1 - T * f)
    return np.stack([a0, a1, a2, a3])


def _logistic(x, s):
    x = np.abs(x)
    e = np.exp(-x / s)
    return e / (s * (1 + e) ** 2)


def azimuthal(phi, p: int, s: float, gamma_o, gamma_t) -> np.ndarray:
    """N_p: logistic around Phi(p, h), trimmed to [-pi, pi] and normalised there."""
    d = np.asarray(phi, np.float64) - (2 * p * np.asarray(gamma_t) - 2 * np.asarray(gamma_o) + p * np.pi)
    d = np.mod(d + np.pi, 2 * np.pi) - np.pi
    norm = 1 / (1 + np.exp(-np.pi / s)) - 1 / (1 + np.exp(np.pi / s))
    return _logistic(d, s) / norm


def _tilted(sin_o, cos_o, alpha_rad: float):
    """(sin, cos) of theta_o' for p = 0, 1, 2 (tilts -2 alpha, alpha, 4 alpha); p = 3 untilted."""
    out = []
    for k in (-2.0, 1.0, 4.0, 0.0):
        a = k * alpha_rad
        out.append((sin_o * np.cos(a) + cos_o * np.sin(a), np.abs(cos_o * np.cos(a) - sin_o * np.sin(a))))
    return out


def scattering(sin_o, sin_i, phi, h, sigma_a, prm: HairParams = HairParams()) -> np.ndarray:
    """S(wo, wi, h) (module docstring), shape (..., 3): everything broadcast together, sigma_a
    (..., 3) per channel.  ``sin_o``, ``sin_i`` = w . T; ``phi`` = azimuth of wi minus that of wo."""
    sin_o, sin_i, phi, h = (np.asarray(a, np.float64) for a in (sin_o, sin_i, phi, h))
    cos_o = np.sqrt(np.maximum(1 - sin_o**2, 0))
    cos_i = np.sqrt(np.maximum(1 - sin_i**2, 0))
    v = prm.variances()
    s = prm.azimuthal_scale()
    etap = np.sqrt(np.maximum(prm.eta**2 - sin_o**2, 0)) / np.maximum(cos_o, 1e-12)
    gamma_o = np.arcsin(np.clip(h, -1, 1))
    gamma_t = np.arcsin(np.clip(h / etap, -1, 1))
    A = attenuation(cos_o, h, sigma_a, prm.eta)
    tilt = _tilted(sin_o, cos_o, np.radians(prm.alpha_deg))
    out = 0.0
    for p in range(P_MAX):
        so, co = tilt[p]
        m = longitudinal(cos_i, co, sin_i, so, v[p])
        out = out + (m * azimuthal(phi, p, s, gamma_o, gamma_t))[..., None] * A[p]
    m3 = longitudinal(cos_i, cos_o, sin_i, sin_o, v[P_MAX])
    return out + (m3 / (2 * np.pi))[..., None] * A[P_MAX]


def width_nodes(n: int = WIDTH_NODES) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre nodes h and weights w on [-1, 1] with sum(w) = 1 (the width average)."""
    x, w = np.polynomial.legendre.leggauss(n)
    return x, w / 2


def fibre_scattering(sin_o, sin_i, phi, sigma_a, prm: HairParams = HairParams(),
                     nodes: int = WIDTH_NODES) -> np.ndarray:
    """Width-averaged S_far(wo, wi) = 1/2 integral S dh (shape (..., 3))."""
    hs, ws = width_nodes(nodes)
    out = 0.0
    for h, w in zip(hs, ws):
        out = out + w * scattering(sin_o, sin_i, phi, h, sigma_a, prm)
    return out


def fibre_angles(tangent, wo, wi) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(sin theta_o, sin theta_i, phi) of directions ``wo``, ``wi`` (unit, (..., 3)) about the unit
    fibre ``tangent``; phi in [0, pi] (the width average depends on |phi| only)."""
    T = np.asarray(tangent, np.float64)
    wo = np.asarray(wo, np.float64)
    wi = np.asarray(wi, np.float64)
    so = np.sum(wo * T, -1)
    si = np.sum(wi * T, -1)
    po = wo - so[..., None] * T
    pi_ = wi - si[..., None] * T
    c = np.sum(po * pi_, -1) / np.maximum(np.linalg.norm(po, axis=-1) * np.linalg.norm(pi_, axis=-1), 1e-12)
    return np.clip(so, -1, 1), np.clip(si, -1, 1), np.arccos(np.clip(c, -1, 1))


def back_albedo(sigma_a, prm: HairParams = HairParams(), nodes: int = WIDTH_NODES) -> np.ndarray:
    """(..., 3) width-averaged energy of the lobes that leave on the side the light came from
    (R, TRT and the residual) at normal incidence: A_0 + A_2 + A_3 averaged over h."""
    hs, ws = width_nodes(nodes)
    A = attenuation(np.ones_like(hs), hs, np.asarray(sigma_a, np.float64)[..., None, :], prm.eta)
    return np.sum((A[0] + A[2] + A[3]) * ws[:, None], axis=-2)


#: Strand points per block of :func:`fibre_radiance` (bounds its temporaries to ~20 MB each).
RADIANCE_BLOCK = 8192


def log_i0e(x) -> np.ndarray:
    """log(I0(x) exp(-x)) for x >= 0 from the polynomials of Abramowitz & Stegun 9.8.1 / 9.8.2
    (relative error of I0 below 2e-7; tested against scipy's ``i0e``), float32-friendly."""
    x = np.asarray(x)
    small = x < 3.75
    t = np.where(small, x, 3.75) / 3.75
    t2 = t * t
    p_small = 1 + t2 * (3.5156229 + t2 * (3.0899424 + t2 * (1.2067492 + t2 * (0.2659732 + t2 * (0.0360768
                                                                                           + t2 * 0.0045813)))))
    xb = np.where(small, 3.75, x)
    u = 3.75 / xb
    p_big = (0.39894228 + u * (0.01328592 + u * (0.00225319 + u * (-0.00157565 + u * (0.00916281 + u * (
        -0.02057706 + u * (0.02635537 + u * (-0.01647633 + u * 0.00392377))))))))
    return np.where(small, np.log(p_small) - x, np.log(p_big) - 0.5 * np.log(xb))


def _m_fast(cos_i, cos_o, sin_i, sin_o, v):
    """M_p in float32; ``v`` a scalar or an array broadcasting with the angles."""
    v = np.asarray(v, np.float64)
    a = cos_i * cos_o / v.astype(np.float32)
    b = sin_i * sin_o / v.astype(np.float32)
    c = (-1 / v - np.log(v) - np.log1p(-np.exp(-2 / v))).astype(np.float32)
    return np.exp(log_i0e(a) + a - b + c)


def fibre_radiance(tangents, wo, light_dirs, light_power, visibility, sigma_a, prm: HairParams = HairParams(),
                   nodes: int = WIDTH_NODES, light_spread=None) -> np.ndarray:
    """(N, 3) radiance scattered once towards ``wo`` by N fibres lit by L directional lights:
    sum_l S_far(wo, d_l) power_l visibility_l.  The same sum as :func:`fibre_scattering` per light
    (tested: float32 round-off), factored and in float32 for speed: M_p per (fibre, light) with
    :func:`log_i0e`, A_p and the deflections per (fibre, h), the logistic per (fibre, light, h).

    tangents, wo: (N, 3) unit; light_dirs (L, 3) unit towards the lights; light_power (L, 3) their
    radiance integrated over solid angle; visibility (N, L) in [0, 1]; sigma_a (N, 3).

    ``light_spread`` (L,): angular variance (rad^2) of each light's extent, added to the variance
    of the longitudinal lobes and of the azimuthal logistic (a lobe convolved with the light's
    blob: both stay normalised), so that lobes narrower than the spacing of the lights that stand
    for an environment (``median_cut``) do not alias; 0 = point lights, exactly the sum above."""
    T = np.asarray(tangents, np.float64)
    out = np.zeros((len(T), 3))
    args = [np.asarray(a, np.float64) for a in (wo, visibility, sigma_a)]
    spread = np.zeros(len(light_dirs)) if light_spread is None else np.asarray(light_spread, np.float64)
    for a in range(0, len(T), RADIANCE_BLOCK):
        b = slice(a, a + RADIANCE_BLOCK)
        out[b] = _radiance_block(T[b], args[0][b], np.asarray(light_dirs, np.float64),
                                 np.asarray(light_power, np.float64), args[1][b], args[2][b], prm, nodes, spread)
    return out


def _radiance_block(T, wo, dirs, power, vis, sigma_a, prm, nodes, spread):
    f4 = np.float32
    N, L = len(T), len(dirs)
    so, si, phi = fibre_angles(T[:, None], wo[:, None], np.broadcast_to(dirs, (N, L, 3)))
    so = so[:, 0]
    co = np.sqrt(np.maximum(1 - so**2, 0))
    si, phi = si.astype(f4), phi.astype(f4)
    ci = np.sqrt(np.maximum(1 - si**2, 0))
    hs, ws = width_nodes(nodes)
    etap = np.sqrt(np.maximum(prm.eta**2 - so**2, 0)) / np.maximum(co, 1e-12)
    gamma_o = np.arcsin(hs)[None]                                        # (1, H)
    gamma_t = np.arcsin(np.clip(hs[None] / etap[:, None], -1, 1))        # (N, H)
    A = attenuation(co[:, None], hs[None], sigma_a[:, None], prm.eta)    # (4, N, H, 3)
    A = (A * ws[None, None, :, None]).astype(f4)                          # weights folded in
    v = prm.variances()[:, None] + spread[None]                            # (4, L)
    s0 = prm.azimuthal_scale()
    s = np.sqrt(s0**2 + 3 * spread / np.pi**2)                              # logistic variance s^2 pi^2 / 3
    norm = 1 / (1 / (1 + np.exp(-np.pi / s)) - 1 / (1 + np.exp(np.pi / s)))
    s_b, k_b = s.astype(f4)[None, :, None], (norm / s).astype(f4)[None, :, None]
    tilt = _tilted(so, co, np.radians(prm.alpha_deg))
    total = np.zeros((N, L, 3), f4)
    for p in range(P_MAX):
        m = _m_fast(ci, tilt[p][1][:, None].astype(f4), si, tilt[p][0][:, None].astype(f4), v[p][None])  # (N, L)
        defl = np.mod(2 * p * gamma_t - 2 * gamma_o + p * np.pi + np.pi, 2 * np.pi) - np.pi  # in [-pi, pi)
        d = phi[:, :, None] - defl[:, None, :].astype(f4)                   # in [-pi, 2 pi)
        d = np.minimum(np.abs(d), f4(2 * np.pi) - d)                      # |wrapped to [-pi, pi]|
        e = np.exp(-d / s_b)
        n = e / (1 + e) ** 2 * k_b                                         # trimmed logistic (N, L, H)
        total += m[..., None] * np.matmul(n, A[p])
    m3 = _m_fast(ci, co[:, None].astype(f4), si, so[:, None].astype(f4), v[P_MAX][None])
    total += (m3 / f4(2 * np.pi))[..., None] * A[P_MAX].sum(1)[:, None]
    return np.einsum("nlc,lc,nl->nc", total.astype(np.float64), power, vis)

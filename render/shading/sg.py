"""Spherical Gaussians (docs/methods.md §3; seed 001 Eq. 6, 11-18; seed 004 Eq. 3, A.1-A.2).

    G(i; p, lambda, mu) = mu * exp(lambda * (i.p - 1)),  p unit axis, lambda >= 0, mu RGB.

Everything is float64 and written so that nothing overflows or loses the hard cases of
docs/methods.md §5: lambda from 1e-3 to 1e5 (the exponent lambda (i.p - 1) is always <= 0; 1 - i.p is
computed as |i - p|^2 / 2), antipodal product axes (|p_m| -> 0, the product is then a constant),
lambda -> 0 (integrals use expm1).

Visibility (SSDF, docs/methods.md §3): f_h(theta_d, lambda) = integral of G(i; p, lambda, 1) over the
visible side of a great circle at signed angular distance theta_d from the axis
(theta_d = pi/2: the hemisphere centred on p; theta_d = -pi/2: the opposite one). The printed
fits of seeds 001 / 004 have typos (docs/methods.md §3), so we compute f_h exactly (:func:`fh_exact`,
vectorised quadrature, checked against scipy.quad) and fit our own table (:func:`fh_fit`,
bilinear in (warped theta_d, log10 lambda), GLSL twin in ``shading_sg.glsl``); the printed fits
are kept (:func:`fh_printed_001`, :func:`fh_printed_004`) only to measure how wrong they are.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from capture.sampling import cell_centres, sample_grid

#: Clamped cosine max(0, i.n) as one SG (Wang et al. 2009; seed 004): sharpness and amplitude.
COS_LOBE_LAMBDA = 2.133
COS_LOBE_MU = 1.170
#: |p_m| below this: the product of two SGs is treated as a constant (axis arbitrary).
PRODUCT_AXIS_EPS = 1e-12
#: f_h table: sharpness range (log10) and resolution; theta_d warp scale (see _fh_warp).
FH_LOG10_LAMBDA = (-3.0, 5.0)
FH_TABLE_SHAPE = (129, 161)  # (warped theta_d nodes, log10 lambda nodes)
FH_WARP_Y = 6.0
#: Gauss-Legendre nodes of the exact f_h quadrature (middle piece).
FH_GL_NODES = 96


def _unit(v) -> np.ndarray:
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def one_minus_dot(a, b) -> np.ndarray:
    """1 - a.b for unit vectors, computed as |a - b|^2 / 2 (no cancellation for a ~ b)."""
    d = np.asarray(a, np.float64) - np.asarray(b, np.float64)
    return 0.5 * np.sum(d * d, axis=-1)


def sg_eval(dirs, axis, lam, mu=1.0) -> np.ndarray:
    """G at unit ``dirs`` (..., 3) for one SG (axis (3,), lam scalar, mu scalar or (C,)):
    returns (...,) or (..., C)."""
    e = np.exp(-np.asarray(lam, np.float64) * one_minus_dot(dirs, axis))
    mu = np.asarray(mu, np.float64)
    return e[..., None] * mu if mu.ndim else e * mu


def sg_mixture_eval(dirs, axes, lams, mus) -> np.ndarray:
    """(N, C) sum of K SGs (axes (K,3), lams (K,), mus (K,C)) at dirs (N,3)."""
    d = np.atleast_2d(np.asarray(dirs, np.float64))
    e = np.exp(np.asarray(lams, np.float64)[None, :] * (d @ np.asarray(axes, np.float64).T - 1.0))
    return e @ np.asarray(mus, np.float64)


def sg_product(p1, l1, mu1, p2, l2, mu2):
    """The product of two SGs as one SG (seed 001 Eq. 11), broadcasting over leading axes.

    Returns (axis, lam, mu). With p_m = (l1 p1 + l2 p2) / (l1 + l2): lam = |l1 p1 + l2 p2|,
    axis = p_m / |p_m|, mu = mu1 mu2 exp(lam - l1 - l2); the exponent is computed as
    -2 l1 l2 (1 - p1.p2) / (lam + l1 + l2) (no cancellation, never positive). When |p_m| -> 0
    (antipodal axes, equal sharpness) the product is the constant mu1 mu2 exp(-2 l1): lam = 0
    and the axis is p1 (any axis is exact then)."""
    p1 = np.asarray(p1, np.float64)
    p2 = np.asarray(p2, np.float64)
    l1 = np.asarray(l1, np.float64)
    l2 = np.asarray(l2, np.float64)
    v = l1[..., None] * p1 + l2[..., None] * p2
    lam = np.linalg.norm(v, axis=-1)
    s = l1 + l2
    small = lam <= PRODUCT_AXIS_EPS * np.maximum(s, 1e-300)
    axis = np.where(small[..., None], p1 * np.ones_like(v), v / np.where(small, 1.0, lam)[..., None])
    lam = np.where(small, 0.0, lam)
    denom = lam + s
    expo = np.where(denom > 0, -2.0 * l1 * l2 * one_minus_dot(p1, p2) / np.where(denom > 0, denom, 1.0), 0.0)
    scale = np.exp(expo)
    mu1 = np.asarray(mu1, np.float64)
    mu2 = np.asarray(mu2, np.float64)
    mu = mu1 * mu2 * (scale[..., None] if (mu1 * mu2).ndim > scale.ndim else scale)
    return axis, lam, mu


def sg_integral(lam, mu=1.0) -> np.ndarray:
    """Integral of G over the sphere: 2 pi mu (1 - exp(-2 lam)) / lam (4 pi mu at lam = 0)."""
    lam = np.asarray(lam, np.float64)
    mu = np.asarray(mu, np.float64)
    f = np.where(lam > 1e-12, -np.expm1(-2 * lam) / np.where(lam > 1e-12, lam, 1.0), 2.0 - 2.0 * lam)
    f = 2 * np.pi * f
    return f[..., None] * mu if mu.ndim > f.ndim else f * mu


def sg_hemi_integral(lam) -> np.ndarray:
    """f_h(pi/2, lam): integral of G(.; p, lam, 1) over the hemisphere centred on p (001 Eq. 18):
    2 pi (1 - exp(-lam)) / lam (2 pi at lam = 0)."""
    lam = np.asarray(lam, np.float64)
    return 2 * np.pi * np.where(lam > 1e-12, -np.expm1(-lam) / np.where(lam > 1e-12, lam, 1.0), 1.0 - 0.5 * lam)


def sg_inner_product(p1, l1, mu1, p2, l2, mu2) -> np.ndarray:
    """Integral over the sphere of the product of two SGs."""
    _, lam, mu = sg_product(p1, l1, mu1, p2, l2, mu2)
    return sg_integral(lam, mu)


def sg_irradiance(axes, lams, mus, normals) -> np.ndarray:
    """(N, C) diffuse irradiance of an SG mixture: sum_k integral G_k * cosine-lobe SG
    (the clamped cosine approximated by (COS_LOBE_LAMBDA, COS_LOBE_MU))."""
    n = np.atleast_2d(np.asarray(normals, np.float64))[:, None, :]
    axes = np.asarray(axes, np.float64)[None]
    lams = np.asarray(lams, np.float64)[None]
    mus = np.asarray(mus, np.float64)[None]
    val = sg_inner_product(axes, lams, mus, n, COS_LOBE_LAMBDA, COS_LOBE_MU)
    return val.sum(1)


def fit_cosine_lobe(h: int = 256) -> tuple[float, float]:
    """Our own least-squares fit of max(0, i.n) by one SG over the sphere (solid-angle weighted
    quadrature on a 1-D theta grid); returns (lambda, mu). Compare with (2.133, 1.170)."""
    from scipy.optimize import minimize

    th = cell_centres(h * 8, 0.0, np.pi)
    w = np.sin(th) * (np.pi / (h * 8)) * 2 * np.pi
    c = np.cos(th)
    target = np.maximum(c, 0)

    def loss(x):
        lam, mu = x
        return float(np.sum(w * (mu * np.exp(lam * (c - 1)) - target) ** 2))

    r = minimize(loss, [2.0, 1.1], method="Nelder-Mead", options={"xatol": 1e-8, "fatol": 1e-14})
    return float(r.x[0]), float(r.x[1])


# -- visibility-weighted integral f_h ----------------------------------------------------------
def fh_exact(theta_d, lam, n_gl: int = FH_GL_NODES) -> np.ndarray:
    """f_h(theta_d, lam) (see module doc), vectorised, theta_d clamped to [-pi/2, pi/2].

    Substituting u = exp(-lam (1 - cos theta)) turns the SG weight into du:
    f_h = 2 pi / lam * integral_{exp(-2 lam)}^1 frac(theta(u)) du, frac = visible fraction of
    the circle at polar angle theta from p = acos(clip(-tan(theta_d) cot(theta), -1, 1)) / pi.
    frac is 1 or 0 outside theta in [|theta_d|, pi - |theta_d|] (analytic pieces); the middle
    piece uses Gauss-Legendre with a cosine substitution (frac has sqrt endpoints there)."""
    td = np.clip(np.asarray(theta_d, np.float64), -np.pi / 2, np.pi / 2)
    lam = np.asarray(lam, np.float64)
    td, lam = np.broadcast_arrays(td, lam)
    shape = td.shape
    td = td.reshape(-1)
    lam = np.maximum(lam.reshape(-1), 1e-300)
    a = np.abs(td)
    t1 = 2 * lam * np.sin(a / 2) ** 2  # lam (1 - cos|td|)
    t2 = lam * (1 + np.cos(a))
    pos = td >= 0
    # all integrals below are of du = -d(exp(-t)) over [t_lo, t_hi]:  exp(-t_lo) - exp(-t_hi)
    first = -np.expm1(-t1)  # theta in [0, |td|]
    last = np.exp(-t2) - np.exp(-2 * lam)  # theta in [pi - |td|, pi]
    x, wgl = np.polynomial.legendre.leggauss(n_gl)
    y = (x + 1) / 2
    s = (1 - np.cos(np.pi * y)) / 2  # cosine substitution, ds/dy = pi sin(pi y) / 2
    ds = np.pi * np.sin(np.pi * y) / 2 * wgl / 2
    # middle: t from t1 to t2, in u from exp(-t1) down to exp(-t2); parametrise u
    ua = np.exp(-t1)[:, None]
    ub = np.exp(-t2)[:, None]
    u = ua + (ub - ua) * s[None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -np.log(u)
        cos_t = np.clip(1 - t / lam[:, None], -1, 1)
        sin_t = np.sqrt(np.maximum(0.0, 1 - cos_t**2))
        num = -cos_t * np.sin(td)[:, None]
        den = sin_t * np.cos(td)[:, None]
        c0 = np.where(den != 0, num / np.where(den != 0, den, 1.0), np.sign(num) * np.inf)
        c0 = np.where(np.isnan(c0), 0.0, c0)
    frac = np.arccos(np.clip(c0, -1, 1)) / np.pi
    middle = (frac * ds[None, :]).sum(1) * (ua - ub)[:, 0]
    total = np.where(pos, first, 0.0) + middle + np.where(pos, 0.0, last)
    out = 2 * np.pi * total / lam
    return out.reshape(shape)


def fh_quad(theta_d: float, lam: float) -> float:
    """Slow scalar reference for f_h with scipy.quad over the polar angle (breakpoints)."""
    from scipy.integrate import quad

    td = float(np.clip(theta_d, -np.pi / 2, np.pi / 2))
    lam = float(lam)

    def f(th):
        den = np.sin(th) * np.cos(td)
        num = -np.cos(th) * np.sin(td)
        c0 = num / den if den != 0 else (np.sign(num) * np.inf if num != 0 else 0.0)
        return np.exp(-2 * lam * np.sin(th / 2) ** 2) * np.sin(th) * np.arccos(np.clip(c0, -1, 1)) / np.pi

    a = abs(td)
    width = min(np.pi, 30 / np.sqrt(max(lam, 1e-12)))
    pts = sorted({a, np.pi - a, min(width, np.pi), min(width / 10, np.pi)})
    edges = [0.0] + [p for p in pts if 0 < p < np.pi] + [np.pi]
    tot = 0.0
    for lo, hi in zip(edges[:-1], edges[1:]):
        tot += quad(f, lo, hi, epsabs=0, epsrel=1e-12, limit=400)[0]
    return 2 * np.pi * tot


def _fh_warp(theta_d, lam) -> np.ndarray:
    """Table coordinate for theta_d: w = clip(sin(theta_d) * max(1, sqrt(lam) / Y), -1, 1):
    the full range for broad lobes, the transition band |sin theta_d| sqrt(lam) < Y otherwise."""
    td = np.clip(np.asarray(theta_d, np.float64), -np.pi / 2, np.pi / 2)
    return np.clip(np.sin(td) * np.maximum(1.0, np.sqrt(np.asarray(lam, np.float64)) / FH_WARP_Y), -1, 1)


def _fh_unwarp(w, lam) -> np.ndarray:
    return np.arcsin(np.clip(w / np.maximum(1.0, np.sqrt(lam) / FH_WARP_Y), -1, 1))


@lru_cache(maxsize=1)
def fh_table() -> np.ndarray:
    """(NW, NL) float64 ratio f_h(theta_d, lam) / f_h(pi/2, lam) on the nodes of the table
    (w uniform in [-1, 1], log10 lam uniform in FH_LOG10_LAMBDA), from :func:`fh_exact`."""
    nw, nl = FH_TABLE_SHAPE
    w = np.linspace(-1, 1, nw)
    lam = 10 ** np.linspace(*FH_LOG10_LAMBDA, nl)
    W, L = np.meshgrid(w, lam, indexing="ij")
    return fh_exact(_fh_unwarp(W, L), L) / sg_hemi_integral(L)


def fh_fit(theta_d, lam) -> np.ndarray:
    """Our fitted f_h: sg_hemi_integral(lam) times the bilinear lookup of :func:`fh_table`
    (lam clamped to the table range for the lookup). GLSL twin: ``sg_fh`` in shading_sg.glsl."""
    lam = np.asarray(lam, np.float64)
    tab = fh_table()
    nw, nl = tab.shape
    lo, hi = FH_LOG10_LAMBDA
    ll = np.clip(np.log10(np.maximum(lam, 1e-300)), lo, hi)
    x = (_fh_warp(theta_d, lam) + 1) / 2 * (nw - 1)
    y = (ll - lo) / (hi - lo) * (nl - 1)
    r = sample_grid(tab, np.stack(np.broadcast_arrays(x, y), -1), "linear", "clamp")
    return r * sg_hemi_integral(lam)


def fh_printed_001(theta_d, lam) -> np.ndarray:
    """Seed 001 Eq. 14 as printed (for comparison only; docs/methods.md §3 warns about its signs)."""
    lam = np.asarray(lam, np.float64)
    k = 0.0079 * (lam / 10) ** 2 - 0.9088 * (lam / 10) + 0.79119
    with np.errstate(over="ignore"):
        return 1.0 / (1.0 + np.exp(k * np.asarray(theta_d, np.float64))) * sg_hemi_integral(lam)


def fh_printed_004(theta_d, lam) -> np.ndarray:
    """Seed 004 A.2 as printed (for comparison only)."""
    lam = np.asarray(lam, np.float64)
    k = 0.204 * lam**3 - 0.892 * lam**2 + 2.995 * lam + 0.067
    with np.errstate(over="ignore"):
        s = 1.05 / (1 + k * np.exp(np.asarray(theta_d, np.float64))) + (1 - 1.05) / 2
    return s * sg_hemi_integral(lam)


def sg_visible_integral(theta_d, lam, mu=1.0) -> np.ndarray:
    """Integral of G times visibility ~ mu f_h(theta_d, lam) (001 Eq. 12-14) with our fit."""
    f = fh_fit(theta_d, lam)
    mu = np.asarray(mu, np.float64)
    return f[..., None] * mu if mu.ndim > f.ndim else f * mu


# -- BRDF lobes as SGs (004 Eq. 5-8, 36-38) ----------------------------------------------------
def blinn_phong_ndf_sg(normal, n_exp):
    """Blinn-Phong D(h) = exp(-n (1 - h.n)) as an SG in the half-vector domain: (axis, lam, mu)."""
    return _unit(normal), np.asarray(n_exp, np.float64), np.ones_like(np.asarray(n_exp, np.float64))


def cook_torrance_ndf_sg(normal, m):
    """Cook-Torrance (Beckmann-like) D(h) ~ G(h; n, 2 / m^2, 1) (004)."""
    m = np.asarray(m, np.float64)
    return _unit(normal), 2.0 / m**2, np.ones_like(m)


def ward_ndf_sg(normal, alpha):
    """Isotropic Ward D(h) = exp(-tan^2(theta_h) / alpha^2) / (pi alpha^2 cos^3(theta_h)) as one
    SG in the half vector: tan^2 = (1 - c^2) / c^2 ~ 2 (1 - c) near c = 1, so lambda = 2 / alpha^2,
    mu = 1 / (pi alpha^2) (the peak). Good for small alpha (tested), crude beyond ~0.3."""
    a = np.asarray(alpha, np.float64)
    return _unit(normal), 2.0 / a**2, 1.0 / (np.pi * a**2)


def warp_ndf_sg(axis_d, lam_d, mu_d, out_dir):
    """Warp an NDF SG from the half-vector domain to the incident domain for view ``out_dir``
    (004 Eq. 36-38): p_W = 2 (o.p_D) p_D - o, lam_W = lam_D / (4 |p_D.o|), mu_W = mu_D."""
    p = _unit(axis_d)
    o = _unit(out_dir)
    c = np.sum(o * p, axis=-1)
    pw = 2 * c[..., None] * p - o
    lam_w = np.asarray(lam_d, np.float64) / (4 * np.maximum(np.abs(c), 1e-6))
    return _unit(pw), lam_w, mu_d


def fh_texture(ctx):
    """moderngl R32F texture of :func:`fh_table` for ``sg_fh`` in shading_sg.glsl (compile
    with ``#define SG_FH_TABLE``; set ``u_fh_params`` from :func:`fh_glsl_params`). Caller
    releases it."""
    import moderngl

    t = np.ascontiguousarray(fh_table().T.astype(np.float32))  # rows = lambda nodes
    tex = ctx.texture((t.shape[1], t.shape[0]), 1, t.tobytes(), dtype="f4")
    tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
    tex.repeat_x = False
    tex.repeat_y = False
    return tex


def fh_glsl_params() -> tuple[float, float, float, float]:
    """Value of ``uniform vec4 u_fh_params`` for sg_fh in shading_sg.glsl."""
    return (FH_LOG10_LAMBDA[0], FH_LOG10_LAMBDA[1], FH_WARP_Y, 0.0)

"""Relighting a capture (issue 15; docs/methods.md §3): the numpy reference of the GPU pass in
``render.relight.gl`` (GLSL twin ``render/relight/shaders/relight_common.glsl``).

What the capture saw at a point x is C_A = integral rho(w) L_A(w) V(x, w) dw (times the camera's
exposure and the surface's reflectance); under another environment B the same point shows
C_B ~ C_A * T_B(x) / T_A(x), the quotient of the two *transfers*

    T(x, v) = (E_K(n) + beta F(n, v)) * S(x),

* E_K(n) = integral K(n.w) L(w) dw, the unoccluded transfer of a zonal kernel K around the point's
  orientation n (the SDF gradient: the surface normal, or the strand direction of fur grown
  outward), exact: a table over n (the pixel quadrature of ``msem.convolve_zonal``, FFT over
  azimuth) looked up bilinearly like the irradiance table (``render.shading.irradiance``).
  Kernels (:data:`KERNELS`): "lambert" max(0, n.w); "fur" Kajiya-Kay's diffuse sin(n, w) of a
  strand along n.
* S(x), the share of that light the object leaves visible: the environment as K spherical
  Gaussians (``render.shading.sg_fit``), each times the clamped-cosine SG around n
  (``render.shading.sg``), integrated over the directions the sphere set leaves visible, the
  SSDF model's f_h(SSDF(x, axis), lambda) / f_h(pi/2, lambda) (``render.shading.ssdf``; the
  visible share of the ground shadow of seed 004 Eq. 16-17), weighted by the lobes' integrals.
  S = 1 with nothing in the way, so the convex case is exact.
* F(n, v), the light fibres scatter forwards (the TT lobe of hair, Marschner et al. 2003): the SG
  lobes as lights, each weighted by the kernel at its axis and a Henyey-Greenstein phase
  (mean 1 over the sphere, asymmetry FORWARD_G) of the angle between the light and the direction
  to the camera v; beta = FORWARD_SCATTER.  This is the view-dependent part: back-lit fur glows.

Energy stays sane where the quotient is ill-posed (a point the capture barely lit, a normal the
lighting grazes): both transfers get REGULARISE x their environment's reference transfer (the
transfer of a uniform environment of the same mean radiance) added, so a point that saw nearly
nothing takes the global gain (mean radiance of B over A), and the result is clamped to
[0, MAX_GAIN x the global gain] per channel.  Points without a defined orientation take the
global gain.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from capture.rotations import rotation_between
from capture.sampling import cell_centres
from render.shading.envmap import EnvMap, dir_to_uv, sample_equirect
from render.shading.msem import convolve_zonal
from render.shading.sg import COS_LOBE_LAMBDA, COS_LOBE_MU, fh_fit, sg_integral, sg_product
from render.shading.ssdf import SSDF_MAX, ssdf_spheres


def _lambert(c):
    return np.maximum(c, 0.0)


def _strand(c):
    return np.sqrt(np.maximum(1.0 - np.minimum(c * c, 1.0), 0.0))


#: Zonal transfer kernels K(n.w): "lambert" the clamped cosine; "wrap" max(0, n.w + 1/2) / (3/2),
#: wrapped diffuse (light reaches a fuzzy shell from beyond its horizon); "half-lambert"
#: ((n.w + 1) / 2)^2; "fur" sin(n, w), Kajiya-Kay's diffuse term of a strand along n (measured
#: uncorrelated with the truth on the combed fur ball: the strands do not follow the SDF gradient).
def _half_lambert(c):
    return (0.5 * (np.clip(c, -1.0, 1.0) + 1.0)) ** 2


def _wrap(c):
    return np.maximum(c + 0.5, 0.0) / 1.5


def _uniform(c):
    return np.ones_like(np.asarray(c, np.float64))


KERNELS = {"lambert": _lambert, "fur": _strand, "half-lambert": _half_lambert, "wrap": _wrap}
#: The basis of a mixed kernel ``mix:w0,w1,w2,w3`` = sum w_j K_j (``render.relight.calibrate`` fits the
#: weights to the capture): "uniform" is K = 1, light from everywhere alike (the single gain's transfer).
#: GLSL: RELIGHT_KERNEL = len(KERNELS) with the weights injected as RELIGHT_KERNEL_W.
MIX_BASIS = {"lambert": _lambert, "wrap": _wrap, "half-lambert": _half_lambert, "uniform": _uniform}
MIX_PREFIX = "mix:"


def mix_kernel(weights) -> str:
    """The kernel name of the mixture with these (len(MIX_BASIS),) weights >= 0 (not all 0)."""
    w = np.asarray(weights, np.float64).reshape(-1)
    if w.shape != (len(MIX_BASIS),) or np.any(w < 0) or not w.sum() > 0 or not np.all(np.isfinite(w)):
        raise ValueError(f"mix kernel: need {len(MIX_BASIS)} weights >= 0, not all 0, got {w.tolist()}")
    return MIX_PREFIX + ",".join(f"{x:.6g}" for x in w)


def mix_weights(kernel: str) -> np.ndarray:
    """(len(MIX_BASIS),) weights of a ``mix:`` kernel name (ValueError if malformed)."""
    try:
        w = np.array([float(x) for x in kernel[len(MIX_PREFIX):].split(",")])
    except ValueError:
        w = np.zeros(0)
    mix_kernel(w)  # validates
    return w


def kernel_fn(kernel: str):
    """K(c) of a kernel name: one of :data:`KERNELS` or ``mix:w0,..`` over :data:`MIX_BASIS`."""
    if kernel in KERNELS:
        return KERNELS[kernel]
    if isinstance(kernel, str) and kernel.startswith(MIX_PREFIX):
        w = mix_weights(kernel)
        return lambda c: sum(wj * f(c) for wj, f in zip(w, MIX_BASIS.values()) if wj)
    raise ValueError(f"unknown relighting kernel {kernel!r}; use one of {', '.join(KERNELS)}, auto "
                     f"(fitted to the capture) or {MIX_PREFIX}w0,w1,w2,w3 over {', '.join(MIX_BASIS)}")
#: The fixed kernel of the relighting before issue 23 (measured best of the four on the fur ball and
#: the plant, docs/relight.md); since then the fallback when a capture cannot be fitted
#: (render.relight.calibrate) and the default of relight_lighting.
DEFAULT_KERNEL = "wrap"
#: Rows of the transfer table (h, 2h) and of the map it is computed from (the irradiance table's
#: h = 64 is within 1.1 % of the brute-force integral: render.shading.irradiance).
TRANSFER_TABLE_H = 64
#: SG lobes fitted to each environment (visible share, forward scattering).
RELIGHT_SG_K = 16
#: Weight beta of the forward-scattered light against the diffuse transfer, and the asymmetry g of
#: its Henyey-Greenstein phase (module doc; beta 0 = view-independent).  Measured with
#: ``furrow bench relight`` (docs/relight.md): backward scattering (g < 0) loses on the fur ball
#: and the plant, beta 0.3-3 with g 0.3-0.8 gain, g 0.8 most on the plant.
FORWARD_SCATTER = 1.0
FORWARD_G = 0.8
#: Both transfers get this fraction of their environment's reference transfer added (module doc):
#: where the capture transfer is below about this fraction of its typical value the gain tends
#: to the global gain instead of dividing by nearly nothing.
REGULARISE = 0.05
#: Largest gain, as a multiple of the global gain (per channel).
MAX_GAIN = 4.0
#: A point's orientation counts as undefined when the SDF gradient is shorter than this (per metre).
MIN_GRADIENT = 1e-6


@dataclass(frozen=True)
class RelightLighting:
    """One environment prepared for relighting, in WORLD coordinates where noted.

    table: (h, 2h, 3) float32 unoccluded transfer E_K over orientations, equirect in the MAP's
        frame (lookup direction = to_env @ n).
    to_env: (3, 3) rotation taking world directions into the map's frame (the world's up to +z).
    axes: (K, 3) world unit SG axes; lams: (K,) sharpness; mus: (K, 3) linear RGB radiance.
    mean: (3,) mean radiance of the map over the sphere (solid-angle weighted).
    kernel: the kernel name of ``table``; reference: (3,) the transfer of a uniform environment of
        ``mean`` radiance (mean x the kernel's integral over the sphere).
    """

    table: np.ndarray
    to_env: np.ndarray
    axes: np.ndarray
    lams: np.ndarray
    mus: np.ndarray
    mean: np.ndarray
    kernel: str
    reference: np.ndarray

    def __post_init__(self) -> None:
        t = np.asarray(self.table)
        if t.ndim != 3 or t.shape[1] != 2 * t.shape[0] or t.shape[2] != 3:
            raise ValueError(f"RelightLighting: table must be (h, 2h, 3), got {t.shape}")
        k = len(np.asarray(self.lams).reshape(-1))
        if np.asarray(self.axes).shape != (k, 3) or np.asarray(self.mus).shape != (k, 3):
            raise ValueError(f"RelightLighting: axes and mus must be ({k}, 3)")
        kernel_fn(self.kernel)


def world_to_env(up) -> np.ndarray:
    """(3, 3) rotation taking world directions into the map's frame: the world's ``up`` to +z."""
    return rotation_between(np.asarray(up, np.float64), (0.0, 0.0, 1.0))


def kernel_integral(kernel: str) -> float:
    """Integral of the kernel over the sphere (pi for lambert, pi^2 for fur): 2 pi int K(c) dc."""
    c = cell_centres(20000, -1.0, 1.0)
    return float(2 * np.pi * kernel_fn(kernel)(c).mean() * 2)


def transfer_table(env: EnvMap, kernel: str, h: int = TRANSFER_TABLE_H) -> np.ndarray:
    """(h, 2h, 3) float32 E_K(n) = sum_w K(n.w) L(w) Omega(w) at the pixel-centre directions of an
    (h, 2h) map, on ``env`` area-resampled to h rows."""
    fn = kernel_fn(kernel)
    src = env.resized(int(h))
    return np.maximum(convolve_zonal(src, fn, np.pi, normalise=False), 0).astype(np.float32)


def relight_lighting(env: EnvMap, up=(0.0, 0.0, 1.0), kernel: str = DEFAULT_KERNEL, k: int = RELIGHT_SG_K,
                     fit=None) -> RelightLighting:
    """``env`` prepared for relighting in the world whose up is ``up``: its transfer table, its SG
    fit (``render.shading.sg_fit.fit_env_sg``, or ``fit``) turned into the world, its mean radiance."""
    from render.shading.sg_fit import fit_env_sg

    fit = fit_env_sg(env, k) if fit is None else fit
    R = world_to_env(up)
    omega = env.pixel_solid_angles()
    mean = np.einsum("hwc,hw->c", env.data.astype(np.float64), omega) / omega.sum()
    return RelightLighting(transfer_table(env, kernel), R, np.asarray(fit.axes, np.float64) @ R,
                           np.asarray(fit.lams, np.float64), np.asarray(fit.mus, np.float64), mean, kernel,
                           mean * kernel_integral(kernel))


def unoccluded_transfer(lighting: RelightLighting, normals) -> np.ndarray:
    """(P, 3) E_K at world unit ``normals`` (P, 3): bilinear lookup of the table (wrap in u,
    clamp in v) at the normals turned into the map's frame."""
    n = np.asarray(normals, np.float64).reshape(-1, 3) @ np.asarray(lighting.to_env).T
    return sample_equirect(np.asarray(lighting.table, np.float64), dir_to_uv(n))


def visible_share(points, normals, lighting: RelightLighting, spheres=None) -> np.ndarray:
    """(P, 3) S(x) (module doc) at world ``points`` with unit ``normals``; 1 without spheres."""
    x = np.asarray(points, np.float64).reshape(-1, 3)
    n = np.asarray(normals, np.float64).reshape(-1, 3)
    if spheres is None or not len(spheres):
        return np.ones((len(x), 3))
    ax, lam, mu = sg_product(np.asarray(lighting.axes)[None], np.asarray(lighting.lams)[None],
                             np.asarray(lighting.mus)[None], n[:, None, :], COS_LOBE_LAMBDA, COS_LOBE_MU)
    w = mu * sg_integral(lam)[..., None]  # (P, K, 3) each lobe's unoccluded integral
    theta = ssdf_spheres(x, n, ax, spheres.centers, spheres.radii)
    share = fh_fit(theta, lam) / fh_fit(np.full(lam.shape, SSDF_MAX), lam)
    tot = w.sum(1)
    return np.where(tot > 0, np.einsum("pk,pkc->pc", share, w) / np.where(tot > 0, tot, 1.0), 1.0)


def henyey_greenstein(c, g: float = FORWARD_G, dtype=np.float64) -> np.ndarray:
    """Henyey-Greenstein phase times 4 pi (mean 1 over the sphere) at cosine ``c`` of the scattering
    angle (1 = straight on), computed in ``dtype`` (float32: the relighting fit's quadrature)."""
    c = np.asarray(c, dtype)
    x = dtype(1 + g * g) - dtype(2 * g) * c
    return dtype(1 - g * g) / x ** dtype(1.5) if dtype is np.float64 else dtype(1 - g * g) / (x * np.sqrt(x))


def forward_transfer(lighting: RelightLighting, normals, views, g: float = FORWARD_G) -> np.ndarray:
    """(P, 3) F(n, v) (module doc) at world unit ``normals`` and unit directions to the camera
    ``views`` (P, 3): sum_k integral(G_k) K(n.p_k) HG(-v.p_k)."""
    n = np.asarray(normals, np.float64).reshape(-1, 3)
    v = np.asarray(views, np.float64).reshape(-1, 3)
    ax = np.asarray(lighting.axes, np.float64)
    power = np.asarray(lighting.mus, np.float64) * sg_integral(np.asarray(lighting.lams, np.float64))[:, None]
    w = kernel_fn(lighting.kernel)(n @ ax.T) * henyey_greenstein(-(v @ ax.T), g)
    return w @ power


def transfer(points, normals, lighting: RelightLighting, spheres=None, views=None,
             forward: float = FORWARD_SCATTER) -> np.ndarray:
    """(P, 3) T(x, v) (module doc); without ``views`` (or with ``forward`` 0) the view-independent
    E_K(n) S(x)."""
    t = unoccluded_transfer(lighting, normals)
    if views is not None and forward:
        t = t + forward * forward_transfer(lighting, normals, views)
    return t * visible_share(points, normals, lighting, spheres)


def global_gain(a: RelightLighting, b: RelightLighting) -> np.ndarray:
    """(3,) mean radiance of B over A per channel (the single-gain baseline); 1 where A is black."""
    ma, mb = np.asarray(a.mean, np.float64), np.asarray(b.mean, np.float64)
    return np.where(ma > 0, mb / np.where(ma > 0, ma, 1.0), 1.0)


def relight_gain(points, normals, a: RelightLighting, b: RelightLighting, spheres=None, views=None,
                 forward: float = FORWARD_SCATTER, regularise: float = REGULARISE, max_gain: float = MAX_GAIN,
                 shares=None, forward_g: float = FORWARD_G) -> np.ndarray:
    """(P, 3) colour gain from capture lighting ``a`` to ``b`` at world ``points`` with SDF
    gradients ``normals`` (any length) seen from unit directions ``views`` (None: no forward
    scattering): the regularised transfer quotient clamped to [0, max_gain x global gain]; the
    global gain where the gradient is (near) zero.  ``shares``: the visible shares (S_A, S_B) to
    use instead of computing them from ``spheres``."""
    if a.kernel != b.kernel:
        raise ValueError(f"relight_gain: both lightings need the same kernel, got {a.kernel} and {b.kernel}")
    n = np.asarray(normals, np.float64).reshape(-1, 3)
    nl = np.linalg.norm(n, axis=1)
    ok = nl > MIN_GRADIENT
    un = np.where(ok[:, None], n / np.where(ok, nl, 1.0)[:, None], np.array([0.0, 0.0, 1.0]))
    if shares is None:
        shares = (visible_share(points, un, a, spheres), visible_share(points, un, b, spheres))
    f = forward if views is not None else 0.0
    ta, tb = (unoccluded_transfer(lt, un) for lt in (a, b))
    if f:
        ta = ta + f * forward_transfer(a, un, views, forward_g)
        tb = tb + f * forward_transfer(b, un, views, forward_g)
    return gain_from_transfers(ta * shares[0], tb * shares[1], (1 + f) * a.reference, (1 + f) * b.reference,
                               global_gain(a, b), ok, regularise, max_gain)


def gain_from_transfers(ta, tb, ref_a, ref_b, g, ok, regularise: float = REGULARISE,
                        max_gain: float = MAX_GAIN) -> np.ndarray:
    """(P, 3): (tb + r ref_b) / (ta + r ref_a) clamped to [0, max_gain g]; g where not ``ok``."""
    den = np.asarray(ta) + regularise * np.asarray(ref_a)
    num = np.asarray(tb) + regularise * np.asarray(ref_b)
    q = np.where(den > 0, num / np.where(den > 0, den, 1.0), g)
    q = np.clip(q, 0.0, max_gain * np.asarray(g))
    return np.where(np.asarray(ok)[:, None], q, g)

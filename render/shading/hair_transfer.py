"""Strand transfer of the relighting (issue 23; numpy reference, GLSL twin
``render/relight/shaders/relight_hair.glsl``): what a fibre with unit tangent T in a fur shell with
smoothed normal n, seen from the unit direction v (to the camera), returns of an environment, as two
parts the fibre's colour weighs differently, with the map's SG lobes (axis p_k, power P_k = mu_k x their
integral) as lights and x_k = p_k . T + v . T (0 on the specular cone sin theta_i = -sin theta_o):

    D(T, n, v) = sum_k P_k W(n . p_k) (exp(-x_k^2 / 2 beta_D^2) + floor) (1 + beta_TT HG(-v . p_k))  coloured
    R(T, n, v) = sum_k P_k W(n . p_k) exp(-x_k^2 / (2 beta_R^2))                                     white

* the lobes of Marschner et al. 2003 / Chiang et al. 2016 (``render.shading.hair``) all lie near the
  specular cone: R narrow (beta_R ~ the longitudinal width of beta_m = 0.3) and white; TT and TRT wider
  and coloured (beta_D), with a floor for the light scattered many times in dense fur; HG a
  Henyey-Greenstein phase (mean 1) for the forward-transmitted TT; azimuthally flat otherwise;
* W the wrap kernel max(0, c + 1/2) / (3/2) of the shell's normal: the light the fur ball itself hides
  (measured: Kajiya-Kay's sin(T, p) on the tangent alone lit the far side of the fur ball, docs/relight.md).

A captured strand's colour under lighting A is C = rho D_A + sigma R_A (rho: RGB, the fibre's colour
including the camera's exposure; sigma: its white specular weight): :func:`fit_strand_colour` inverts
that over all capture views that saw a voxel (least squares, sigma >= 0), and the new colour is
C' = C (rho D_B + sigma R_B) / (rho D_A + sigma R_A) -- the same model forwards (:func:`hair_gain`).
"""

from __future__ import annotations

import numpy as np

from render.shading.sg import sg_integral
from render.shading.transfer import FORWARD_G, MAX_GAIN, REGULARISE, RelightLighting, henyey_greenstein

#: Weight of the forward-transmitted (TT) light against the diffuse strand transfer.
HAIR_FORWARD = 1.0
#: Width of the R lobe around the specular cone (in sine units; ~ the longitudinal width of
#: Chiang et al.'s beta_m = 0.3).
HAIR_BETA_R = 0.3
#: Width of the coloured lobes (TT, TRT) around the specular cone, wider than R (sine units), and the
#: isotropic floor of multiply scattered light under them.
HAIR_BETA_D = 0.45
HAIR_FLOOR = 0.25
#: Ridge weight of the specular weight sigma in the colour fit, relative to the mean R^2 x samples
#: (keeps sigma near 0 where the views cannot tell R from D).
SIGMA_RIDGE = 0.05
#: Voxels with fewer samples than this keep no strand colour (the fit is not trusted).
MIN_FIT_SAMPLES = 6.0


def _lobes(lt: RelightLighting):
    ax = np.asarray(lt.axes, np.float64)
    power = np.asarray(lt.mus, np.float64) * sg_integral(np.asarray(lt.lams, np.float64))[:, None]
    return ax, power


def _wrap(c):
    return np.maximum(c + 0.5, 0.0) / 1.5


def hair_reference(lt: RelightLighting) -> np.ndarray:
    """(3,) the strand transfer D of a uniform environment of the map's mean radiance (the scale of the
    regularisation): mean x (integral of the wrap kernel) x (mean of sin over the sphere, pi / 4)."""
    from render.shading.transfer import kernel_integral

    return np.asarray(lt.mean, np.float64) * kernel_integral("wrap") * (np.pi / 4)


def _terms(lt: RelightLighting, tangents, normals, views, forward: float, g: float, beta: float):
    t = np.asarray(tangents, np.float64).reshape(-1, 3)
    n = np.asarray(normals, np.float64).reshape(-1, 3)
    v = np.asarray(views, np.float64).reshape(-1, 3)
    ax, power = _lobes(lt)
    c = t @ ax.T
    vis = _wrap(n @ ax.T)
    x = c + np.sum(t * v, 1, keepdims=True)
    diff = (np.exp(-0.5 * (x / HAIR_BETA_D) ** 2) + HAIR_FLOOR) * (1 + forward * henyey_greenstein(-(v @ ax.T), g))
    spec = np.exp(-0.5 * (x / beta) ** 2)
    return (vis * diff) @ power, (vis * spec) @ power


def hair_diffuse(lt: RelightLighting, tangents, normals, views, forward: float = HAIR_FORWARD,
                 g: float = FORWARD_G) -> np.ndarray:
    """(P, 3) D(T, n, v) (module doc) at unit tangents, shell normals (or 0) and views (P, 3)."""
    return _terms(lt, tangents, normals, views, forward, g, HAIR_BETA_R)[0]


def hair_specular(lt: RelightLighting, tangents, normals, views, beta: float = HAIR_BETA_R) -> np.ndarray:
    """(P, 3) R(T, n, v) (module doc): the SG lobes through the R lobe's longitudinal Gaussian."""
    return _terms(lt, tangents, normals, views, HAIR_FORWARD, FORWARD_G, beta)[1]


def fit_strand_colour(flat, colour, d, r, n_voxels: int, ridge: float = SIGMA_RIDGE):
    """((V, 3) rho, (V,) sigma, (V,) samples) per voxel: least squares of colour = rho D + sigma R over
    the samples (``flat``: (S,) voxel index; ``colour``, ``d``, ``r``: (S, 3)), sigma >= 0 and rho >= 0,
    sigma ridged towards 0 by ``ridge`` x mean(R^2) x samples; voxels without samples get zeros."""
    n = int(n_voxels)
    bc = lambda w: np.bincount(flat, w, n)
    cnt = bc(None)
    dd = np.stack([bc(d[:, c] ** 2) for c in range(3)], -1)
    dr = np.stack([bc(d[:, c] * r[:, c]) for c in range(3)], -1)
    rr = sum(bc(r[:, c] ** 2) for c in range(3))
    cd = np.stack([bc(colour[:, c] * d[:, c]) for c in range(3)], -1)
    cr = sum(bc(colour[:, c] * r[:, c]) for c in range(3))
    rr_mean = float(np.sum(r ** 2) / max(len(r), 1))
    rr = rr + ridge * rr_mean * cnt
    # eliminate rho_c = (cd_c - sigma dr_c) / dd_c, then a 1-D problem in sigma
    ok = np.all(dd > 0, 1) & (cnt >= 1)
    safe = np.where(dd > 0, dd, 1.0)
    num = cr - np.sum(dr * cd / safe, 1)
    den = rr - np.sum(dr * dr / safe, 1)
    sigma = np.where(ok & (den > 0), np.maximum(num / np.where(den > 0, den, 1.0), 0.0), 0.0)
    rho = np.where(ok[:, None], np.maximum((cd - sigma[:, None] * dr) / safe, 0.0), 0.0)
    return rho, sigma, cnt


def hair_gain(tangents, normals, views, rho, sigma, a: RelightLighting, b: RelightLighting, g_global,
              regularise: float = REGULARISE, max_gain: float = MAX_GAIN, forward_g: float = FORWARD_G) -> np.ndarray:
    """(P, 3) gain from A to B of strands (module doc): (rho D_B + sigma R_B + r rho ref_B) /
    (rho D_A + sigma R_A + r rho ref_A), clamped to [0, max_gain g_global]; g_global where that is 0/0."""
    rho = np.asarray(rho, np.float64).reshape(-1, 3)
    sg = np.asarray(sigma, np.float64).reshape(-1, 1)
    da, ra = _terms(a, tangents, normals, views, HAIR_FORWARD, forward_g, HAIR_BETA_R)
    db, rb = _terms(b, tangents, normals, views, HAIR_FORWARD, forward_g, HAIR_BETA_R)
    den = rho * da + sg * ra + regularise * rho * hair_reference(a)
    num = rho * db + sg * rb + regularise * rho * hair_reference(b)
    g = np.broadcast_to(np.asarray(g_global, np.float64), num.shape)
    q = np.where(den > 0, num / np.where(den > 0, den, 1.0), g)
    return np.clip(q, 0.0, max_gain * g)

"""Strand transfer of the relighting (issue 23; numpy reference, GLSL twin
``render/relight/shaders/relight_hair.glsl``): what a fibre with unit tangent T, seen from the unit
direction v (to the camera), returns of an environment, as two parts the fibre's colour weighs
differently:

    D(T, v) = E_fur(T) + beta_TT sum_k P_k sin(T, p_k) HG(-v . p_k)       coloured (diffuse + TT)
    R(T, v) = sum_k P_k exp(-(p_k . T + v . T)^2 / (2 beta_R^2))          white (the R lobe)

* E_fur(T) = integral sin(T, w) L(w) dw: Kajiya-Kay's diffuse term of a strand, exact (the "fur" table
  of ``render.shading.transfer``, looked up at T: a strand's transfer is even in T);
* the sums run over the map's SG lobes (axis p_k, power P_k = mu_k x their integral) as lights, as the
  surface transfer's forward term: HG a Henyey-Greenstein phase (mean 1) for the light fibres transmit
  forwards (Marschner's TT), and the R lobe's longitudinal Gaussian around the specular cone
  sin theta_i = -sin theta_o (Marschner et al. 2003; the width of Chiang et al.'s beta_m = 0.3 in
  ``render.shading.hair``; azimuthally flat, its tilt alpha neglected).

A captured strand's colour under lighting A is C = rho D_A + sigma R_A (rho: RGB, the fibre's colour
including the camera's exposure; sigma: its white specular weight): :func:`fit_strand_colour` inverts
that over all capture views that saw a voxel (least squares, sigma >= 0), and the new colour is
C' = C (rho D_B + sigma R_B) / (rho D_A + sigma R_A) -- the same model forwards (:func:`hair_gain`).
"""

from __future__ import annotations

import numpy as np

from render.shading.envmap import dir_to_uv, sample_equirect
from render.shading.sg import sg_integral
from render.shading.transfer import FORWARD_G, MAX_GAIN, REGULARISE, RelightLighting, henyey_greenstein

#: Weight of the forward-transmitted (TT) light against the diffuse strand transfer.
HAIR_FORWARD = 1.0
#: Width of the R lobe around the specular cone (in sine units; ~ the longitudinal width of
#: Chiang et al.'s beta_m = 0.3).
HAIR_BETA_R = 0.3
#: Ridge weight of the specular weight sigma in the colour fit, relative to the mean R^2 x samples
#: (keeps sigma near 0 where the views cannot tell R from D).
SIGMA_RIDGE = 0.05
#: Voxels with fewer samples than this keep no strand colour (the fit is not trusted).
MIN_FIT_SAMPLES = 6.0


def _lobes(lt: RelightLighting):
    ax = np.asarray(lt.axes, np.float64)
    power = np.asarray(lt.mus, np.float64) * sg_integral(np.asarray(lt.lams, np.float64))[:, None]
    return ax, power


def fur_lighting(env, lt: RelightLighting) -> RelightLighting:
    """``lt`` (any kernel, prepared from ``env``) with the "fur" transfer table instead: same SG lobes,
    same frame, its reference transfer the fur kernel's."""
    from render.shading.transfer import kernel_integral, transfer_table

    return RelightLighting(transfer_table(env, "fur"), lt.to_env, lt.axes, lt.lams, lt.mus, lt.mean, "fur",
                           np.asarray(lt.mean) * kernel_integral("fur"))


def hair_diffuse(fur: RelightLighting, tangents, views, forward: float = HAIR_FORWARD,
                 g: float = FORWARD_G) -> np.ndarray:
    """(P, 3) D(T, v) (module doc) of the lighting ``fur`` (kernel "fur") at unit tangents and views (P, 3)."""
    if fur.kernel != "fur":
        raise ValueError(f"hair_diffuse needs a lighting with the 'fur' kernel, got {fur.kernel!r}")
    t = np.asarray(tangents, np.float64).reshape(-1, 3)
    v = np.asarray(views, np.float64).reshape(-1, 3)
    d = sample_equirect(np.asarray(fur.table, np.float64), dir_to_uv(t @ np.asarray(fur.to_env).T))
    if forward:
        ax, power = _lobes(fur)
        c = t @ ax.T
        w = np.sqrt(np.maximum(1 - np.minimum(c * c, 1), 0)) * henyey_greenstein(-(v @ ax.T), g)
        d = d + forward * (w @ power)
    return d


def hair_specular(fur: RelightLighting, tangents, views, beta: float = HAIR_BETA_R) -> np.ndarray:
    """(P, 3) R(T, v) (module doc): the SG lobes through the R lobe's longitudinal Gaussian."""
    t = np.asarray(tangents, np.float64).reshape(-1, 3)
    v = np.asarray(views, np.float64).reshape(-1, 3)
    ax, power = _lobes(fur)
    x = t @ ax.T + np.sum(t * v, 1, keepdims=True)
    return np.exp(-0.5 * (x / beta) ** 2) @ power


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


def hair_gain(tangents, views, rho, sigma, fur_a: RelightLighting, fur_b: RelightLighting, g_global,
              regularise: float = REGULARISE, max_gain: float = MAX_GAIN, forward_g: float = FORWARD_G) -> np.ndarray:
    """(P, 3) gain from A to B of strands (module doc): (rho D_B + sigma R_B + r rho ref_B) /
    (rho D_A + sigma R_A + r rho ref_A), clamped to [0, max_gain g_global]; g_global where that is 0/0."""
    rho = np.asarray(rho, np.float64).reshape(-1, 3)
    sg = np.asarray(sigma, np.float64).reshape(-1, 1)
    ta = rho * hair_diffuse(fur_a, tangents, views, g=forward_g) + sg * hair_specular(fur_a, tangents, views)
    tb = rho * hair_diffuse(fur_b, tangents, views, g=forward_g) + sg * hair_specular(fur_b, tangents, views)
    den = ta + regularise * (1 + HAIR_FORWARD) * rho * np.asarray(fur_a.reference)
    num = tb + regularise * (1 + HAIR_FORWARD) * rho * np.asarray(fur_b.reference)
    g = np.broadcast_to(np.asarray(g_global, np.float64), num.shape)
    q = np.where(den > 0, num / np.where(den > 0, den, 1.0), g)
    return np.clip(q, 0.0, max_gain * g)

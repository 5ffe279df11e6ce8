"""Dominant light sources of an environment map (for shadow maps of the synthetic renderer and
for the light-source map of glare, docs/methods.md §4 §3.2), and the environment with them removed.

A light is a compact region of pixels much brighter than its surroundings. It is removed from
the map by replacing its pixels with the surrounding background level ("fill"), so
``env = env_minus_lights(env) + excess`` pixel by pixel, excess = max(L - fill, 0) >= 0 on the
regions. Each light is returned as a directional source: direction d = the normalised
luminance-weighted vector P = sum lum(excess) Omega w, and per-channel power
``power_c = d . sum excess_c Omega w`` (the irradiance on a surface facing d). For every normal n
whose hemisphere contains a whole region, the region's luminance irradiance is then EXACTLY
``lum(power) * max(0, n.d)`; per channel it differs only by the chromatic part of the excess
that is not along d (measured up to 0.9% on the bundled sunset map).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from render.shading.envmap import EnvMap

#: Rec. 709 luminance weights (linear RGB).
LUMA = np.array([0.2126, 0.7152, 0.0722])
#: A light region = pixels within this angle of the peak (radians) ...
LIGHT_MAX_RADIUS = np.radians(12.0)
#: ... whose luminance is at least this fraction of the peak's ...
LIGHT_REL_THRESHOLD = 0.05
#: ... and at least this many times the map's median luminance (so diffuse sky is never a light).
LIGHT_MIN_CONTRAST = 4.0
#: Re-centring iterations of the light cap on the region's centroid.
RECENTRE_ITERS = 3
#: Ring (radians beyond the region's own angular extent) whose median radiance is the fill level.
FILL_RING = np.radians(4.0)


class DominantLights(NamedTuple):
    """k lights (k may be smaller than asked when the map has fewer bright regions).

    dirs: (k, 3) float64 unit directions (world, +z up), luminance-weighted region centroid.
    power: (k, 3) float64 RGB directional power (irradiance on a surface facing the light,
        W m^-2 up to the map's scale): d . sum (L - fill) * Omega * w over the region.
    solid_angle: (k,) float64 solid angle of each region (sr).
    """

    dirs: np.ndarray
    power: np.ndarray
    solid_angle: np.ndarray


def _extract(env: EnvMap, k: int):
    """The k lights and the (H, W, 3) float64 residual radiance; shared by both public calls."""
    if k < 0:
        raise ValueError(f"dominant_lights: k must be >= 0, got {k}")
    data = env.data.astype(np.float64)
    res = data.copy()
    dirs = env.pixel_directions().reshape(-1, 3)
    omega = env.pixel_solid_angles().reshape(-1)
    flat = res.reshape(-1, 3)
    lum = data.reshape(-1, 3) @ LUMA
    median = float(np.median(lum))
    taken = np.zeros(lum.shape, bool)
    out_d, out_p, out_s = [], [], []
    for _ in range(k):
        cand = np.where(taken, -np.inf, lum)
        i = int(np.argmax(cand))
        peak = cand[i]
        thr = max(LIGHT_REL_THRESHOLD * peak, LIGHT_MIN_CONTRAST * median)
        if not np.isfinite(peak) or peak <= thr or peak <= 0:
            break
        # the argmax of a flat-topped source is an edge pixel: re-centre the cap on the
        # region's luminance centroid a few times so the whole source falls inside it
        centre = dirs[i]
        bright = (lum >= thr) & ~taken
        for _ in range(RECENTRE_ITERS):
            cosang = dirs @ centre
            region = (cosang >= np.cos(LIGHT_MAX_RADIUS)) & bright
            c = ((lum[region] * omega[region])[:, None] * dirs[region]).sum(0)
            centre = c / np.linalg.norm(c)
        cosang = dirs @ centre
        region = (cosang >= np.cos(LIGHT_MAX_RADIUS)) & bright
        if not region.any():
            taken[i] = True
            continue
        # angular extent of the region, then the ring around it gives the fill level
        ext = float(np.arccos(np.clip(cosang[region].min(), -1, 1)))
        ring = ((cosang < np.cos(ext)) & (cosang >= np.cos(ext + FILL_RING)) & ~taken & (lum < thr))
        fill = np.median(data.reshape(-1, 3)[ring], axis=0) if ring.any() else np.zeros(3)
        excess = np.maximum(flat[region] - fill, 0)
        flat[region] = np.minimum(flat[region], fill)
        w = excess * omega[region, None]
        p_vec = (w @ LUMA)[:, None] * dirs[region]
        dvec = p_vec.sum(0)
        nd = np.linalg.norm(dvec)
        taken |= cosang >= np.cos(ext + FILL_RING)
        if nd == 0:
            continue
        d_hat = dvec / nd
        out_d.append(d_hat)
        # directional power per channel: irradiance the region gives a surface facing d_hat,
        # d . sum (L_c - fill_c) Omega w  (slightly below the total excess sum (L - fill) Omega)
        out_p.append(w.T @ (dirs[region] @ d_hat))
        out_s.append(float(omega[region].sum()))
    lights = DominantLights(np.array(out_d, np.float64).reshape(-1, 3),
                            np.array(out_p, np.float64).reshape(-1, 3),
                            np.array(out_s, np.float64))
    return lights, res


def dominant_lights(env: EnvMap, k: int = 4) -> DominantLights:
    """Up to k brightest separated light regions of ``env`` (brightest first). Unpacks as
    ``dirs, power, solid_angle = dominant_lights(env, k)``."""
    return _extract(env, int(k))[0]


def env_minus_lights(env: EnvMap, k: int = 4) -> EnvMap:
    """``env`` with the regions of ``dominant_lights(env, k)`` replaced by their surrounding
    fill level (the complement of the lights: the two add back to ``env``'s total power)."""
    res = _extract(env, int(k))[1]
    return EnvMap(res.astype(np.float32), f"{env.name}-minus-lights")


def lights_irradiance(lights: DominantLights, normals) -> np.ndarray:
    """(N, 3) irradiance of the lights treated as directional sources: power * max(0, n.d)."""
    n = np.atleast_2d(np.asarray(normals, np.float64))
    if len(lights.dirs) == 0:
        return np.zeros((n.shape[0], 3))
    return np.maximum(n @ lights.dirs.T, 0) @ lights.power

"""An environment map as a few directional lights of about equal energy: Debevec 2005, "A Median Cut
Algorithm for Light Probe Sampling" (SIGGRAPH 2005 poster / sketch).

The equirectangular map is split recursively: every region is cut across its longer side (the
azimuthal extent measured at the region's central latitude, so regions stay roughly square on
the sphere) where its luminance energy sum(lum(L) Omega) is halved.  After ``depth`` rounds there
are 2^depth regions (a region concentrated in one pixel cannot be halved, so energies are equal
only roughly); each becomes a light at its energy-weighted mean direction d with per-channel
power sum(L_c Omega) over the region: the integral of radiance over the region, which is what a
BSDF without a cosine (a hair fibre, ``render.shading.hair``: L_o = integral S L d omega) sees from
a compact source, and what keeps every channel's total (``EnvMap.total_power``) exact.  As an
irradiance source (power max(0, n . d)) it is exact on average over all normals and overestimates
normals facing a wide region slightly (measured in tests/render/shading/test_median_cut.py).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from render.shading.envmap import EnvMap
from render.shading.lights import LUMA


class CutLights(NamedTuple):
    """dirs (n, 3) unit world directions; power (n, 3) radiance integrated over each light's
    region (sum L Omega); solid_angle (n,) of each region (sr)."""

    dirs: np.ndarray
    power: np.ndarray
    solid_angle: np.ndarray


def _regions(energy: np.ndarray, depth: int) -> list[tuple[int, int, int, int]]:
    """Row/column boxes (r0, r1, c0, c1) of the median cut of ``energy`` (H, W)."""
    H, W = energy.shape
    row_sin = np.sin(np.pi * (np.arange(H) + 0.5) / H)
    boxes = [(0, H, 0, W)]
    for _ in range(depth):
        nxt = []
        for r0, r1, c0, c1 in boxes:
            e = energy[r0:r1, c0:c1]
            wide = (c1 - c0) * row_sin[(r0 + r1) // 2] * (H / W) * 2 > (r1 - r0)  # columns span 2 pi, rows pi
            if (wide and c1 - c0 < 2) or (not wide and r1 - r0 < 2):
                wide = not wide
            if (c1 - c0 < 2) and (r1 - r0 < 2):
                nxt.append((r0, r1, c0, c1))
                continue
            prof = e.sum(0) if wide else e.sum(1)
            cum = np.cumsum(prof)
            k = int(np.searchsorted(cum, 0.5 * cum[-1])) + 1 if cum[-1] > 0 else len(prof) // 2
            k = min(max(k, 1), len(prof) - 1)
            if wide:
                nxt += [(r0, r1, c0, c0 + k), (r0, r1, c0 + k, c1)]
            else:
                nxt += [(r0, r0 + k, c0, c1), (r0 + k, r1, c0, c1)]
        boxes = nxt
    return boxes


def median_cut_lights(env: EnvMap, depth: int = 4) -> CutLights:
    """2^depth directional lights of roughly equal energy standing for ``env`` (module docstring)."""
    if not 0 <= depth <= 12:
        raise ValueError(f"median_cut_lights: depth must be in [0, 12], got {depth}")
    L = env.data.astype(np.float64)
    om = env.pixel_solid_angles()
    dirs = env.pixel_directions()
    energy = (L @ LUMA) * om
    out_d, out_p, out_s = [], [], []
    for r0, r1, c0, c1 in _regions(energy, depth):
        e = energy[r0:r1, c0:c1]
        w = dirs[r0:r1, c0:c1]
        o = om[r0:r1, c0:c1]
        v = np.einsum("hw,hwk->k", e, w) if e.sum() > 0 else np.einsum("hw,hwk->k", o, w)
        d = v / max(np.linalg.norm(v), 1e-300)
        out_d.append(d)
        out_p.append(np.einsum("hwc,hw->c", L[r0:r1, c0:c1], o))
        out_s.append(o.sum())
    return CutLights(np.array(out_d), np.array(out_p), np.array(out_s))

"""Glare maps (METHODS §4 §3.2-3.3; seed 002) and the numpy twin of the streak rasteriser.

The streak geometry itself (Eq. 6-12, eyelash table, triangle fans, energy) lives in
``render.shading.glare`` (written by the shading helper) and is called from here, not copied.
This module adds what compositing needs:

* *light-source map* (:func:`light_source_map`): the environment with only its very bright
  sources kept (luminance >= ``threshold``), all else black; :func:`light_sources` lists its
  texels as directional sources (area-resampled, total power kept): direction and irradiance
  E_j = L_j Omega_j.
* *specular-parameter map* (:func:`specular_parameter_map`): (H, W, 2) k_s and the Blinn-Phong
  exponent n per pixel.
* *light-reflection map* (:func:`light_reflection_map`): the sources mirrored by the surface with
  the energy-preserving lobe of Eq. 4, ``sum_j k_s E_j (n + 2) / (8 pi) cos^n(N.H_j)`` for
  N.L_j > 0 (render.shading.brdf).
* :func:`glare_sources`: bright pixels of a display-scaled image -> (centres, excess, intensity,
  n) in the pixel convention of ``render.shading.glare`` (pixel centres at +0.5, y down).
* :func:`rasterize_triangles_reference`: per-pixel numpy twin of the GL streak pass (triangles
  with linearly interpolated vertex colours sampled at pixel centres, summed = additive blend).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from render.shading.brdf import blinn_phong_normalized
from render.shading.envmap import EnvMap

#: Rec. 709 luminance (linear RGB).
LUMA = np.array([0.2126, 0.7152, 0.0722])
#: Light-source map default: sources are texels of at least this luminance (the exposure set to
#: the highlights, METHODS §4); the bundled maps' skies stay below ~20, their suns are 50-2000.
LIGHT_SOURCE_THRESHOLD = 40.0
#: Height of the resampled map the sources are listed from (power preserving).
LIGHT_SOURCE_HEIGHT = 128
#: Most sources kept (brightest first, by irradiance).
MAX_LIGHT_SOURCES = 256


def luminance(rgb) -> np.ndarray:
    return np.asarray(rgb, np.float64) @ LUMA


def light_source_map(env: EnvMap, threshold: float = LIGHT_SOURCE_THRESHOLD) -> EnvMap:
    """The environment with only the texels of luminance >= ``threshold`` kept (others 0)."""
    keep = luminance(env.data) >= threshold
    return EnvMap(np.where(keep[..., None], env.data, 0).astype(np.float32), f"{env.name}-lights")


class LightSources(NamedTuple):
    """dirs (J, 3) unit world directions; irradiance (J, 3) = L Omega of each source texel."""

    dirs: np.ndarray
    irradiance: np.ndarray


def light_sources(lsm: EnvMap, height: int = LIGHT_SOURCE_HEIGHT,
                  max_sources: int = MAX_LIGHT_SOURCES) -> LightSources:
    """The non-zero texels of a light-source map, area-resampled to ``height`` rows (total power
    kept), as directional sources; at most ``max_sources`` (the brightest)."""
    small = lsm.resized(min(int(height), lsm.height))
    e = small.data.astype(np.float64) * small.pixel_solid_angles()[..., None]
    flat = e.reshape(-1, 3)
    lum = flat @ LUMA
    idx = np.flatnonzero(lum > 0)
    idx = idx[np.argsort(-lum[idx], kind="stable")][:max_sources]
    return LightSources(small.pixel_directions().reshape(-1, 3)[idx], flat[idx])


def specular_parameter_map(shape, k_s=1.0, n=100.0, mask=None) -> np.ndarray:
    """(H, W, 2) float32 specular-parameter map: k_s (channel 0) and the exponent n (channel 1),
    scalars or (H, W) arrays; 0 outside ``mask``."""
    h, w = int(shape[0]), int(shape[1])
    out = np.empty((h, w, 2), np.float32)
    out[..., 0] = k_s
    out[..., 1] = n
    if np.any(out < 0) or not np.all(np.isfinite(out)):
        raise ValueError("specular_parameter_map: k_s and n must be finite and >= 0")
    if mask is not None:
        out[~np.asarray(mask, bool)] = 0
    return out


def light_reflection_map(normals, view_dirs, spec, sources: LightSources) -> np.ndarray:
    """(H, W, 3) float64 light-reflection map (see module doc). normals, view_dirs (H, W, 3)
    unit world vectors (view = from the surface towards the eye); spec (H, W, 2); pixels with
    k_s = 0 stay 0."""
    nrm = np.asarray(normals, np.float64)
    v = np.asarray(view_dirs, np.float64)
    spec = np.asarray(spec, np.float64)
    if spec.shape[:-1] != nrm.shape[:-1] or spec.shape[-1] != 2 or v.shape != nrm.shape:
        raise ValueError(f"light_reflection_map: shapes normals {nrm.shape}, view {v.shape}, spec {spec.shape}")
    out = np.zeros(nrm.shape[:-1] + (3,))
    live = spec[..., 0] > 0
    if not np.any(live) or len(sources.dirs) == 0:
        return out
    N, V, ks, ne = nrm[live], v[live], spec[live, 0], spec[live, 1]
    acc = np.zeros((len(N), 3))
    for j in range(len(sources.dirs)):
        l = sources.dirs[j]
        h = l[None] + V
        h /= np.maximum(np.linalg.norm(h, axis=-1, keepdims=True), 1e-12)
        lobe = blinn_phong_normalized(np.sum(N * h, -1), ne) * (N @ l > 0)
        acc += (ks * lobe)[:, None] * sources.irradiance[j][None]
    out[live] = acc
    return out


class GlareSources(NamedTuple):
    """Bright pixels in the convention of render.shading.glare: centres (N, 2) (x + 0.5, y + 0.5)
    pixels, y down; excess (N, 3) light moved into the streaks; intensity (N,) peak luminance
    (display units); n (N,) Blinn-Phong exponents."""

    centres: np.ndarray
    excess: np.ndarray
    intensity: np.ndarray
    n: np.ndarray


def glare_sources(image, display_max: float = 1.0, mask=None, spec=None, default_n: float = 100.0) -> GlareSources:
    """Bright pixels of ``image`` (H, W, 3) linear, exposure applied: luminance > display_max
    (inside ``mask`` if given). Their excess is what render.shading.glare.bright_pixels defines
    (the colour above luminance display_max, hue kept); n from ``spec`` (H, W, 2) or default_n."""
    from render.shading.glare import bright_pixels

    img = np.asarray(image, np.float64)
    if mask is not None:
        img = np.where(np.asarray(mask, bool)[..., None], img, 0.0)
    c, e, inten = bright_pixels(img, display_max)
    ij = (c - 0.5).astype(np.int64)
    n = np.full(len(c), float(default_n)) if spec is None else np.asarray(spec, np.float64)[ij[:, 1], ij[:, 0], 1]
    return GlareSources(c, e, inten * display_max, n)


def remove_excess(image, src: GlareSources) -> np.ndarray:
    """float64 copy of ``image`` with each source pixel's excess taken out."""
    out = np.array(image, np.float64)
    ij = (src.centres - 0.5).astype(np.int64)
    out[ij[:, 1], ij[:, 0]] -= src.excess
    return out


def rasterize_triangles_reference(pos, col, width: int, height: int) -> np.ndarray:
    """(H, W, 3) float64: every triangle of (T*3, 2) positions (pixels, y down, pixel (x, y)
    sampled at (x + 0.5, y + 0.5)) with (T*3, 3) vertex colours, linearly interpolated at the
    pixel centres it covers, summed -- the numpy twin of additive GL drawing (edge pixels exactly
    on a shared edge may differ: the value there is ~0 on the streaks' rims)."""
    p = np.asarray(pos, np.float64).reshape(-1, 3, 2)
    c = np.asarray(col, np.float64).reshape(-1, 3, 3)
    out = np.zeros((height, width, 3))
    for a, ca in zip(p, c):
        lo = np.maximum(np.floor(a.min(0) - 0.5).astype(int), 0)
        hi = np.minimum(np.ceil(a.max(0) - 0.5).astype(int), [width - 1, height - 1])
        if np.any(hi < lo):
            continue
        yy, xx = np.mgrid[lo[1]:hi[1] + 1, lo[0]:hi[0] + 1]
        px, py = xx + 0.5, yy + 0.5
        (x0, y0), (x1, y1), (x2, y2) = a
        det = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        if det == 0:
            continue
        l1 = ((px - x0) * (y2 - y0) - (x2 - x0) * (py - y0)) / det
        l2 = ((x1 - x0) * (py - y0) - (px - x0) * (y1 - y0)) / det
        l0 = 1 - l1 - l2
        inside = (l0 >= 0) & (l1 >= 0) & (l2 >= 0)
        val = l0[..., None] * ca[0] + l1[..., None] * ca[1] + l2[..., None] * ca[2]
        out[lo[1]:hi[1] + 1, lo[0]:hi[0] + 1] += np.where(inside[..., None], val, 0.0)
    return out

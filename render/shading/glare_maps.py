"""Glare maps (docs/methods.md §4 §3.2-3.3; seed 002) and the numpy twin of the streak rasteriser.

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
* :func:`glare_sources`: bright pixels of a display-scaled image (OpenCV pixel centres).
* :func:`make_streaks`: the streak pairs of the bright pixels as parameters (centre, axis,
  half-length L, width W, centre colour c) for the instanced GL fans of ``render/composite/glare_layer.py``;
  shape from render.shading.glare (``streak_shape`` Eq. 7-12, ``streak_directions``,
  ``eyelash_factor``). A pair is a rhombus with half-diagonals L (along) and W / 2 (across),
  value ``c max(0, 1 - |s| / L - 2 |t| / W)`` (the fan of 4 triangles, centre c, rim 0), holding
  c L W / 3; c = 3 e / (L W) for its share e of the pixel's excess.
  Widths below MIN_STREAK_WIDTH are raised to it (energy kept through c): sampled at pixel
  centres, sub-pixel fans put the whole peak c on the centre pixel (measured 4x too much light
  for W ~ 0.2 px), so the GL pass also supersamples (render/composite/glare_layer.py).
* :func:`rasterize_streaks_reference`: numpy twin of the GL pass (tent at the sub-sample
  centres, box average), and :func:`streak_energy_on_screen` (analytic light inside the window).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from capture.camera import resample_pixel_coords
from capture.sampling import cell_centres, nearest_pixel
from render.shading.brdf import blinn_phong_normalized
from render.shading.envmap import EnvMap
from render.shading.lights import LUMA

#: Light-source map default: sources are texels of at least this luminance (the exposure set to
#: the highlights, docs/methods.md §4); the bundled maps' skies stay below ~20, their suns are 50-2000.
LIGHT_SOURCE_THRESHOLD = 40.0
#: Height of the resampled map the sources are listed from (power preserving).
LIGHT_SOURCE_HEIGHT = 128
#: Narrowest streak pair drawn (pixels); see the module doc.
MIN_STREAK_WIDTH = 1.0
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
    """Bright pixels: centres (N, 2) OpenCV pixel centres (u = column, v = row, integers);
    excess (N, 3) light moved into the streaks; intensity (N,) peak luminance (display units);
    n (N,) Blinn-Phong exponents."""

    centres: np.ndarray
    excess: np.ndarray
    intensity: np.ndarray
    n: np.ndarray


def glare_sources(image, display_max: float = 1.0, mask=None, spec=None, default_n: float = 100.0) -> GlareSources:
    """Bright pixels of ``image`` (H, W, 3) linear, exposure applied: luminance > display_max
    (inside ``mask`` if given). Their excess is what render.shading.glare.bright_pixel_indices
    defines (the colour above luminance display_max, hue kept); n from ``spec`` (H, W, 2) or default_n."""
    from render.shading.glare import bright_pixel_indices

    img = np.asarray(image, np.float64)
    if mask is not None:
        img = np.where(np.asarray(mask, bool)[..., None], img, 0.0)
    ij, e, inten = bright_pixel_indices(img, display_max)
    n = np.full(len(ij), float(default_n)) if spec is None else np.asarray(spec, np.float64)[ij[:, 1], ij[:, 0], 1]
    return GlareSources(ij.astype(np.float64), e, inten * display_max, n)


def remove_excess(image, src: GlareSources) -> np.ndarray:
    """float64 copy of ``image`` with each source pixel's excess taken out."""
    out = np.array(image, np.float64)
    ij = nearest_pixel(src.centres)  # the sources' own pixels (their centres are integers)
    out[ij[:, 1], ij[:, 0]] -= src.excess
    return out


class Streaks(NamedTuple):
    """M streak pairs in OpenCV pixels: centre (M, 2) (u, v); axis (M, 2) unit (image axes, v
    down); length (M,) half-diagonal along the axis; width (M,) full width across; colour (M, 3)
    value at the centre; energy (M, 3) = colour * length * width / 3 (the pair's light)."""

    centre: np.ndarray
    axis: np.ndarray
    length: np.ndarray
    width: np.ndarray
    colour: np.ndarray
    energy: np.ndarray

    def __len__(self) -> int:
        return len(self.length)


def make_streaks(src: GlareSources, cfg=None, min_width: float = MIN_STREAK_WIDTH) -> Streaks:
    """The streak pairs of ``src`` (module doc). cfg: render.shading.glare.GlareConfig."""
    from render.shading.glare import GlareConfig, eyelash_factor, streak_directions, streak_shape

    cfg = GlareConfig() if cfg is None else cfg
    c = np.asarray(src.centres, np.float64).reshape(-1, 2)
    N, D = len(c), int(cfg.n_dirs)
    ks_il = np.asarray(src.intensity, np.float64) * 8 * np.pi / (np.asarray(src.n, np.float64) + 2)  # peak -> k_s I_l
    L_s, W_s = streak_shape(ks_il, src.n, cfg.k_length, cfg.k_size)
    ang = streak_directions(c[:, 0], cfg)  # (N, D) degrees from horizontal
    L = np.clip(L_s[:, None] * eyelash_factor(ang), 0.5, cfg.max_length)
    W = np.maximum(np.broadcast_to(W_s[:, None], L.shape), min_width)
    rad = np.radians(ang)
    axis = np.stack([np.cos(rad), -np.sin(rad)], -1)  # measured upwards on screen (v down)
    energy = np.broadcast_to(np.asarray(src.excess, np.float64)[:, None, :] / D, (N, D, 3))
    colour = 3.0 * energy / (L * W)[..., None]
    centre = np.broadcast_to(c[:, None, :], (N, D, 2))
    return Streaks(centre.reshape(-1, 2).copy(), axis.reshape(-1, 2).copy(), L.reshape(-1), W.reshape(-1),
                   colour.reshape(-1, 3), energy.reshape(-1, 3).copy())


def _tent(streaks: Streaks, m: int, uu, vv):
    c, a = streaks.centre[m], streaks.axis[m]
    du, dv = uu - c[0], vv - c[1]
    s = du * a[0] + dv * a[1]
    t = -du * a[1] + dv * a[0]
    return np.maximum(0.0, 1 - np.abs(s) / streaks.length[m] - 2 * np.abs(t) / streaks.width[m])


def _extent(streaks: Streaks, m: int):
    a = np.abs(streaks.axis[m])
    return a * streaks.length[m] + a[..., ::-1] * streaks.width[m] / 2


def rasterize_streaks_reference(streaks: Streaks, width: int, height: int, supersample: int = 1) -> np.ndarray:
    """(H, W, 3) float64 numpy twin of render.composite.glare_layer.GlareLayer: every pair's tent evaluated at the
    s x s sub-sample centres of each pixel (``capture.camera.resample_pixel_coords``), summed,
    box-averaged."""
    s = int(supersample)
    Ws, Hs = width * s, height * s
    out = np.zeros((Hs, Ws, 3))
    for m in range(len(streaks)):
        c, ext = streaks.centre[m], _extent(streaks, m)
        lo = np.maximum(np.floor(resample_pixel_coords(c - ext, s)).astype(int), 0)
        hi = np.minimum(np.ceil(resample_pixel_coords(c + ext, s)).astype(int), [Ws - 1, Hs - 1])
        if np.any(hi < lo):
            continue
        jj, ii = np.mgrid[lo[1]:hi[1] + 1, lo[0]:hi[0] + 1]
        w = _tent(streaks, m, resample_pixel_coords(ii, 1.0 / s), resample_pixel_coords(jj, 1.0 / s))
        out[lo[1]:hi[1] + 1, lo[0]:hi[0] + 1] += w[..., None] * streaks.colour[m]
    return out.reshape(height, s, width, s, 3).mean(axis=(1, 3))


def streak_energy_on_screen(streaks: Streaks, width: int, height: int) -> np.ndarray:
    """(3,) analytic streak light inside the window [-0.5, W - 0.5] x [-0.5, H - 0.5]: the full
    energy of pairs lying inside, a fine quadrature (8 x 8 per pixel) of those crossing the edge."""
    tot = np.zeros(3)
    lim = np.array([width - 0.5, height - 0.5])
    for m in range(len(streaks)):
        c, ext = streaks.centre[m], _extent(streaks, m)
        if np.all(c - ext >= -0.5) and np.all(c + ext <= lim):
            tot += streaks.energy[m]
            continue
        lo, hi = np.maximum(c - ext, -0.5), np.minimum(c + ext, lim)
        if np.any(hi <= lo):
            continue
        n = np.maximum(np.ceil((hi - lo) * 8).astype(int), 1)
        uu, vv = np.meshgrid(cell_centres(n[0], lo[0], hi[0]), cell_centres(n[1], lo[1], hi[1]))
        tot += _tent(streaks, m, uu, vv).sum() * np.prod((hi - lo) / n) * streaks.colour[m]
    return tot

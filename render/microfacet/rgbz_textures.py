"""The RGBz texels the microfacets and the VDTM baseline sample (``microfacet_rgbz.glsl``), and the
matte beside them when the model has one (volume.model.RgbzImages.alpha).

With a matte the colour texels hold the PREMULTIPLIED colour (rgb x alpha) and the matte layer
the alpha: the shaders then carry (premultiplied rgb, alpha) through Eq. 2, the blend and the
fallback exactly as they carry the colour (``HAS_ALPHA``), and a slice fragment's output alpha
is the blended view alpha (the frame's alpha: the coverage of the drawn samples times it).
"""

from __future__ import annotations

import numpy as np

#: Storage of the RGBz and matte texture arrays (GL "f2").
RGBZ_DTYPE = np.float16


def rgbz_array(rgb: np.ndarray, depth: np.ndarray, alpha: np.ndarray | None = None) -> np.ndarray:
    """(N, H, W, 4) float32 RGBz texels: linear rgb (premultiplied by ``alpha`` (N, H, W) when
    given) + z-depth in metres (0 = none)."""
    rgb = np.asarray(rgb, np.float32)
    if alpha is not None:
        rgb = rgb * np.asarray(alpha, np.float32)[..., None]
    return np.concatenate([rgb, np.asarray(depth, np.float32)[..., None]], axis=-1)


def twin_colours(rgb: np.ndarray, alpha: np.ndarray | None = None) -> np.ndarray:
    """(N, H, W, 3 or 4) float64 colours the numpy twins sample, as the GPU stores them
    (RGBZ_DTYPE): rgb, or premultiplied rgb + alpha with a matte."""
    col = rgbz_array(rgb, np.zeros(np.shape(rgb)[:3]), alpha)[..., :3].astype(RGBZ_DTYPE).astype(np.float64)
    if alpha is None:
        return col
    return np.concatenate([col, np.asarray(alpha).astype(RGBZ_DTYPE).astype(np.float64)[..., None]], -1)


def matte_texture(ctx, alpha: np.ndarray | None):
    """R16F texture array of the matte (NEAREST, clamped; sampler ``matte`` of microfacet_rgbz.glsl),
    or None without one."""
    if alpha is None:
        return None
    a = np.ascontiguousarray(np.asarray(alpha, np.float32).astype(RGBZ_DTYPE))
    n, H, W = a.shape
    tex = ctx.texture_array((W, H, n), 1, a.tobytes(), dtype="f2")
    tex.filter = (ctx.NEAREST, ctx.NEAREST)
    tex.repeat_x = tex.repeat_y = False
    return tex

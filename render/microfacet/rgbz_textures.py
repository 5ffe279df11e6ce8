"""The RGBz texels the microfacets and the VDTM baseline sample (``microfacet_rgbz.glsl``), and the
matte beside them when the model has one (volume.model.RgbzImages.alpha).

With a matte the colour texels hold the PREMULTIPLIED colour (rgb x alpha) and the matte layer
the alpha: the shaders then carry (premultiplied rgb, alpha) through Eq. 2, the blend and the
fallback exactly as they carry the colour (``HAS_ALPHA``), and a slice fragment's output alpha
is the blended view alpha (the frame's alpha: the coverage of the drawn samples times it).

:func:`layer_textures` builds the arrays view by view from a model's RgbzImages (``rgbz.view(n)``,
float16 values: render.crops.view_f16), never the decoded (N, H, W) stacks: these methods index
their views by full-frame pixel (the microfacet cull pyramid too), so they upload full layers, not
the crops gather and points upload (render/crops.py).
"""

from __future__ import annotations

import numpy as np

from render.crops import view_f16

#: Storage of the RGBz and matte texture arrays (GL "f2").
RGBZ_DTYPE = np.float16
#: Largest full-frame texture arrays :func:`layer_textures` makes (bytes): 200 views of 1920x1440
#: need 5.5 GB, which took llvmpipe past the 23 GB of this machine (the process was killed).
MAX_LAYER_BYTES = 2 << 30


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


def layer_textures(ctx, rgbz, depth=None, dtype: str = "f2", on_view=None):
    """(RGBz texture array, matte texture array or None) of ``rgbz`` (RgbzImages), written view by
    view: layer i = :func:`rgbz_array` of view i (its depth, or ``depth[i]`` (H, W) metres when
    given), stored as GL ``dtype`` ("f2": RGBZ_DTYPE, or "f4"); NEAREST, clamped.  ``on_view(i,
    texels)`` (optional) sees each layer's (H, W, 4) float32 texels as computed (before storage)."""
    n = len(rgbz)
    W, H = rgbz.size
    need = n * W * H * (4 * (2 if dtype == "f2" else 4) + (2 if rgbz.has_alpha else 0))
    if need > MAX_LAYER_BYTES:
        raise ValueError(f"this method keeps every view as a full {W}x{H} texture layer: {n} views need "
                         f"{need / 2 ** 30:.1f} GiB (limit {MAX_LAYER_BYTES / 2 ** 30:.0f}); render with --method "
                         "gather or points (they upload the crops around the object), or build the model with fewer or "
                         "smaller views (furrow model --views N, --output-size WxH)")
    tex = ctx.texture_array((W, H, max(n, 1)), 4, None, dtype=dtype)
    matte = ctx.texture_array((W, H, max(n, 1)), 1, None, dtype="f2") if rgbz.has_alpha else None
    for i in range(n):
        rgb, d, a = view_f16(rgbz, i)
        if depth is not None:
            d = np.asarray(depth[i], np.float32)
        texels = rgbz_array(rgb[None], d[None], None if a is None else a[None])[0]
        if on_view is not None:
            on_view(i, texels)
        stored = texels.astype(RGBZ_DTYPE) if dtype == "f2" else texels
        tex.write(np.ascontiguousarray(stored).tobytes(), viewport=(0, 0, i, W, H, 1))
        if matte is not None:
            matte.write(np.ascontiguousarray(a, RGBZ_DTYPE).tobytes(), viewport=(0, 0, i, W, H, 1))
    for t in (tex, matte):
        if t is not None:
            t.filter = (ctx.NEAREST, ctx.NEAREST)
            t.repeat_x = t.repeat_y = False
    return tex, matte

"""The kept views uploaded as their crops only (issue 24): what gather and points read of a model's
RGBz images (volume.rgbz_store.RgbzImages), one view at a time, never the decoded full stack.

Every view arrives as ``rgbz.crop(n)``: its rectangle (x0, y0, w, h) in the W x H image and the
decoded colour, depth and matte inside it; outside the rectangle a view is empty (colour 0, depth
0, alpha 0).  A dense store's crop is the whole frame, so the same code serves both stores.

Values are taken as float16 (:func:`crop_f16`): what every dense store holds and what a compact
store's ``rgb`` / ``depth`` / ``alpha`` stacks decode to, so a renderer built from crops sees
exactly the texels it saw through the full stacks (bit-identical frames; tests/render/gather).

:class:`CropTextures` uploads them as a texture array whose layers are the size of the largest
crop (layer i: view i's crop at its origin, written when first asked for) plus the (N, 4)
rectangles: a shader fetches image
pixel (x, y) of view i at layer texel (x - x0, y - y0) and treats a pixel outside the rectangle
as empty (``gather_frag.glsl`` ``texel``).
"""

from __future__ import annotations

import numpy as np

#: Storage of the uploaded colour, depth and matte texels (GL "f2"): the RGBz store's own type.
TEXEL_DTYPE = np.float16


def crop_f16(rgbz, n: int):
    """(rect (x0, y0, w, h) ints, rgb (h, w, 3), depth (h, w), alpha (h, w) or None) of view n of
    ``rgbz`` (an RgbzImages), as float16 values held in float32 arrays."""
    rect, rgb, depth, alpha = rgbz.crop(n)
    f = [None if a is None else np.asarray(a).astype(TEXEL_DTYPE).astype(np.float32) for a in (rgb, depth, alpha)]
    return tuple(int(v) for v in rect), f[0], f[1], f[2]


def view_f16(rgbz, n: int):
    """(rgb (H, W, 3), depth (H, W), alpha (H, W) or None) full frames of view n of ``rgbz`` as
    float16 values held in float32 arrays: one row of the stacks ``rgbz.rgb`` / ``.depth`` /
    ``.alpha`` without decoding (or holding) the others."""
    return tuple(None if a is None else np.asarray(a).astype(TEXEL_DTYPE).astype(np.float32) for a in rgbz.view(n))


def layer_size(rects: np.ndarray) -> tuple[int, int]:
    """(w, h) of a texture-array layer holding the largest of ``rects`` (N, 4) (at least 1 x 1)."""
    r = np.asarray(rects, np.int64).reshape(-1, 4)
    if not len(r):
        return 1, 1
    return max(int(r[:, 2].max()), 1), max(int(r[:, 3].max()), 1)


class CropTextures:
    """GPU texture arrays of the kept views' crops, each layer written when first asked for
    (:meth:`load`): a frame uploads only the views it reads (the first frame of a large capture
    a handful of them), :meth:`load_all` the rest.

    Attributes:
        rgbz: RGBA16F array (w, h, N): linear straight rgb + z-depth (metres, 0 = none) of view i's
            crop at layer i, texel (0, 0) = image pixel (x0, y0); texels beyond the crop (and
            layers not loaded) undefined: a shader reads only inside ``rects`` of loaded views.
        matte: R16F array of the straight alpha alike, or None (a model without a matte).
        rects: (N, 4) int32 (x0, y0, w, h) of each layer's crop in its W x H image.
        bytes: bytes uploaded so far (the texels of the loaded crops).
    """

    def __init__(self, ctx, rgbz):
        self.source = rgbz
        n_views = len(rgbz)
        self.rects = np.asarray(rgbz.rects, np.int32).reshape(-1, 4)
        lw, lh = layer_size(self.rects)
        self.rgbz = ctx.texture_array((lw, lh, max(n_views, 1)), 4, None, dtype="f2")
        self.matte = ctx.texture_array((lw, lh, max(n_views, 1)), 1, None, dtype="f2") if rgbz.has_alpha else None
        for t in (self.rgbz, self.matte):
            if t is not None:
                t.filter = (ctx.NEAREST, ctx.NEAREST)
                t.repeat_x = t.repeat_y = False
        self.loaded = np.zeros(n_views, bool)
        self.bytes = 0

    def load(self, n: int):
        """Decode view n's crop (:func:`crop_f16`), write its layers; returns (rect, rgb, depth,
        alpha) as decoded (for the caller's own per-view buffers).  Loads it again if asked twice."""
        rect, rgb, depth, alpha = crop_f16(self.source, n)
        w, h = rect[2], rect[3]
        if w * h:
            texels = np.concatenate([rgb, depth[..., None]], -1).astype(TEXEL_DTYPE)
            self.rgbz.write(np.ascontiguousarray(texels).tobytes(), viewport=(0, 0, n, w, h, 1))
            self.bytes += texels.nbytes
            if self.matte is not None:
                a = np.ascontiguousarray(np.zeros((h, w)) if alpha is None else alpha, TEXEL_DTYPE)
                self.matte.write(a.tobytes(), viewport=(0, 0, n, w, h, 1))
                self.bytes += a.nbytes
        self.loaded[n] = True
        return rect, rgb, depth, alpha

    def release(self) -> None:
        for t in (self.rgbz, self.matte):
            if t is not None:
                t.release()

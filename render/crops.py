"""The kept views uploaded as their crops only (issue 24): what gather and points read of a model's
RGBz images (volume.rgbz_store.RgbzImages), one view at a time, never the decoded full stack.

Every view arrives as ``rgbz.crop(n)``: its rectangle (x0, y0, w, h) in the W x H image and the
decoded colour, depth and matte inside it; outside the rectangle a view is empty (colour 0, depth
0, alpha 0).  A dense store's crop is the whole frame, so the same code serves both stores.

Values are taken as float16 (:func:`crop_f16`): what every dense store holds and what a compact
store's ``rgb`` / ``depth`` / ``alpha`` stacks decode to, so a renderer built from crops sees
exactly the texels it saw through the full stacks (bit-identical frames; tests/render/gather).

:class:`CropTextures` uploads them as a texture array whose layers are the size of the largest
crop (a cache of ``RESIDENT_VIEWS`` layers, a view written into one when first asked for) plus
the (N, 4) rectangles: a shader fetches image pixel (x, y) of view i at texel (x - x0, y - y0) of
its layer and treats a pixel outside the rectangle
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


#: Views resident on the GPU at once (texture-array layers; the least recently used is replaced):
#: a frame of gather needs k_depth + k_blend (4), so memory is bounded whatever the capture's size.
RESIDENT_VIEWS = 16


class CropTextures:
    """GPU texture arrays of the kept views' crops: a cache of ``RESIDENT_VIEWS`` layers (fewer with
    fewer views), each view written into a layer when first asked for (:meth:`load`), the least
    recently used view replaced when all are taken.  A frame uploads only the views it reads (the
    first frame of a large capture a handful of them), and the memory stays bounded.

    Attributes:
        rgbz: RGBA16F array (w, h, layers): linear straight rgb + z-depth (metres, 0 = none) of a
            resident view's crop, texel (0, 0) = image pixel (x0, y0); texels beyond the crop
            undefined: a shader reads only inside the view's rect.
        matte: R16F array of the straight alpha alike, or None (a model without a matte).
        rects: (N, 4) int32 (x0, y0, w, h) of each view's crop in its W x H image.
        layer: (N,) int, the layer holding view i, -1 when it is not resident.
        bytes: bytes uploaded so far (the texels of the crops written).
    """

    def __init__(self, ctx, rgbz, capacity: int = RESIDENT_VIEWS):
        self.source = rgbz
        n_views = len(rgbz)
        self.rects = np.asarray(rgbz.rects, np.int32).reshape(-1, 4)
        lw, lh = layer_size(self.rects)
        self.capacity = max(min(n_views, int(capacity)), 1)
        self.rgbz = ctx.texture_array((lw, lh, self.capacity), 4, None, dtype="f2")
        self.matte = ctx.texture_array((lw, lh, self.capacity), 1, None, dtype="f2") if rgbz.has_alpha else None
        for t in (self.rgbz, self.matte):
            if t is not None:
                t.filter = (ctx.NEAREST, ctx.NEAREST)
                t.repeat_x = t.repeat_y = False
        self.layer = np.full(n_views, -1, int)
        self._owner = np.full(self.capacity, -1, int)  # view held by each layer
        self._used = np.zeros(self.capacity, np.int64)  # last use (a counter) of each layer
        self._clock = 0
        self.bytes = 0

    @property
    def loaded(self) -> np.ndarray:
        """(N,) bool: the views resident now."""
        return self.layer >= 0

    def load(self, views, on_load=None, on_evict=None) -> None:
        """Make ``views`` resident (at most ``capacity`` of them): each one not resident is decoded
        (:func:`crop_f16`) into a free layer or the least recently used one outside ``views``;
        ``on_evict(n)`` is told of a view replaced, ``on_load(n, rect, rgb, depth, alpha)`` sees
        each decoded crop (for the caller's per-view buffers)."""
        views = [int(v) for v in dict.fromkeys(int(v) for v in views)]
        if len(views) > self.capacity:
            raise ValueError(f"CropTextures.load: {len(views)} views at once, {self.capacity} layers")
        self._clock += 1
        for n in views:  # mark first, so that none of them is replaced by another
            if self.layer[n] >= 0:
                self._used[self.layer[n]] = self._clock
        for n in views:
            if self.layer[n] >= 0:
                continue
            slot = int(np.argmin(self._used))
            old = self._owner[slot]
            if old >= 0:
                self.layer[old] = -1
                if on_evict is not None:
                    on_evict(int(old))
            self._owner[slot], self.layer[n], self._used[slot] = n, slot, self._clock
            rect, rgb, depth, alpha = crop_f16(self.source, n)
            self._write(slot, rect, rgb, depth, alpha)
            if on_load is not None:
                on_load(n, rect, rgb, depth, alpha)

    def _write(self, slot: int, rect, rgb, depth, alpha) -> None:
        w, h = rect[2], rect[3]
        if not w * h:
            return
        texels = np.concatenate([rgb, depth[..., None]], -1).astype(TEXEL_DTYPE)
        self.rgbz.write(np.ascontiguousarray(texels).tobytes(), viewport=(0, 0, slot, w, h, 1))
        self.bytes += texels.nbytes
        if self.matte is not None:
            a = np.ascontiguousarray(np.zeros((h, w)) if alpha is None else alpha, TEXEL_DTYPE)
            self.matte.write(a.tobytes(), viewport=(0, 0, slot, w, h, 1))
            self.bytes += a.nbytes

    def release(self) -> None:
        for t in (self.rgbz, self.matte):
            if t is not None:
                t.release()

"""RGBz images held as the object, not the frame (issue 24): per-view crops, encoded compactly.

:class:`RgbzImages` is what ``volume`` hands to ``render`` (docs/methods.md §1.4).  It holds its
views in one of two stores:

* **dense** (``RgbzImages(rgb, depth, cameras, alpha)``): full frames as float16, as every model
  before issue 24 (tests and hand-made models use it; rgbz.npz files of schema 1 load as it);
* **compact** (``RgbzImages.from_crops(cameras, crops)``, what ``furrow model`` builds): per view
  a :class:`RgbzCrop`, the rectangle of the image around the object's footprint (every pixel with
  geometry depth or alpha, grown by a margin, :func:`crop_margin_px`) with 8-bit sRGB colour,
  8-bit alpha and 16-bit depth quantised over the view's own depth range [z0, z0 + 65534 dz]
  (dz = 5 um for an object 0.3 m deep: finer than float16's 0.1 mm at 0.4 m).  Pixels outside
  the rectangle are empty: colour 0, depth 0, alpha 0.  On disk every view is its own member of a
  compressed npz (:func:`save_crops`), read only when that view is asked for (:func:`open_crops`).

The renderers read ``rgb`` (N, H, W, 3) linear float16, ``depth`` (N, H, W), ``alpha`` (N, H, W)
or None and ``cameras`` as before: a compact store decodes the full stack on first access (and
keeps it).  Per-view readers use :meth:`RgbzImages.view` (one decoded full frame) or
:meth:`RgbzImages.crop` (one decoded crop and its rectangle) and never hold the stack.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from capture.camera import Camera
from capture.sampling import mask_box
from capture.scan import srgb_to_linear, to_uint8_srgb


class ModelError(ValueError):
    """An invalid model (in memory or on disk); the message names the field or file."""


#: Storage type of dense RGBz images: half floats, what the microfacet renderer uploads anyway.
#: 11-bit mantissa: every 8-bit sRGB value round-trips exactly; depth to 1/4096 relative
#: (0.1 mm at 0.4 m, below the 1 mm of a millimetre PNG).
RGBZ_STORAGE = np.float16
#: Quantised depth levels of a compact crop: 0 = no depth, 1..DEPTH_LEVELS over the view's range.
DEPTH_LEVELS = 65535
#: Crop margin around the object's footprint: this fraction of the image diagonal...
CROP_MARGIN_FRACTION = 0.02
#: ...and at least this many pixels (colour a renderer may resample just beside a silhouette).
CROP_MARGIN_MIN_PX = 8
#: Marker key of a compact rgbz.npz (dense files hold "rgb" and "depth").
COMPACT_KEY = "compact_rects"
#: zlib level of a compact rgbz.npz's members (:func:`save_crops`; volume.splats.RGBZ_DEFLATE_LEVEL sizes it).
CROPS_DEFLATE_LEVEL = 6
#: The 256 linear values of the 8-bit sRGB codes (decoding is a table lookup).
_SRGB_LUT = srgb_to_linear(np.arange(256, dtype=np.float32) / 255.0)


def crop_margin_px(width: int, height: int) -> int:
    """Margin (pixels) kept around the object's footprint in a W x H view."""
    return max(CROP_MARGIN_MIN_PX, int(np.ceil(CROP_MARGIN_FRACTION * float(np.hypot(width, height)))))


def bbox(mask: np.ndarray, margin: int) -> tuple[int, int, int, int]:
    """(x0, y0, w, h) of the bounding box of ``mask`` (H, W) bool grown by ``margin`` pixels and
    clipped to the image; (0, 0, 0, 0) when the mask is empty."""
    box = mask_box(mask)
    if box is None:
        return 0, 0, 0, 0
    H, W = np.shape(mask)
    y0, y1 = max(box[0] - margin, 0), min(box[1] + margin, H)
    x0, x1 = max(box[2] - margin, 0), min(box[3] + margin, W)
    return x0, y0, x1 - x0, y1 - y0


@dataclass(frozen=True)
class RgbzCrop:
    """One view's encoded RGBz crop.

    Attributes:
        rect: (x0, y0, w, h) pixels of the crop in its W x H image (w = h = 0: nothing).
        srgb: (h, w, 3) uint8 sRGB colour.
        depth: (h, w) uint16 quantised z-depth: 0 = none, q >= 1 means z0 + (q - 1) * dz metres.
        z0: metres, the depth of code 1; dz: metres per code (> 0).
        alpha: (h, w) uint8 straight alpha (255 = opaque), or None.
        measured: (h, w) bool, the pixels whose depth is the capture's own measurement (not the
            geometry's fill or the closing, volume.rgbz), or None = every pixel with depth (the
            models before it was kept).
    """

    rect: tuple
    srgb: np.ndarray
    depth: np.ndarray
    z0: float
    dz: float
    alpha: np.ndarray | None = None
    measured: np.ndarray | None = None

    def __post_init__(self) -> None:
        x0, y0, w, h = (int(v) for v in self.rect)
        if min(x0, y0, w, h) < 0:
            raise ModelError(f"RgbzCrop: bad rectangle {self.rect}")
        if self.srgb.shape != (h, w, 3) or self.srgb.dtype != np.uint8:
            raise ModelError(f"RgbzCrop: srgb must be ({h},{w},3) uint8, got {self.srgb.shape} {self.srgb.dtype}")
        if self.depth.shape != (h, w) or self.depth.dtype != np.uint16:
            raise ModelError(f"RgbzCrop: depth must be ({h},{w}) uint16, got {self.depth.shape} {self.depth.dtype}")
        if self.alpha is not None and (self.alpha.shape != (h, w) or self.alpha.dtype != np.uint8):
            raise ModelError(f"RgbzCrop: alpha must be ({h},{w}) uint8, got {self.alpha.shape} {self.alpha.dtype}")
        if self.measured is not None and (self.measured.shape != (h, w) or self.measured.dtype != bool):
            m = self.measured
            raise ModelError(f"RgbzCrop: measured must be ({h},{w}) bool, got {m.shape} {m.dtype}")
        if not (np.isfinite(self.z0) and self.z0 >= 0 and np.isfinite(self.dz) and self.dz > 0):
            raise ModelError(f"RgbzCrop: depth range z0 {self.z0}, dz {self.dz} must be finite, dz > 0")
        object.__setattr__(self, "rect", (x0, y0, w, h))
        object.__setattr__(self, "z0", float(self.z0))
        object.__setattr__(self, "dz", float(self.dz))

    @classmethod
    def encode(cls, rgb: np.ndarray, depth: np.ndarray, alpha: np.ndarray | None = None,
               margin: int | None = None, measured: np.ndarray | None = None) -> RgbzCrop:
        """Crop of one full frame: ``rgb`` (H, W, 3) linear float or uint8 sRGB, ``depth`` (H, W)
        metres (0 = none), ``alpha`` (H, W) in [0, 1] or None, ``measured`` (H, W) bool or None;
        the rectangle holds every pixel with depth or alpha, grown by ``margin`` (default
        :func:`crop_margin_px`)."""
        depth = np.asarray(depth, np.float32)
        H, W = depth.shape
        keep = depth > 0
        if alpha is not None:
            keep = keep | (np.asarray(alpha) > 0)
        x0, y0, w, h = bbox(keep, crop_margin_px(W, H) if margin is None else int(margin))
        sl = (slice(y0, y0 + h), slice(x0, x0 + w))
        c = np.asarray(rgb)[sl]
        srgb = c if c.dtype == np.uint8 else to_uint8_srgb(c)
        d = depth[sl]
        has = d > 0
        z0 = float(d[has].min()) if has.any() else 0.0
        span = float(d[has].max()) - z0 if has.any() else 0.0
        dz = max(span / (DEPTH_LEVELS - 1), np.finfo(np.float32).tiny, z0 * 1e-9)
        q = np.where(has, np.round((d - z0) / dz) + 1, 0)
        a = None if alpha is None else np.round(np.clip(np.asarray(alpha, np.float32)[sl], 0, 1) * 255).astype(np.uint8)
        m = None if measured is None else np.ascontiguousarray(np.asarray(measured, bool)[sl] & has)
        return cls((x0, y0, w, h), np.ascontiguousarray(srgb), np.clip(q, 0, DEPTH_LEVELS).astype(np.uint16),
                   z0, dz, a, m)

    def decode(self) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """(rgb (h, w, 3) float32 linear, depth (h, w) float32 metres, alpha (h, w) float32 or None)."""
        q = self.depth
        z = np.where(q > 0, self.z0 + (q.astype(np.float64) - 1) * self.dz, 0.0).astype(np.float32)
        a = None if self.alpha is None else self.alpha.astype(np.float32) / np.float32(255)
        return _SRGB_LUT[self.srgb], z, a

    def save(self, path: Path) -> Path:
        """Write the crop to its own file (uncompressed npz; a view's crop waiting to join the model's
        store, volume.rgbz.build_rgbz); ``path``."""
        arrays = {"rect": np.asarray(self.rect, np.int64), "srgb": self.srgb, "depth": self.depth,
                  "range": np.array([self.z0, self.dz], np.float64)}
        for k in ("alpha", "measured"):
            if getattr(self, k) is not None:
                arrays[k] = getattr(self, k)
        tmp = Path(path).with_suffix(".tmp.npz")
        np.savez(tmp, **arrays)
        tmp.rename(path)
        return Path(path)

    @classmethod
    def load(cls, crop, remove: bool = False) -> RgbzCrop:
        """``crop`` itself, or the crop read from the file :meth:`save` wrote (removed after reading
        when ``remove``)."""
        if isinstance(crop, RgbzCrop):
            return crop
        with np.load(crop) as z:
            out = cls(tuple(int(v) for v in z["rect"]), z["srgb"], z["depth"], float(z["range"][0]),
                      float(z["range"][1]), *(z[k] if k in z.files else None for k in ("alpha", "measured")))
        if remove:
            Path(crop).unlink()
        return out

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in (self.srgb, self.depth, self.alpha, self.measured) if a is not None)


def save_crops(path: Path, crops, with_alpha: bool) -> None:
    """Write crops (an iterable, consumed one at a time) as a compressed npz: member
    ``COMPACT_KEY`` (N, 4) int64 rectangles, ``ranges`` (N, 2) float64 (z0, dz), and per view
    ``v<n>_srgb``, ``v<n>_depth`` (+ ``v<n>_alpha``; + ``v<n>_measured`` where the crop has it)."""
    import zipfile

    rects, ranges = [], []
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED, compresslevel=CROPS_DEFLATE_LEVEL) as zf:
        for n, c in enumerate(crops):
            rects.append(c.rect)
            ranges.append((c.z0, c.dz))
            for name, a in crop_arrays(n, c, with_alpha):
                _member(zf, name, a)
        _member(zf, COMPACT_KEY, np.asarray(rects, np.int64).reshape(-1, 4))
        _member(zf, "ranges", np.asarray(ranges, np.float64).reshape(-1, 2))


def crop_arrays(n: int, c: RgbzCrop, with_alpha: bool) -> list[tuple[str, np.ndarray]]:
    """(member name, array) of view ``n``'s crop ``c`` in a compact rgbz.npz, in :func:`save_crops`' order."""
    out = [(f"v{n}_srgb", c.srgb), (f"v{n}_depth", c.depth)]
    if with_alpha:
        out.append((f"v{n}_alpha", c.alpha if c.alpha is not None else np.full(c.depth.shape, 255, np.uint8)))
    if c.measured is not None:
        out.append((f"v{n}_measured", c.measured))
    return out


def _member(zf, name: str, a: np.ndarray) -> None:
    from numpy.lib import format as npformat

    with zf.open(name + ".npy", "w", force_zip64=True) as fh:
        npformat.write_array(fh, np.ascontiguousarray(a), allow_pickle=False)


class CropFile:
    """The crops of a compact rgbz.npz, read one view at a time (:meth:`crop`); the rectangles and
    depth ranges are read at once.  Errors name the file."""

    def __init__(self, path: Path):
        self.path = Path(path)
        with np.load(self.path, allow_pickle=False) as z:
            self.rects = z[COMPACT_KEY].astype(np.int64)
            self.ranges = z["ranges"].astype(np.float64)
            self.has_alpha = "v0_alpha" in z.files
        if self.ranges.shape != (len(self.rects), 2):
            raise ModelError(f"{self.path}: ranges must be ({len(self.rects)}, 2), got {self.ranges.shape}")

    def __len__(self) -> int:
        return len(self.rects)

    def measured(self, n: int) -> np.ndarray | None:
        """View n's measured-depth mask alone (RgbzCrop.measured; None when the file has none), without
        decoding its colour and depth again (a renderer that has its crop reads this beside it)."""
        try:
            with np.load(self.path, allow_pickle=False) as z:
                key = f"v{n}_measured"
                return z[key] if key in z.files else None
        except Exception as e:  # corrupt zip
            raise ModelError(f"{self.path}: cannot read view {n}'s measured mask ({type(e).__name__}: {e})") from None

    def crop(self, n: int) -> RgbzCrop:
        try:
            with np.load(self.path, allow_pickle=False) as z:
                a = z[f"v{n}_alpha"] if self.has_alpha else None
                m = z[f"v{n}_measured"] if f"v{n}_measured" in z.files else None
                return RgbzCrop(tuple(self.rects[n]), z[f"v{n}_srgb"], z[f"v{n}_depth"], float(self.ranges[n, 0]),
                                float(self.ranges[n, 1]), a, m)
        except ModelError as e:
            raise ModelError(f"{self.path}: view {n}: {e}") from None
        except Exception as e:  # missing member, corrupt zip
            raise ModelError(f"{self.path}: cannot read view {n} ({type(e).__name__}: {e})") from None


def full_frame(rect, rgb: np.ndarray, depth: np.ndarray, alpha: np.ndarray | None, W: int, H: int):
    """A decoded crop (:meth:`RgbzCrop.decode` at ``rect``) as full W x H frames (rgb (H, W, 3),
    depth (H, W), alpha (H, W) or None), float32, empty outside the rectangle (:meth:`RgbzImages.view`)."""
    x0, y0, w, h = rect
    out = np.zeros((H, W, 3), np.float32), np.zeros((H, W), np.float32)
    out[0][y0:y0 + h, x0:x0 + w] = rgb
    out[1][y0:y0 + h, x0:x0 + w] = depth
    a = None
    if alpha is not None:
        a = np.zeros((H, W), np.float32)
        a[y0:y0 + h, x0:x0 + w] = alpha
    return out[0], out[1], a


def is_compact(path: Path) -> bool:
    """True when the rgbz.npz at ``path`` is a compact (cropped) one."""
    with np.load(path, allow_pickle=False) as z:
        return COMPACT_KEY in z.files


class RgbzImages:
    """Per-camera colour + geometry depth (docs/methods.md §1.4, the paper's RGBz images).

    Attributes:
        rgb: (N, H, W, 3) linear colour, float16 (RGBZ_STORAGE; float32 or float16 given).
        depth: (N, H, W) z-depth (metres, along the optical axis) of the geometry projected
            into each camera, 0 = no geometry; float16 (float32 or float16 given).
        cameras: N cameras (OpenCV convention), all of size W x H.
        alpha: optional (N, H, W) straight alpha matte of the object per camera in [0, 1]
            (RGBZ_STORAGE); None = binary (has geometry depth = opaque).
        measured (:meth:`measured_mask`): per view, the pixels whose depth the capture measured
            (not the geometry's fill); None = every pixel with depth.
    A compact store (module docstring) decodes rgb / depth / alpha on first access.
    """

    def __init__(self, rgb=None, depth=None, cameras=(), alpha=None, *, crops=None, measured=None):
        cams = tuple(cameras)
        object.__setattr__(self, "cameras", cams)
        object.__setattr__(self, "_crops", crops)
        object.__setattr__(self, "_dense", None)
        object.__setattr__(self, "_measured", None)
        if crops is not None:
            _check_crops(cams, crops)
            return
        object.__setattr__(self, "_dense", _dense(rgb, depth, cams, alpha))
        if measured is not None:
            m = np.asarray(measured, bool)
            if m.shape != self._dense[1].shape:
                raise ModelError(f"RgbzImages: measured must be {self._dense[1].shape}, got {m.shape}")
            m = m & (self._dense[1] > 0)
            m.setflags(write=False)
            object.__setattr__(self, "_measured", m)

    def __setattr__(self, name, value):
        raise AttributeError(f"RgbzImages is frozen (cannot set {name})")

    @property
    def crop_file(self) -> Path | None:
        """The compact rgbz.npz the crops are read from (a CropFile store), else None."""
        return self._crops.path if isinstance(self._crops, CropFile) else None

    @classmethod
    def from_crops(cls, cameras, crops) -> RgbzImages:
        """A compact store: ``crops`` a list of :class:`RgbzCrop` or a :class:`CropFile`."""
        return cls(cameras=cameras, crops=crops)

    def __len__(self) -> int:
        return len(self.cameras)

    @property
    def compact(self) -> bool:
        return self._crops is not None

    @property
    def size(self) -> tuple[int, int]:
        """(W, H) of every view (0, 0 without views)."""
        return (self.cameras[0].width, self.cameras[0].height) if self.cameras else (0, 0)

    @property
    def has_alpha(self) -> bool:
        if self._crops is None:
            return self._dense[2] is not None
        if isinstance(self._crops, CropFile):
            return self._crops.has_alpha
        return bool(self._crops) and self._crops[0].alpha is not None

    @property
    def rects(self) -> np.ndarray:
        """(N, 4) int64 (x0, y0, w, h) of each view's crop (the full frame in a dense store)."""
        if self._crops is None:
            W, H = self.size
            return np.tile(np.array([0, 0, W, H], np.int64), (len(self), 1))
        if isinstance(self._crops, CropFile):
            return self._crops.rects.copy()
        return np.array([c.rect for c in self._crops], np.int64).reshape(-1, 4)

    def encoded(self, n: int) -> RgbzCrop:
        """View n's encoded crop (compact stores only)."""
        if self._crops is None:
            raise ModelError("RgbzImages.encoded: a dense store has no encoded crops")
        return self._crops.crop(n) if isinstance(self._crops, CropFile) else self._crops[n]

    def crop(self, n: int) -> tuple[tuple, np.ndarray, np.ndarray, np.ndarray | None]:
        """(rect (x0, y0, w, h), rgb (h, w, 3) float32 linear, depth (h, w) float32 metres,
        alpha (h, w) float32 or None) of view n: what a renderer uploads (crop API, issue 24)."""
        if self._crops is None:
            rgb, depth, alpha = self._dense
            W, H = self.size
            return ((0, 0, W, H), rgb[n].astype(np.float32), depth[n].astype(np.float32),
                    None if alpha is None else alpha[n].astype(np.float32))
        c = self.encoded(n)
        return (c.rect, *c.decode())

    def measured_mask(self, n: int) -> np.ndarray | None:
        """(h, w) bool on view n's crop (:meth:`crop`'s rectangle): the pixels whose depth the
        capture measured; None = every pixel with depth (a model built before the mask was kept)."""
        if self._crops is None:
            return None if self._measured is None else self._measured[n]
        if isinstance(self._crops, CropFile):
            return self._crops.measured(n)
        return self._crops[n].measured

    @property
    def measured(self) -> np.ndarray | None:
        """(N, H, W) bool full frames of :meth:`measured_mask`, or None when no view has a mask."""
        if self._crops is None:
            return self._measured
        W, H = self.size
        out = np.zeros((len(self), H, W), bool)
        found = False
        for i, (x0, y0, w, h) in enumerate(self.rects):
            m = self.measured_mask(i)
            if m is None:
                m = self.crop(i)[2] > 0
            else:
                found = True
            out[i, y0:y0 + h, x0:x0 + w] = m
        return out if found else None

    def view(self, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """View n as full frames (rgb (H, W, 3), depth (H, W), alpha (H, W) or None), float32."""
        rect, rgb, depth, alpha = self.crop(n)
        if self._crops is None:
            return rgb, depth, alpha
        return full_frame(rect, rgb, depth, alpha, *self.size)

    def _decoded(self):
        if self._dense is None:
            W, H = self.size
            n = len(self)
            rgb, depth = np.zeros((n, H, W, 3), RGBZ_STORAGE), np.zeros((n, H, W), RGBZ_STORAGE)
            alpha = np.zeros((n, H, W), RGBZ_STORAGE) if self.has_alpha else None
            for i in range(n):
                (x0, y0, w, h), c, d, a = self.crop(i)
                rgb[i, y0:y0 + h, x0:x0 + w] = c
                depth[i, y0:y0 + h, x0:x0 + w] = d
                if alpha is not None:
                    alpha[i, y0:y0 + h, x0:x0 + w] = a
            for a in (rgb, depth, alpha):
                if a is not None:
                    a.setflags(write=False)
            object.__setattr__(self, "_dense", (rgb, depth, alpha))
        return self._dense

    @property
    def rgb(self) -> np.ndarray:
        return self._decoded()[0]

    @property
    def depth(self) -> np.ndarray:
        return self._decoded()[1]

    @property
    def alpha(self) -> np.ndarray | None:
        return self._decoded()[2]

    def stored_bytes(self) -> int:
        """Bytes of the arrays held (encoded crops, or the dense stack) before any decoding."""
        if self._crops is None or isinstance(self._crops, CropFile):
            return sum(a.nbytes for a in (self._dense or ()) if a is not None)
        return sum(c.nbytes for c in self._crops)


def _check_crops(cams, crops) -> None:
    if len(crops) != len(cams):
        raise ModelError(f"RgbzImages: {len(crops)} crops for {len(cams)} cameras")
    if cams and any((c.height, c.width) != (cams[0].height, cams[0].width) for c in cams):
        raise ModelError("RgbzImages: all cameras must have the same image size")
    rects = crops.rects if isinstance(crops, CropFile) else np.array([c.rect for c in crops]).reshape(-1, 4)
    if cams and len(rects) and (np.any(rects[:, 0] + rects[:, 2] > cams[0].width)
                                or np.any(rects[:, 1] + rects[:, 3] > cams[0].height)):
        raise ModelError("RgbzImages: a crop reaches outside its image")


def _dense(rgb, depth, cams: tuple[Camera, ...], alpha):
    """Validated read-only float16 (rgb, depth, alpha) of a dense store."""
    rgb = np.asarray(rgb)
    depth = np.asarray(depth)
    n = len(cams)
    if rgb.dtype not in (np.float32, np.float16) or depth.dtype not in (np.float32, np.float16):
        raise ModelError(f"RgbzImages: rgb and depth must be float32 or float16, got {rgb.dtype}, {depth.dtype}")
    rgb, depth = rgb.astype(RGBZ_STORAGE), depth.astype(RGBZ_STORAGE)  # own copies
    if n == 0:
        if rgb.size or depth.size:
            raise ModelError("RgbzImages: images given without cameras")
        H = W = 0
    else:
        H, W = cams[0].height, cams[0].width
        if any((c.height, c.width) != (H, W) for c in cams):
            raise ModelError("RgbzImages: all cameras must have the same image size")
    if rgb.shape != (n, H, W, 3) and not (n == 0 and rgb.size == 0):
        raise ModelError(f"RgbzImages: rgb must be ({n},{H},{W},3), got {rgb.shape}")
    if depth.shape != (n, H, W) and not (n == 0 and depth.size == 0):
        raise ModelError(f"RgbzImages: depth must be ({n},{H},{W}), got {depth.shape}")
    if not np.all(np.isfinite(depth)) or (depth.size and depth.min() < 0):
        raise ModelError("RgbzImages: depth must be finite and >= 0 (0 = no geometry)")
    rgb, depth = rgb.reshape(n, H, W, 3), depth.reshape(n, H, W)
    if alpha is not None:
        alpha = np.asarray(alpha)
        if alpha.shape != depth.shape:
            raise ModelError(f"RgbzImages: alpha must be {depth.shape}, got {alpha.shape}")
        if not np.all(np.isfinite(alpha)) or (alpha.size and (alpha.min() < 0 or alpha.max() > 1)):
            raise ModelError("RgbzImages: alpha must be finite and in [0, 1]")
        alpha = alpha.astype(RGBZ_STORAGE)
        alpha.setflags(write=False)
    rgb.setflags(write=False)
    depth.setflags(write=False)
    return rgb, depth, alpha

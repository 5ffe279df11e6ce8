"""Scans and scan sets: the data passed from ``capture`` to ``volume``.

A :class:`Scan` is one colour image and one z-depth map seen by one :class:`Camera`;
a :class:`ScanSet` is the posed set plus the object's bounds.  Both are frozen and
validated on construction (shapes, dtypes, units) with errors that name the scan.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from capture.camera import Camera
from capture.sampling import points_box


class ScanError(ValueError):
    """Invalid scan data; the message names the scan / file."""


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """sRGB-encoded values in [0, 1] -> linear (IEC 61966-2-1)."""
    c = np.asarray(c, dtype=np.float32)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)


#: :func:`srgb8_to_linear` of an image by OpenCV's table lookup (True), else numpy's indexing (the reference).
SRGB8_CV2 = True
#: The linear values of the 256 8-bit sRGB codes (:func:`srgb8_to_linear`).
_SRGB8_LUT = srgb_to_linear(np.arange(256, dtype=np.float32) / 255.0)


def srgb8_to_linear(rgb: np.ndarray) -> np.ndarray:
    """``srgb_to_linear(rgb.astype(np.float32) / 255.0)`` of uint8 sRGB codes as a table lookup: the
    same float32 values (the table is that function of the 256 codes), without a power per pixel
    (0.8 s a 1920x1440 frame here; tests/capture/test_scan_store.py compares them).  An image of up to
    four channels is looked up by OpenCV (``cv2.LUT``: the same float32 values, 0.5 ms a 1280x960 frame
    against 7.9 ms by numpy's indexing, which stays for other shapes and as the reference: SRGB8_CV2)."""
    rgb = np.asarray(rgb, np.uint8)
    if SRGB8_CV2 and rgb.ndim in (2, 3) and (rgb.ndim == 2 or rgb.shape[2] <= 4) and rgb.size:
        import cv2

        return cv2.LUT(np.ascontiguousarray(rgb), _SRGB8_LUT)
    return _SRGB8_LUT[rgb]


#: float16 of :data:`_SRGB8_LUT` (:func:`linear16`).
_SRGB8_LUT16 = _SRGB8_LUT.astype(np.float16)


def linear16(rgb: np.ndarray) -> np.ndarray:
    """``Scan.linear_rgb.astype(np.float16)`` of a scan's ``rgb`` (uint8 sRGB codes or float linear):
    for 8-bit codes one float16 table lookup, the same values without a float32 frame between
    (the background plate stage's views, volume/surroundings.py)."""
    rgb = np.asarray(rgb)
    return _SRGB8_LUT16[rgb] if rgb.dtype == np.uint8 else rgb.astype(np.float16)


def linear_to_srgb(c: np.ndarray) -> np.ndarray:
    """Linear values -> sRGB-encoded in [0, 1] (clipped)."""
    # ``np.where(c <= 0.0031308, c * 12.92, 1.055 * np.power(c, 1 / 2.4) - 0.055)`` of the clipped
    # float32 c, operation for operation in place (the same float32 values: tests/capture/test_plate.py)
    c = np.asarray(np.clip(np.asarray(c, dtype=np.float32), 0.0, 1.0), np.float32)
    out = np.power(c, 1 / 2.4, out=np.empty_like(c))
    np.multiply(out, 1.055, out=out)
    np.subtract(out, 0.055, out=out)
    np.multiply(c, 12.92, out=out, where=c <= 0.0031308)
    return out


def to_uint8_srgb(linear: np.ndarray) -> np.ndarray:
    """Linear float image -> 8-bit sRGB (rounded)."""
    return np.round(linear_to_srgb(linear) * 255.0).astype(np.uint8)


@dataclass(frozen=True)
class Scan:
    """One colour + range capture.

    Attributes:
        rgb: (H, W, 3) uint8 sRGB, or float32 linear radiance.
        depth: (H, W) float32 z-depth along the optical axis in metres; 0 = no measurement.
            NaN / inf are accepted on input and replaced by 0 (no measurement).
        camera: the camera (OpenCV convention) with matching width / height.
        name: identifier, usually the colour file's path relative to the scan set.
        alpha: optional (H, W) float32 straight alpha matte in [0, 1] of the object (1 = opaque
            object, 0 = background; partial on fringe pixels of strands and needles), from the
            capture (``mask_path``, an RGBA image) or estimated (the matting stage); None = not
            known (then "has object depth" is the only mask).
    """

    rgb: np.ndarray
    depth: np.ndarray
    camera: Camera
    name: str = ""
    alpha: np.ndarray | None = None

    def __post_init__(self) -> None:
        label = f"scan {self.name!r}" if self.name else "scan"
        rgb = np.asarray(self.rgb)
        depth = np.asarray(self.depth)
        H, W = self.camera.height, self.camera.width
        if rgb.ndim != 3 or rgb.shape[2] != 3:
            raise ScanError(f"{label}: colour must be (H, W, 3), got shape {rgb.shape}")
        if rgb.dtype not in (np.uint8, np.float32):
            raise ScanError(f"{label}: colour must be uint8 sRGB or float32 linear, got {rgb.dtype}")
        if rgb.shape[:2] != (H, W):
            raise ScanError(f"{label}: colour is {rgb.shape[1]}x{rgb.shape[0]} but the camera is {W}x{H}")
        if depth.shape != (H, W):
            raise ScanError(f"{label}: depth is {depth.shape[::-1]} (WxH) but the camera is {W}x{H}")
        depth = depth.astype(np.float32, copy=True)
        depth[~np.isfinite(depth) | (depth < 0)] = 0.0
        if self.alpha is not None:
            alpha = np.asarray(self.alpha)
            if alpha.shape != (H, W):
                raise ScanError(f"{label}: alpha matte is {alpha.shape[::-1]} (WxH) but the camera is {W}x{H}")
            alpha = np.clip(np.nan_to_num(alpha.astype(np.float32), nan=0.0), 0.0, 1.0)
            alpha.setflags(write=False)
            object.__setattr__(self, "alpha", alpha)
        rgb = rgb.copy()
        rgb.setflags(write=False)
        depth.setflags(write=False)
        object.__setattr__(self, "rgb", rgb)
        object.__setattr__(self, "depth", depth)

    @property
    def linear_rgb(self) -> np.ndarray:
        """(H, W, 3) float32 linear colour."""
        if self.rgb.dtype == np.uint8:
            return srgb8_to_linear(self.rgb)
        return self.rgb

    @property
    def srgb8(self) -> np.ndarray:
        """(H, W, 3) uint8 sRGB colour."""
        return self.rgb if self.rgb.dtype == np.uint8 else to_uint8_srgb(self.rgb)

    @property
    def valid(self) -> np.ndarray:
        """(H, W) bool: pixels with a depth measurement."""
        return self.depth > 0

    def points(self) -> np.ndarray:
        """(N, 3) world points of every valid depth pixel."""
        return self.camera.depth_to_points(self.depth)[0]


@dataclass(frozen=True)
class ScanSet:
    """A set of posed scans of one object.

    Attributes:
        scans: the scans, in capture order.
        bounds: (2, 3) float64 axis-aligned box [min, max] (metres, world) that contains the
            object; every later stage (volume, renderer) works inside it.
        metadata: free-form provenance (source path, generator, seed, ...).
    """

    scans: tuple[Scan, ...]
    bounds: np.ndarray
    metadata: dict = field(default_factory=dict, compare=False)

    def __post_init__(self) -> None:
        scans = tuple(self.scans)
        if not scans:
            raise ScanError("a scan set needs at least one scan")
        b = np.asarray(self.bounds, dtype=np.float64)
        if b.shape != (2, 3) or not np.all(np.isfinite(b)) or np.any(b[1] <= b[0]):
            raise ScanError(f"scan set bounds must be a finite (2, 3) [min, max] box with max > min, got {b.tolist()}")
        b = b.copy()
        b.setflags(write=False)
        object.__setattr__(self, "scans", scans)
        object.__setattr__(self, "bounds", b)

    def __len__(self) -> int:
        return len(self.scans)

    @property
    def cameras(self) -> list[Camera]:
        return [s.camera for s in self.scans]

    @property
    def size(self) -> float:
        """Diagonal of the bounds in metres (the object's size)."""
        return float(np.linalg.norm(self.bounds[1] - self.bounds[0]))

    def select(self, spec: str | None) -> ScanSet:
        """Frames chosen python-slice style: ``"0::2"``, ``"3"``, ``"1,4,7"``, ``":10"``."""
        idx = select_indices(spec, len(self.scans))
        return ScanSet(tuple(self.scans[i] for i in idx), self.bounds, {**self.metadata, "frames": spec})


def select_indices(spec: str | None, n: int) -> list[int]:
    """Indices of ``range(n)`` picked by a slice spec (``a:b:c``), an index or a comma list."""
    if spec is None or spec == "":
        return list(range(n))
    out: list[int] = []
    try:
        for part in spec.split(","):
            part = part.strip()
            if ":" in part:
                bits = [int(b) if b.strip() else None for b in part.split(":")]
                if len(bits) > 3:
                    raise ValueError
                out.extend(range(n)[slice(*bits)])
            else:
                i = int(part)
                if not -n <= i < n:
                    raise IndexError(f"frame {i} out of range for {n} frames")
                out.append(i % n)
    except ValueError:
        raise ValueError(f"bad frame spec {spec!r}: use python slices like '0::2', '3', or '1,4,7'") from None
    if not out:
        raise ValueError(f"frame spec {spec!r} selects no frame out of {n}")
    return out


#: Depth pixels :func:`sampled_points` back-projects at most (a 200-frame phone capture has 550 million).
MAX_SAMPLED_POINTS = 8_000_000


def sampled_points(scans, max_points: int = MAX_SAMPLED_POINTS) -> np.ndarray:
    """(N, 3) world points of the scans' depth pixels, read one scan at a time; above ``max_points``
    depth pixels in all, every k-th pixel of each scan (the same k for all) stands for them."""
    total = sum(int(np.count_nonzero(s.depth > 0)) for s in scans)
    k = max(1, -(-total // max(int(max_points), 1)))
    pts = [p for p in (every_kth_point(s, k) for s in scans) if len(p)]
    return np.concatenate(pts) if pts else np.zeros((0, 3))


def every_kth_point(scan, k: int) -> np.ndarray:
    """(N, 3) world points of every ``k``-th depth pixel of ``scan`` in row-major order: the rows
    ``scan.points()[::k]``, only those pixels back-projected (a 200-frame phone capture's bounds
    back-projected all 550 million of its depth pixels to keep 8 million)."""
    depth = np.asarray(scan.depth)
    flat = np.flatnonzero(np.isfinite(depth) & (depth > 0))[::k]  # np.nonzero's pixels, row-major
    v, u = np.divmod(flat, depth.shape[1])
    if not len(v):
        return np.zeros((0, 3))
    return scan.camera.unproject(np.stack([u, v], axis=-1).astype(np.float64), depth[v, u])


def bounds_from_points(points: np.ndarray, margin: float = 0.05) -> np.ndarray:
    """(2, 3) box around points, grown by ``margin`` of its diagonal on every side."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if not np.all(np.isfinite(p), axis=1).any():
        raise ScanError("cannot compute bounds: no valid 3-D points")
    lo, hi = points_box(p)
    pad = margin * max(np.linalg.norm(hi - lo), 1e-6)
    return np.stack([lo - pad, hi + pad])

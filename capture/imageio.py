"""Reading and writing the image files of a scan set: colour PNG/JPEG, 16-bit PNG and EXR depth.

Every reader raises :class:`ScanIOError` naming the file and the problem.  Every writer
writes to a temporary file beside the target and renames it into place.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from capture.atomic import atomic_write
from capture.scan import srgb_to_linear


class ScanIOError(ValueError):
    """A file of a scan set is missing, unreadable or inconsistent; the message names it."""


def finite_number(v, what: str, where: str) -> float:
    """A finite JSON number (or numeric string) read from file ``where``; bools, lists, objects,
    NaN and inf are a ScanIOError naming ``what``."""
    if isinstance(v, bool) or not isinstance(v, (int, float, str)):
        raise ScanIOError(f"{where}: {what} is not a number: {v!r}")
    try:
        v = float(v)
    except (ValueError, OverflowError):
        raise ScanIOError(f"{where}: {what} is not a number: {v!r}") from None
    if not np.isfinite(v):
        raise ScanIOError(f"{where}: {what} is not finite")
    return v


def _cv2():
    import cv2

    return cv2


def read_color(path: Path) -> np.ndarray:
    """Colour image -> (H, W, 3) uint8 sRGB, or float32 linear for 16-bit PNG / EXR input."""
    path = Path(path)
    if not path.is_file():
        raise ScanIOError(f"{path}: colour image not found")
    if path.suffix.lower() == ".exr":
        return read_exr_rgb(path)
    img = _cv2().imread(str(path), _cv2().IMREAD_UNCHANGED)
    if img is None:
        raise ScanIOError(f"{path}: not a readable image (corrupt or unsupported format)")
    if img.ndim == 2:
        img = np.repeat(img[..., None], 3, axis=2)
    elif img.shape[2] == 4:
        img = img[..., :3]
    elif img.shape[2] != 3:
        raise ScanIOError(f"{path}: colour image has {img.shape[2]} channels, expected 3 or 4")
    img = np.ascontiguousarray(img[..., ::-1])  # BGR -> RGB
    if img.dtype == np.uint8:
        return img
    if img.dtype == np.uint16:
        return srgb_to_linear(img.astype(np.float32) / 65535.0)
    raise ScanIOError(f"{path}: unsupported colour dtype {img.dtype}")


def read_depth_raw(path: Path) -> np.ndarray:
    """Depth file -> (H, W) raw values (uint16 for PNG, float32 for EXR / float TIFF)."""
    path = Path(path)
    if not path.is_file():
        raise ScanIOError(f"{path}: depth file not found")
    if path.suffix.lower() == ".exr":
        d = read_exr(path)
        if d.ndim == 3:
            d = d[..., 0]
        return d.astype(np.float32)
    if path.suffix.lower() == ".npy":
        try:
            d = np.load(path, allow_pickle=False)
        except Exception as e:
            raise ScanIOError(f"{path}: not a readable .npy depth array ({e})") from None
        if d.ndim != 2:
            raise ScanIOError(f"{path}: depth array must be 2-D, got shape {d.shape}")
        return d
    d = _cv2().imread(str(path), _cv2().IMREAD_UNCHANGED)
    if d is None:
        raise ScanIOError(f"{path}: not a readable depth image (corrupt or unsupported format)")
    if d.ndim == 3:
        raise ScanIOError(f"{path}: depth image has {d.shape[2]} channels; expected a single-channel "
                          "16-bit PNG (or float EXR)")
    if d.dtype == np.uint8:
        raise ScanIOError(f"{path}: depth image is 8-bit; expected 16-bit PNG or float EXR "
                          "(8 bits cannot hold a depth map)")
    return d


class _Chan:
    def __init__(self, pixels: np.ndarray):
        self.pixels = pixels


def read_exr(path: Path) -> np.ndarray:
    """EXR -> float32 (H, W) or (H, W, C): the first of the channel sets RGB, RGBA, separate
    R G B, then one of Z, Y, depth, D, R, V, or the only channel. OpenEXR package (docs/pitfalls.md)."""
    import OpenEXR

    try:
        with OpenEXR.File(str(path)) as f:
            chans = {k: _Chan(np.array(v.pixels)) for k, v in f.channels().items()}
    except Exception as e:
        raise ScanIOError(f"{path}: not a readable EXR file ({e})") from None
    for key in ("RGB", "RGBA"):
        if key in chans:
            return np.asarray(chans[key].pixels, dtype=np.float32)
    if all(k in chans for k in ("R", "G", "B")):
        return np.stack([chans[k].pixels for k in ("R", "G", "B")], axis=-1).astype(np.float32)
    for key in ("Z", "Y", "depth", "D", "R", "V"):
        if key in chans:
            return np.asarray(chans[key].pixels, dtype=np.float32)
    if len(chans) == 1:
        return np.asarray(next(iter(chans.values())).pixels, dtype=np.float32)
    raise ScanIOError(f"{path}: EXR has channels {sorted(chans)}; expected RGB, Y or Z")


def read_exr_rgb(path: Path) -> np.ndarray:
    """EXR -> float32 (H, W, 3) colour (:func:`read_exr`; one channel is repeated as grey, alpha dropped)."""
    img = read_exr(path)
    if img.ndim == 2:
        img = np.repeat(img[..., None], 3, axis=2)
    return np.ascontiguousarray(img[..., :3], dtype=np.float32)


def write_exr(path: Path, data: np.ndarray) -> None:
    """Write float32 (H, W) as channel Z, or (H, W, 3) as RGB (ZIP compression, lossless), atomically."""
    import OpenEXR

    data = np.ascontiguousarray(data, dtype=np.float32)
    key = "Z" if data.ndim == 2 else "RGB"
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with atomic_write(path) as tmp, OpenEXR.File(header, {key: data}) as f:
        f.write(str(tmp))


def write_png(path: Path, img: np.ndarray) -> None:
    """Write uint8 RGB (H, W, 3) or RGBA (H, W, 4), uint8 gray or uint16 gray (H, W) PNG atomically."""
    img = np.asarray(img)
    if img.ndim == 3:
        img = np.ascontiguousarray(img[..., [2, 1, 0, 3][: img.shape[2]]])  # RGB(A) -> BGR(A)
    with atomic_write(path) as tmp:
        if not _cv2().imwrite(str(tmp), img):
            raise ScanIOError(f"{path}: could not write PNG")


def depth_to_uint16(depth_m: np.ndarray, unit: float, name: str) -> np.ndarray:
    """Metres -> 16-bit integer depth units (0 stays 0); error if out of range."""
    d = np.asarray(depth_m, dtype=np.float64)
    q = np.round(np.where(np.isfinite(d) & (d > 0), d / unit, 0.0))
    if q.max(initial=0) > 65535:
        raise ScanIOError(f"{name}: depth {d.max():.3f} m does not fit 16-bit PNG at {unit} m per unit; use EXR")
    return q.astype(np.uint16)


def read_confidence(path: Path) -> np.ndarray:
    """Confidence map -> (H, W) uint8: an 8-bit single-channel PNG / TIFF (ARKit levels 0-2 or 0-255)."""
    path = Path(path)
    if not path.is_file():
        raise ScanIOError(f"{path}: confidence file not found")
    c = _cv2().imread(str(path), _cv2().IMREAD_UNCHANGED)
    if c is None:
        raise ScanIOError(f"{path}: not a readable confidence image (corrupt or unsupported format)")
    if c.ndim != 2 or c.dtype != np.uint8:
        raise ScanIOError(f"{path}: confidence must be an 8-bit single-channel image, got {c.dtype} "
                          f"with shape {c.shape}")
    return c

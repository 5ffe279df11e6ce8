"""The object's alpha matte on disk: per-frame ``mask_path`` of transforms.json, ``masks/NAME.png``
of the plain folder and COLMAP layouts, and RGBA colour images.

nerfstudio keys a per-frame mask as ``mask_path`` (binary: 0 = not the object); the plain folder
and COLMAP layouts hold it as ``masks/NAME.png`` beside ``rgb/`` or ``images/`` (COLMAP's own
``masks/IMAGE_NAME.png`` is read too).  The frame-reading step that reads it is
capture.sources.read_matte, the same for every layout.  furrow reads it as
a soft straight alpha matte: an 8-bit image in 0..255 (a binary 0/1 image is read as 0/1), 16-bit in
0..65535, the first channel of a colour mask; a colour image with an alpha channel (RGBA PNG)
supplies its alpha when the frame has no ``mask_path`` (unless it is opaque everywhere).  The mask
must have the colour image's size.
The writer stores ``Scan.alpha`` as ``masks/NAME.png`` (8-bit) and keys it in ``mask_path``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from capture.imageio import ScanIOError, write_png
from capture.scan import Scan

#: Folder of the mattes written beside images/ and depth/.
MASK_DIR = "masks"
#: PNG colour types (IHDR byte 25) that carry alpha: grey + alpha and RGBA.
PNG_ALPHA_TYPES = (4, 6)
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def read_matte(path: Path, shape: tuple[int, int]) -> np.ndarray:
    """(H, W) float32 alpha in [0, 1] from a mask image (module docstring); ``shape`` = (H, W)."""
    import cv2

    path = Path(path)
    if not path.is_file():
        raise ScanIOError(f"{path}: mask not found")
    m = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if m is None:
        raise ScanIOError(f"{path}: not a readable mask image (corrupt or unsupported format)")
    if m.ndim == 3:
        m = m[..., 3] if m.shape[2] == 4 else m[..., 0]
    if m.shape != tuple(shape):
        raise ScanIOError(f"{path}: mask is {m.shape[1]}x{m.shape[0]} but its colour image is {shape[1]}x{shape[0]}")
    if m.dtype == np.bool_ or (np.issubdtype(m.dtype, np.integer) and m.max(initial=0) <= 1):
        return m.astype(np.float32)
    if m.dtype == np.uint8:
        return m.astype(np.float32) / 255.0
    if m.dtype == np.uint16:
        return m.astype(np.float32) / 65535.0
    if np.issubdtype(m.dtype, np.floating):
        return np.clip(np.nan_to_num(m.astype(np.float32)), 0.0, 1.0)
    raise ScanIOError(f"{path}: unsupported mask dtype {m.dtype}")


#: A capture's given mattes are read as inverted (white = not the object) from the median view's figures
#: (:func:`matte_verdict`): when the pixels they call the object have depth less than MATTE_SHARE_RATIO times as
#: often as the rest (right mattes on 13 captures with their true mattes, over black, before a room, with a table and
#: clutter in the depth: 0.82-0.98 against 0.01-0.47, at least 1.9 times as often); where neither has depth this
#: many times as often as the other (depth over the whole frame: a room, a phone's LiDAR), when the object's median
#: depth is farther than MATTE_DEPTH_RATIO times the rest's (an object stands before its background; the margin is
#: for a table nearer than the object filling the rest, seen from above; inverted, the room is the "object").
MATTE_SHARE_RATIO = 0.5
MATTE_DEPTH_RATIO = 1.25


def matte_depth_shares(alpha: np.ndarray, depth: np.ndarray) -> tuple[float, float, float, float]:
    """(the share of the pixels a matte calls the object (alpha >= 0.5) that have depth, the share of the others
    that have depth, the median depth of each where they have it); NaN where a side has none."""
    a = np.asarray(alpha)
    z = np.asarray(depth, np.float32)
    d = np.isfinite(z) & (z > 0)
    fg = a >= 0.5
    out = []
    for side in (fg, ~fg):
        out.append(float(d[side].mean()) if side.any() else float("nan"))
    for side in (fg, ~fg):
        out.append(float(np.median(z[side & d])) if (side & d).any() else float("nan"))
    return tuple(out)


def matte_verdict(shares) -> dict | None:
    """The given mattes against the depth, from each matted view's :func:`matte_depth_shares`: ``views``, the median
    figures, ``inverted`` (:data:`MATTE_SHARE_RATIO`, :data:`MATTE_DEPTH_RATIO`) and a ``message``; None without
    mattes."""
    s = np.array([x for x in shares if x is not None], np.float64).reshape(-1, 4)
    if not len(s):
        return None
    with np.errstate(all="ignore"):
        fg, bg, zf, zb = (float(np.nanmedian(s[:, k])) if np.isfinite(s[:, k]).any() else float("nan")
                          for k in range(4))
    inverted = False
    if np.isfinite(fg) and np.isfinite(bg):
        if fg < MATTE_SHARE_RATIO * bg:
            inverted = True
        elif bg < MATTE_SHARE_RATIO * fg:
            inverted = False
        else:  # depth on both sides alike: the object must stand in front of the rest
            inverted = bool(np.isfinite(zf) and np.isfinite(zb) and zf > MATTE_DEPTH_RATIO * zb)
    msg = (f"the given mattes call the object pixels of which {fg:.0%} have depth (median {zf:.3g} m), and the rest "
           f"pixels of which {bg:.0%} have depth (median {zb:.3g} m): "
           + ("are they inverted (white = background)? furrow reads white as the object" if inverted
              else "they cover the object"))
    return {"views": len(s), "object_depth_share": round(fg, 4), "rest_depth_share": round(bg, 4),
            "object_depth_m": round(zf, 4), "rest_depth_m": round(zb, 4), "inverted": inverted, "message": msg}


def png_has_alpha(path: Path) -> bool:
    """True when ``path`` is a PNG whose colour type carries an alpha channel (reads 26 bytes)."""
    try:
        with open(path, "rb") as f:
            head = f.read(26)
    except OSError:
        return False
    return len(head) == 26 and head[:8] == PNG_SIGNATURE and head[25] in PNG_ALPHA_TYPES


def rgba_alpha(path: Path) -> np.ndarray | None:
    """(H, W) float32 alpha of an RGBA / grey-alpha PNG colour image, or None when it has none or
    when it is opaque everywhere (an alpha channel that says nothing about the object)."""
    if not png_has_alpha(path):
        return None
    a = read_matte(path, _png_shape(path))
    return None if a.min() >= 1.0 else a


def _png_shape(path: Path) -> tuple[int, int]:
    with open(path, "rb") as f:
        head = f.read(24)
    return int.from_bytes(head[20:24], "big"), int.from_bytes(head[16:20], "big")


def write_matte(scan: Scan, folder: Path, stem: str) -> dict:
    """Write ``scan.alpha`` as ``folder/masks/STEM.png`` (8-bit); the frame keys to add ({} without one)."""
    if scan.alpha is None:
        return {}
    rel = f"{MASK_DIR}/{stem}.png"
    write_png(Path(folder) / rel, np.round(np.clip(scan.alpha, 0, 1) * 255).astype(np.uint8))
    return {"mask_path": rel}

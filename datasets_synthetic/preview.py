"""Contact sheet of a scan set: colour tiles next to colourised depth tiles, one PNG."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from capture.scan import ScanSet

#: Most views shown (evenly spaced over the set).
MAX_TILES = 12
#: Tile width in pixels (height follows the aspect ratio); smaller images are not enlarged.
TILE_WIDTH = 320
#: Tiles (colour + depth pairs count as two) per row.
PAIRS_PER_ROW = 3
#: Gap between tiles (pixels) and its grey level.
GAP = 4
GAP_LEVEL = 40


def colourise_depth(depth: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """(H, W) z-depth (0 = none) -> (H, W, 3) uint8: near = warm, far = cool (turbo), none = black."""
    from matplotlib import colormaps

    d = np.asarray(depth, np.float64)
    valid = d > 0
    t = np.clip((d - lo) / max(hi - lo, 1e-9), 0, 1)
    rgb = colormaps["turbo"](1.0 - t)[..., :3]
    rgb[~valid] = 0
    return np.round(rgb * 255).astype(np.uint8)


def _resize(img: np.ndarray, w: int, h: int) -> np.ndarray:
    import cv2

    if img.shape[1] == w and img.shape[0] == h:
        return img
    return cv2.resize(img, (w, h), interpolation=cv2.INTER_AREA)


def contact_sheet_image(scanset: ScanSet, max_tiles: int = MAX_TILES, tile_width: int = TILE_WIDTH) -> np.ndarray:
    """(H, W, 3) uint8 sheet: for up to ``max_tiles`` evenly spaced views, the sRGB colour image
    and its depth (turbo, common range over the shown views), labelled with the view name."""
    import cv2

    n = len(scanset.scans)
    idx = np.unique(np.round(np.linspace(0, n - 1, min(n, max_tiles))).astype(int))
    scans = [scanset.scans[i] for i in idx]
    valid = np.concatenate([s.depth[s.depth > 0] for s in scans]) if scans else np.zeros(0)
    lo, hi = (np.percentile(valid, [1, 99]) if valid.size else (0.0, 1.0))
    H0, W0 = scans[0].depth.shape
    tw = min(tile_width, W0)
    th = int(round(H0 * tw / W0))
    tiles = []
    for i, s in zip(idx, scans):
        col = _resize(np.ascontiguousarray(s.srgb8), tw, th)
        dep = _resize(colourise_depth(s.depth, lo, hi), tw, th)
        label = Path(s.name).stem or f"view {i}"
        for t in (col, dep):
            cv2.putText(t, label, (3, 11), cv2.FONT_HERSHEY_SIMPLEX, 0.33, (255, 255, 255), 1, cv2.LINE_AA)
        tiles.append(np.concatenate([col, np.full((th, GAP, 3), GAP_LEVEL, np.uint8), dep], axis=1))
    pw = tiles[0].shape[1]
    cols = min(PAIRS_PER_ROW, len(tiles))
    rows = (len(tiles) + cols - 1) // cols
    sheet = np.full((rows * (th + GAP) + GAP, cols * (pw + 3 * GAP) + GAP, 3), GAP_LEVEL, np.uint8)
    for k, t in enumerate(tiles):
        r, c = divmod(k, cols)
        y, x = GAP + r * (th + GAP), GAP + c * (pw + 3 * GAP)
        sheet[y:y + th, x:x + pw] = t
    return sheet


def contact_sheet(scanset: ScanSet, path, max_tiles: int = MAX_TILES, tile_width: int = TILE_WIDTH) -> Path:
    """Write :func:`contact_sheet_image` as a PNG to ``path``; returns the path."""
    from capture.imageio import write_png

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_png(path, contact_sheet_image(scanset, max_tiles, tile_width))
    return path


def contact_sheet_png_bytes(scanset: ScanSet, max_tiles: int = MAX_TILES, tile_width: int = TILE_WIDTH) -> bytes:
    """The contact sheet encoded as PNG bytes (for writing inside an atomic folder)."""
    import cv2

    img = contact_sheet_image(scanset, max_tiles, tile_width)
    ok, buf = cv2.imencode(".png", np.ascontiguousarray(img[..., ::-1]))
    if not ok:
        raise RuntimeError("could not encode the contact sheet as PNG")
    return buf.tobytes()

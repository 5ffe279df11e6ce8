"""Per-view work on the object's footprint, one view (or a bounded batch) at a time (issue 24).

Most of a turntable or phone frame is background with no depth.  The fusion's per-pixel maps
(depth, normal, plane offset, view cosine, no-return flag; volume.fusion.scan_maps) are needed
only where a depth is, or next to one: every other pixel holds the same record (no depth, a
clear no-return).  :func:`pack_scans` therefore computes each scan's maps on its *footprint
rectangle* only (the bounding box of its depth pixels, grown by FOOTPRINT_MARGIN_PX) and writes
them straight into one packed array (volume.fusion_jit.PackedMaps) whose other pixels all read
one shared void record.  Nothing of the size of a frame is held for more than the views being
computed (NORMAL_THREADS at a time), so the stage's peak is the packed footprints plus a few
frames' temporaries, not every frame's maps twice (a list of ScanMaps, then its packed copy).

The margin keeps the result equal to the full-frame maps (tests/volume/test_stream.py checks it
bit for bit): the bilateral filter reads BILATERAL_DIAMETER // 2 pixels around a depth pixel,
the no-return flag SILHOUETTE_PX pixels, and the normals one pixel.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np

from volume.fusion import BILATERAL_DIAMETER, SILHOUETTE_PX, scan_maps
from volume.fusion_jit import PackedMaps, empty_records, write_records

#: Pixels of no depth kept around a scan's depth pixels (module docstring: at least the reach
#: of the bilateral filter, of the no-return flag and of the normals, plus one).
FOOTPRINT_MARGIN_PX = max(BILATERAL_DIAMETER // 2, SILHOUETTE_PX, 1) + 2
#: Views whose maps are computed at the same time (numpy / OpenCV release the GIL).
NORMAL_THREADS = 2


def footprint_rect(mask: np.ndarray, margin: int) -> tuple[int, int, int, int]:
    """(x0, y0, w, h) of the bounding box of ``mask`` (H, W) bool grown by ``margin`` pixels and
    clipped to the image; (0, 0, 0, 0) when the mask is empty."""
    m = np.asarray(mask, bool)
    rows = np.flatnonzero(m.any(axis=1))
    if not len(rows):
        return 0, 0, 0, 0
    cols = np.flatnonzero(m.any(axis=0))
    H, W = m.shape
    y0, y1 = max(int(rows[0]) - margin, 0), min(int(rows[-1]) + 1 + margin, H)
    x0, x1 = max(int(cols[0]) - margin, 0), min(int(cols[-1]) + 1 + margin, W)
    return x0, y0, x1 - x0, y1 - y0


def pack_scans(scans, max_grazing_deg: float, smooth_sigma_z: float, threads: int = NORMAL_THREADS,
               progress=None) -> PackedMaps:
    """PackedMaps of every scan's footprint rectangle (module docstring), ``threads`` views at a
    time; equal, voxel for voxel, to ``pack_maps([scan_maps(s) for s in scans])`` in the fusion."""
    scans = list(scans)
    rects = np.array([footprint_rect(s.depth > 0, FOOTPRINT_MARGIN_PX) for s in scans], np.int64).reshape(-1, 4)
    sizes = rects[:, 2] * rects[:, 3]
    start = 1 + np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
    pixel = empty_records(int(sizes.sum()))
    P = np.zeros((len(scans), 3, 4), np.float32)

    def one(i: int) -> int:
        cam = scans[i].camera
        P[i] = cam.K @ cam.cam_from_world[:3, :]
        if sizes[i]:
            m = scan_maps(scans[i], max_grazing_deg, smooth_sigma_z, rect=tuple(rects[i]))
            write_records(pixel[start[i]:start[i] + sizes[i]], m)
        return i

    with ThreadPoolExecutor(max(int(threads), 1)) as pool:
        done = pool.map(one, range(len(scans)))
        for _ in (progress(done, "normals") if progress else done):
            pass
    W = np.array([s.camera.width for s in scans], np.int64)
    H = np.array([s.camera.height for s in scans], np.int64)
    return PackedMaps(pixel, P, start, W, H, rects)


def packed_fraction(pm: PackedMaps) -> float:
    """Records held over the pixels of the full frames (what the footprints save)."""
    full = float(np.sum(pm.W * pm.H))
    return (len(pm.pixel) - 1) / full if full else 0.0

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

from capture.resample import nearest_depth
from capture.scan import Scan
from volume.fusion import BILATERAL_DIAMETER, SILHOUETTE_PX, scan_maps
from volume.fusion_jit import PackedMaps, empty_records, write_records
from volume.rgbz_store import bbox

#: Pixels of no depth kept around a scan's depth pixels (module docstring: at least the reach
#: of the bilateral filter, of the no-return flag and of the normals, plus one).
FOOTPRINT_MARGIN_PX = max(BILATERAL_DIAMETER // 2, SILHOUETTE_PX, 1) + 2
#: Views whose maps are computed at the same time (numpy / OpenCV release the GIL).
NORMAL_THREADS = 2


def footprint_rect(mask: np.ndarray, margin: int) -> tuple[int, int, int, int]:
    """(x0, y0, w, h) of the bounding box of ``mask`` (H, W) bool grown by ``margin`` pixels and
    clipped to the image; (0, 0, 0, 0) when the mask is empty (volume.rgbz_store.bbox)."""
    return bbox(mask, margin)


def native_scale(scanset, oversample: float = 1.0) -> float:
    """The factor (<= 1) from the scans' cameras to ``oversample`` x the size their depth was measured
    at (scan-set metadata ``depth_size``, set when capture.resample brought it up to the colour's);
    1 when the depth is at the colour's size or ``oversample`` is 0.

    A phone's 256x192 depth resampled to 1920x1440 holds 56x more pixels than it measured, and
    fusion maps at the colour's size would hold 32 bytes of record for each of them in the object's
    footprint: 9 GB for 200 frames of a pot plant.  At 2x the measured size (FusionConfig.map_oversample)
    it is 14x less; the bilinear samples between measured ones still help (measured on a torus at
    a quarter of the colour's size: mean |SDF error| 3.4 mm at 2x against 3.1 at the colour's size
    and 3.6 at 1x; tests/volume/test_stream.py)."""
    size = scanset.metadata.get("depth_size")
    if not size or oversample <= 0:
        return 1.0
    return min(1.0, oversample * float(size[0]) / scanset.scans[0].camera.width)


def depth_only_scan(scan, s: float) -> Scan:
    """``scan``'s depth and camera at ``s`` x its size (depth by the nearest pixel, volume.views),
    with no colour: what the fusion maps read."""
    cam = scan.camera.scaled(s)
    return Scan(np.zeros((cam.height, cam.width, 3), np.uint8), nearest_depth(scan.depth, cam.width, cam.height),
                cam, scan.name)


def pack_scans(scans, max_grazing_deg: float, smooth_sigma_z: float, threads: int = NORMAL_THREADS,
               progress=None, scale: float = 1.0) -> PackedMaps:
    """PackedMaps of every scan's footprint rectangle (module docstring), ``threads`` views at a
    time; equal, voxel for voxel, to ``pack_maps([scan_maps(s) for s in scans])`` in the fusion.
    ``scale`` < 1: the maps of each scan's :func:`depth_only_scan` at that scale (:func:`native_scale`)."""
    scans = list(scans)

    def view(i: int):
        return scans[i] if scale >= 1 else depth_only_scan(scans[i], scale)

    cams = [s.camera if scale >= 1 else s.camera.scaled(scale) for s in scans]
    rects = np.array([footprint_rect(view(i).depth > 0, FOOTPRINT_MARGIN_PX) for i in range(len(scans))],
                     np.int64).reshape(-1, 4)
    sizes = rects[:, 2] * rects[:, 3]
    start = 1 + np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
    pixel = empty_records(int(sizes.sum()))
    P = np.zeros((len(scans), 3, 4), np.float32)

    def one(i: int) -> int:
        P[i] = cams[i].K @ cams[i].cam_from_world[:3, :]
        if sizes[i]:
            m = scan_maps(view(i), max_grazing_deg, smooth_sigma_z, rect=tuple(rects[i]))
            write_records(pixel[start[i]:start[i] + sizes[i]], m)
        return i

    with ThreadPoolExecutor(max(int(threads), 1)) as pool:
        done = pool.map(one, range(len(scans)))
        for _ in (progress(done, "normals") if progress else done):
            pass
    W = np.array([c.width for c in cams], np.int64)
    H = np.array([c.height for c in cams], np.int64)
    return PackedMaps(pixel, P, start, W, H, rects)


def packed_fraction(pm: PackedMaps) -> float:
    """Records held over the pixels of the full frames (what the footprints save)."""
    full = float(np.sum(pm.W * pm.H))
    return (len(pm.pixel) - 1) / full if full else 0.0

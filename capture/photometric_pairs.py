"""Correspondences between neighbouring views, pooled per cell (capture.photometric, step 1), view by view.

Each view i is compared with its ``neighbours`` nearest views j by viewing direction
(:func:`neighbour_pairs`): every ``stride``-th usable pixel of i (:func:`usable`) is back-projected
with its depth and looked up in j (:func:`pair_cells`), and the correspondences are pooled per
cell (capture.photometric_cells).  :func:`measure_pairs` runs this as one pass over the views
(:func:`view_pairs`: view i with all its pairs (i, j)) through a ``map_views`` (capture.view_map):
in this process, or in the pipeline's worker processes, with the same pairs in the same order.
A process keeps the usable colour and mask of its last PREP_CACHE_VIEWS views (a view's
neighbours are mostly the views before and after it), never every view's.
"""

from __future__ import annotations

import uuid
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from capture.lens import remap_bilinear
from capture.photometric_cells import CellGrid, cell_ratios
from capture.scan import Scan, srgb_to_linear
from capture.view_map import PerView, or_serial

#: Automatic sampling stride: one step per this many pixels of the shorter image side.
AUTO_STRIDE_PX = 240
#: usable() on the box of the view's depth pixels (the same mask; tests/capture/test_photometric_pairs.py),
#: else on the whole frame (the reference).
USABLE_BOX = True
#: Views whose linear colour and usable mask a process keeps while the pairs are measured.
PREP_CACHE_VIEWS = 8

#: This process's usable colour and masks: (measurement, view) -> (linear colour, usable mask).
_PREP: OrderedDict = OrderedDict()


def usable(scan: Scan, cfg, boxed: bool | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(linear colour (H, W, 3) float32, (H, W) bool usable samples) of a view (``cfg``: PhotometricConfig).
    ``boxed`` (default USABLE_BOX): the tests run on the box of the depth's pixels grown by one pixel (the
    3 x 3 windows of every depth pixel inside it; none outside is usable), else on the whole frame."""
    import cv2

    lin = np.asarray(scan.linear_rgb, np.float32)
    if USABLE_BOX if boxed is None else boxed:
        ok = np.zeros(scan.depth.shape, bool)
        x, y, w, h = cv2.boundingRect((scan.depth > 0).view(np.uint8))
        if w and h:
            H, W = ok.shape
            box = (slice(max(0, y - 1), min(H, y + h + 1)), slice(max(0, x - 1), min(W, x + w + 1)))
            ok[box] = _usable_at(scan.depth[box], lin[box], None if scan.alpha is None else scan.alpha[box], cfg)
        return lin, ok
    return lin, _usable_at(scan.depth, lin, scan.alpha, cfg)


def _usable_at(d: np.ndarray, lin: np.ndarray, alpha: np.ndarray | None, cfg) -> np.ndarray:
    """:func:`usable`'s mask of depth ``d``, colour ``lin`` and matte ``alpha`` (or None)."""
    import cv2

    d = np.ascontiguousarray(d)
    hi = cv2.dilate(d, np.ones((3, 3), np.uint8))
    lo = cv2.erode(np.where(d > 0, d, np.inf).astype(np.float32), np.ones((3, 3), np.uint8))
    ok = (d > 0) & np.isfinite(lo) & (hi - lo <= cfg.edge_tol * d)
    ok &= np.all(lin <= srgb_to_linear(np.float32(cfg.max_srgb)), axis=2)
    if alpha is not None:
        ok &= alpha >= cfg.min_alpha
    return ok


def _prep(token: str, k: int, scan, cfg):
    """:func:`usable` of view ``k`` of measurement ``token``, from this process's cache when there."""
    key = (token, k)
    if key in _PREP:
        _PREP.move_to_end(key)
        return _PREP[key]
    if _PREP and next(iter(_PREP))[0] != token:
        _PREP.clear()  # a new measurement: the last one's views are done with
    _PREP[key] = usable(scan, cfg)
    while len(_PREP) > PREP_CACHE_VIEWS:
        _PREP.popitem(last=False)
    return _PREP[key]


def pair_cells(si: Scan, sj: Scan, prep_i, prep_j, cfg, grid: CellGrid):
    """(cells (M,) int64, log ratios (M, 3) ``log c_j - log c_i`` of the cells (capture.photometric_cells.cell_ratios),
    correspondences (M,) int) of view i's samples seen again by view j (capture.photometric, step 1)."""
    lin_i, ok_i = prep_i
    lin_j, ok_j = prep_j
    none = (np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros(0, np.int64))
    step = cfg.stride or max(1, min(ok_i.shape) // AUTO_STRIDE_PX)
    vv, uu = np.nonzero(ok_i[::step, ::step])
    vv, uu = vv * step, uu * step
    if len(uu) == 0:
        return none
    pts = si.camera.unproject(np.stack([uu, vv], axis=1).astype(np.float64), si.depth[vv, uu].astype(np.float64))
    pix, z = sj.camera.project(pts)
    depth_j = sj.depth
    H, W = depth_j.shape
    with np.errstate(invalid="ignore"):
        ni = np.floor(np.nan_to_num(pix, nan=-1.0) + 0.5).astype(np.int64)
    inb = (z > 0) & (ni[:, 0] >= 0) & (ni[:, 0] < W) & (ni[:, 1] >= 0) & (ni[:, 1] < H)
    pts, pix, ni, z, vv, uu = pts[inb], pix[inb], ni[inb], z[inb], vv[inb], uu[inb]
    agree = ok_j[ni[:, 1], ni[:, 0]] & (np.abs(depth_j[ni[:, 1], ni[:, 0]] - z) <= cfg.depth_tol * z)
    if agree.sum() < cfg.min_samples:
        return none
    keys, inv, cnt = np.unique(grid.keys(pts[agree]), return_inverse=True, return_counts=True)
    uvj = np.clip(pix[agree], 0, [W - 1, H - 1]).astype(np.float32)
    cj = remap_bilinear(lin_j, uvj[:, :1], uvj[:, 1:]).reshape(-1, 3)
    d = cell_ratios(lin_i[vv[agree], uu[agree]], cj, inv, len(keys), cfg.cell_trim)
    ok = (cnt >= cfg.min_cell_samples) & np.all(np.isfinite(d), axis=1)
    return keys[ok], d[ok], cnt[ok]


def neighbour_pairs(scans, cfg) -> list[tuple[int, int]]:
    """(i, j) ordered pairs: each view with its ``neighbours`` nearest views by viewing direction."""
    fwd = np.stack([s.camera.forward for s in scans])
    cos = np.clip(fwd @ fwd.T, -1, 1)
    np.fill_diagonal(cos, -np.inf)
    lim = np.cos(np.radians(cfg.max_angle_deg))
    pairs = set()
    for i in range(len(scans)):
        for j in np.argsort(-cos[i])[:cfg.neighbours]:
            if cos[i, j] >= lim:
                pairs.add((i, int(j)))
    return sorted(pairs)


@dataclass(frozen=True)
class PairCells:
    """One compared pair: views ``i``, ``j``; its cells' flat indices (M,), log ratios ``d`` (M, 3)
    (log c_j - log c_i) and correspondences per cell (M,)."""

    i: int
    j: int
    cells: np.ndarray
    d: np.ndarray
    samples: np.ndarray


def view_pairs(scan, i: int, arg) -> tuple[None, list[PairCells]]:
    """Per view i (``arg``: (PhotometricConfig, CellGrid, measurement token, [(j, scan j)] in order)):
    its pairs (i, j) with at least ``min_cells`` cells."""
    cfg, grid, token, others = arg
    out = []
    for j, sj in others:
        cells, d, n = pair_cells(scan, sj, _prep(token, i, scan, cfg), _prep(token, j, sj, cfg), cfg, grid)
        if len(cells) >= cfg.min_cells:
            out.append(PairCells(i, j, cells, d, n))
    return None, out


def measure_pairs(scans, cfg, grid: CellGrid, progress=None, map_views=None) -> list[PairCells]:
    """Every neighbour pair with at least ``min_cells`` cells (steps 1-2's data), in (i, j) order,
    view i by view i through ``map_views`` (capture.view_map; default: this process)."""
    scans = list(scans)
    pairs = neighbour_pairs(scans, cfg)
    token = uuid.uuid4().hex
    per_view = [[] for _ in scans]
    for i, j in pairs:
        per_view[i].append((j, scans[j]))
    map_views = or_serial(map_views, progress=progress)
    arg = PerView((cfg, grid, token, tuple(others)) for others in per_view)
    try:
        notes = map_views(view_pairs, scans, arg, "photometric pairs")[1]
    finally:
        _PREP.clear()
    return [p for note in notes for p in note]

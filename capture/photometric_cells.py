"""Correspondences pooled per cell (capture.photometric, step 1): the cube of cells over the object
and the ratio of two views' colours over a cell's corresponding samples.

Fur and needles do not correspond pixel to pixel between views -- a strand in one view is a gap or
another strand in the next -- so a ratio of two pixels says little about the views' exposures.
Pooled over a cell of the object (many strands), the texture averages out and what is left is the
gain between the views and the cell's view-dependent appearance (which capture.photometric
separates from exposure, and capture.photometric_check judges).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Rec. 709 luminance weights (the order of a cell's samples).
LUMA = np.array([0.2126, 0.7152, 0.0722])
#: Floor of a sample's luminance when a cell's samples are ordered by their ratio, as a fraction of
#: the cell's mean luminance in that view (dark samples do not decide the order).
CELL_FLOOR = 0.05
#: Without bounds, the cube of the cells is the box of the views' depth points between these
#: percentiles, sampled every BOUNDS_STRIDE-th pixel, padded by BOUNDS_PAD of its size.
BOUNDS_PERCENTILES = (1.0, 99.0)
BOUNDS_STRIDE = 8
BOUNDS_PAD = 0.05


@dataclass(frozen=True)
class CellGrid:
    """The cube the correspondences are pooled in: ``origin`` (3,) metres of its minimum corner,
    ``cell`` the edge of one cell (metres), ``res`` cells per side."""

    origin: np.ndarray
    cell: float
    res: int

    def keys(self, points: np.ndarray) -> np.ndarray:
        """(N,) int64 flat cell index (i * res + j) * res + k of world points (N, 3), clamped to the cube."""
        ijk = np.clip(np.floor((np.asarray(points) - self.origin) / self.cell).astype(np.int64), 0, self.res - 1)
        return (ijk[:, 0] * self.res + ijk[:, 1]) * self.res + ijk[:, 2]


def depth_points_view(s, k, arg):
    """Per view: (world points (n, 3), their depths (n,), focal length) of every BOUNDS_STRIDE-th pixel."""
    d = s.depth[::BOUNDS_STRIDE, ::BOUNDS_STRIDE]
    vv, uu = np.nonzero(d > 0)
    uv = np.stack([uu, vv], 1).astype(np.float64) * BOUNDS_STRIDE
    return None, (s.camera.unproject(uv, d[vv, uu].astype(np.float64)), d[vv, uu].astype(np.float64),
                  float(np.sqrt(s.camera.K[0, 0] * s.camera.K[1, 1])))


def _depth_points(scans, map_views=None):
    """(world points (N, 3), their depths (N,), focal lengths (V,)) of every BOUNDS_STRIDE-th pixel."""
    from capture.view_map import or_serial

    per_view = or_serial(map_views)(depth_points_view, list(scans), None, "photometric cells")[1]
    focal = np.asarray([f for _, _, f in per_view])
    pts = [p for p, _, _ in per_view if len(p)]
    if not pts:
        return np.zeros((0, 3)), np.zeros(0), focal
    return np.concatenate(pts), np.concatenate([d for _, d, _ in per_view if len(d)]), focal


def cell_grid(scans, res: int, bounds=None, min_px: float = 0.0, map_views=None) -> CellGrid:
    """The cube of at most ``res``^3 cells over the box of the views' depth points (BOUNDS_PERCENTILES, every
    BOUNDS_STRIDE-th pixel, padded BOUNDS_PAD) within ``bounds`` ((2, 3) metres, or None); fewer
    cells when a cell would be narrower than ``min_px`` pixels at the views' median depth (small images:
    a cell must hold samples enough to average).  The views' points through ``map_views`` (capture.view_map)."""
    pts, dep, focal = _depth_points(scans, map_views)
    if len(pts):
        lo, hi = np.percentile(pts, BOUNDS_PERCENTILES, axis=0)
        pad = BOUNDS_PAD * (hi - lo).max()
        box = np.stack([lo - pad, hi + pad])
        if bounds is not None:   # within the given bounds (they may be loose), where the views measured
            b = np.asarray(bounds, np.float64)
            box = np.stack([np.maximum(box[0], b[0]), np.minimum(box[1], b[1])])
            if np.any(box[1] <= box[0]):
                box = b
        bounds = box
    elif bounds is None:
        return CellGrid(np.zeros(3), 1.0, 1)
    b = np.asarray(bounds, np.float64)
    side = max(float((b[1] - b[0]).max()), 1e-9)
    if len(dep) and min_px > 0:
        res = max(1, min(int(res), int(side / (min_px * np.median(dep) / np.median(focal)))))
    return CellGrid(b[0] - (side - (b[1] - b[0])) / 2, side / res, int(res))


def cell_ratios(ci: np.ndarray, cj: np.ndarray, group: np.ndarray, n_groups: int, trim: float) -> np.ndarray:
    """(n_groups, 3) per group of corresponding samples (colours ``ci``, ``cj`` (N, 3) linear; ``group``
    (N,) in [0, n_groups)) the log ratio of sums log sum cj - log sum ci over the samples left after
    cutting ``trim`` of the group's samples off each end of the order of their luminance ratio (ranked
    with a floor of CELL_FLOOR x each view's group mean, so it scales with the view).  The same samples
    leave both sums: exact when cj = g ci, unbiased when the two are exchangeable up to g (strands that
    do not correspond), blind to a sample bright in one view only (a glint).  NaN where a sum is 0."""
    g = np.asarray(group, np.int64)
    li, lj = np.asarray(ci, np.float64) @ LUMA, np.asarray(cj, np.float64) @ LUMA
    n = np.bincount(g, minlength=n_groups)
    fi = CELL_FLOOR * np.bincount(g, li, n_groups) / np.maximum(n, 1)
    fj = CELL_FLOOR * np.bincount(g, lj, n_groups) / np.maximum(n, 1)
    r = np.log((lj + fj[g] + 1e-30) / (li + fi[g] + 1e-30))
    order = np.lexsort((r, g))
    gs = g[order]
    rank = np.arange(len(gs)) - np.concatenate([[0], np.cumsum(n)[:-1]])[gs]
    cut = np.minimum(np.floor(trim * n).astype(np.int64), (n - 1) // 2)
    keep = order[(rank >= cut[gs]) & (rank < (n - cut)[gs])]
    si = np.stack([np.bincount(g[keep], ci[keep, c], n_groups) for c in range(3)], 1)
    sj = np.stack([np.bincount(g[keep], cj[keep, c], n_groups) for c in range(3)], 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where((si > 0) & (sj > 0), np.log(sj) - np.log(si), np.nan)

"""Photometric alignment of the views: a per-view, per-channel gain in linear light.

Phones and RGB-D cameras choose exposure and white balance anew for every frame, so the same
surface point has a different colour in every view; blending such views mixes exposures.  Here
each view's colour is modelled as ``c_i = c / g_i`` (a gain per channel, linear light) and the
correction ``g_i`` is estimated from what neighbouring views see of the same surface:

1. **Correspondences, pooled per cell.**  Every ``stride``-th measured pixel of view i is
   back-projected with its depth and looked up (bilinear) in each of its nearest views j (by
   viewing direction); it counts when j measures the same depth there (relative ``depth_tol``),
   neither colour is clipped, the depth is smooth around it in view i (no silhouette edge,
   ``edge_tol``) and, when a matte is known, both pixels are opaque.  Fur and needles do not
   correspond pixel to pixel between views (a strand in one view is a gap in the other), so no
   pixel ratio is used: the correspondences are pooled per cell of a ``cell_res``^3 cube over the
   object, and each cell gives one ratio of the two views' sums over its samples, the ``cell_trim``
   most extreme samples (by their ratio: sheen, glints, occlusions) left out of both
   (:func:`cell_ratios`): the strand texture averages out, the gain stays.
2. **Pair ratios.**  For every pair, per channel, a robust location of the cells' ``log c_j -
   log c_i`` (median, then Huber IRLS steps) and its weight (cells / robust variance).
3. **Joint solve.**  ``x_i - x_j = d_ij`` (x = log gain) over all pairs, weighted least squares
   with Huber re-weighting of the pair residuals, all channels at once; the gauge (the one
   global gain no view can tell) is fixed afterwards: ``mean`` (default) puts the mean of the views'
   log gains at 0 in every channel (an auto-exposure camera's jitter is about zero-mean in log, and
   the mean estimates its level with less spread than the median: docs/real_cameras.md, stop 65),
   ``median`` the median view's gain at 1, a view name fixes that view.
4. **Appearance is not exposure.**  Fur and needles look different from different directions
   (sheen and hair lobes of the lights, a patterned coat seen along or across its stripes): on a
   fur ball at fixed exposure under a studio's lamps the solve of step 3 finds "gains" of +-0.5 EV
   that are appearance.  Such changes change the colour too (a white sheen on ginger fur, more of
   the dark stripes), an exposure does not (white balance jitter aside, which is independent of
   it).  So (``appearance`` "colour", the default, :func:`colour_appearance_part`) each view's EV is
   predicted from its chromatic change by the relation the other views show; that part is appearance
   and is left in (nothing unless the colour predicts beyond chance: 1 % of shuffled colours do
   better).  With appearance found, only one exposure per view is corrected; without, exposure and
   white balance (capture.photometric_appearance).
   ``appearance`` "smooth" instead keeps what changes smoothly with the viewing direction
   (:func:`exposure_part`), "none" takes every difference for exposure.
5. **Shown to help, or not applied** (capture.photometric_check): the gains are estimated without
   each fold of held-back cells and judged on it; no alignment, one exposure per view, or exposure
   and white balance, whichever is simplest within ``check_z`` standard errors of the best.

Views with no usable pair keep gain 1 (and are listed).  Everything is numpy over arrays of the
scans; :func:`apply_gains` returns the scans with corrected colour (8-bit sRGB stays 8-bit).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from capture.photometric_appearance import APPEARANCE_QUANTILE, colour_appearance_part, exposure_part
from capture.photometric_cells import cell_grid
from capture.photometric_pairs import AUTO_STRIDE_PX, PairCells, measure_pairs
from capture.scan import Scan, to_uint8_srgb
from capture.scan_store import SpilledScan
from capture.view_map import PerView, or_serial

#: Gauge choices besides a view name.
GAUGES = ("median", "mean")
#: A spilled view with float32 colour (a matted foreground) gets its gains as a factor applied on each
#: read (capture.scan_store.SpilledScan.with_gain: the same products) instead of its colour written to
#: the spill folder again: 72 views at 1280x960 wrote 17 MB a view here, the sys time of the page
#: cache (docs/speed.md, round 13).  False: every changed view written (:func:`gain_view`'s reference).
GAINS_ON_READ = True
#: MAD -> standard deviation of a normal distribution.
MAD_TO_SIGMA = 1.4826
#: Huber IRLS steps (pair locations and the joint solve).
IRLS_STEPS = 6
#: Floor of a pair's robust standard deviation (log units): keeps one very consistent pair from
#: dominating the solve.
SIGMA_FLOOR = 0.01
#: How appearance is told from exposure (PhotometricConfig.appearance).
APPEARANCE_MODES = ("auto", "colour", "smooth", "none")
#: Systematic error of a pair's ratio (log units: view-dependent shading that does not average
#: out over its cells), added in quadrature to its statistical error.
PAIR_BIAS = 0.01
#: Weight of the temporary sum-to-zero row that makes the joint system full rank.
GAUGE_ROW_WEIGHT = 1e3


@dataclass(frozen=True)
class PhotometricConfig:
    """Photometric alignment of the views (module docstring)."""

    neighbours: int = 4
    """Views each view is compared with (nearest by viewing direction)."""
    max_angle_deg: float = 75.0
    """Largest angle between the viewing directions of a compared pair (degrees)."""
    stride: int = 0
    """Sample every stride-th pixel (each axis) of each view; 0 = one per :data:`AUTO_STRIDE_PX` of
    the shorter image side (2 at 640x480, 1 for small images)."""
    depth_tol: float = 0.02
    """Depth agreement of a correspondence, relative to its depth."""
    edge_tol: float = 0.2
    """A sample's 3x3 depth range must stay within this fraction of its depth (no silhouette edge).  Fur's
    depth jumps strand to strand: at 0.05 (issue 21) 8 % of a path-traced fur ball's opaque pixels were left
    and 6 pairs of 72 counted; the depth agreement of a correspondence guards the rest."""
    max_srgb: float = 250 / 255
    """Brightest sRGB value of a usable sample (every channel, in both views): brighter may be clipped."""
    min_alpha: float = 0.5
    """Smallest matte alpha of a usable sample (in both views).  At 0.999 (before stop 65) a conifer over
    black gave no pair at all (no needle pixel is opaque in two views) and kept its views' auto-exposure
    jitter; at 0.5 its per-view EV error was 0.03 against a spread of 0.30 (docs/real_cameras.md)."""
    min_samples: int = 100
    """Correspondences a pair needs to count."""
    cell_res: int = 16
    """Cells per side of the cube the correspondences are pooled in (the capture's bounds): a cell
    holds many strands, so their texture averages out, and little enough of the shading to compare."""
    cell_min_px: float = 4.0
    """...but a cell is at least this many sample steps wide at the views' median depth (fewer cells on
    small images, so that each holds samples enough)."""
    cell_trim: float = 0.2
    """Share of a cell's samples cut off at each end of the order of their ratio (sheen, glints)."""
    min_cell_samples: int = 8
    """Correspondences a cell needs in a pair."""
    min_cells: int = 4
    """Cells a pair needs to count."""
    huber: float = 1.0
    """Huber threshold in robust standard deviations (pair locations and the joint solve)."""
    reference: str = "mean"
    """Gauge: ``mean`` (the mean of the views' log gains at 0), ``median`` or the name of the view whose
    colour is kept."""
    appearance: str = "auto"
    """How view-dependent appearance is told from exposure (module docstring, step 4): ``auto`` (colour,
    else smoothness, each only beyond chance), ``colour``, ``smooth`` (issue 21's, no chance test) or ``none``."""
    appearance_deg: float = 30.0
    """``smooth``: correlation angle of view-dependent appearance between viewing directions (degrees)."""
    check: bool = True
    """Apply the gains only when held-back cells show they help (capture.photometric_check); False =
    apply whatever was estimated."""
    check_folds: int = 4
    """Folds of the check (blocks of cells held back in turn)."""
    background: str = "auto"
    """'auto': gains the cells took are refused where the background rings do not show them
    (capture.photometric_background; asked only where the plate's exposure check took none); 'off': not asked."""
    check_z: float = 2.0
    """A more complex correction (exposure, then exposure and white balance) is applied only when it
    beats the simpler one on the held-back cells by more than this many standard errors."""

    def __post_init__(self) -> None:
        if self.neighbours < 1 or self.stride < 0 or self.min_samples < 1 or self.min_cells < 1:
            raise ValueError("photometric: neighbours, min_samples and min_cells must be >= 1, stride >= 0")
        if not all(0 < v < 1 for v in (self.depth_tol, self.edge_tol)) or not 0 < self.max_srgb <= 1:
            raise ValueError("photometric: depth_tol and edge_tol must be in (0, 1), max_srgb in (0, 1]")
        if not 0 < self.min_alpha <= 1:
            raise ValueError(f"photometric: min_alpha must be in (0, 1], got {self.min_alpha}")
        if self.cell_res < 1 or self.min_cell_samples < 1 or not 0 <= self.cell_trim < 0.5:
            raise ValueError("photometric: cell_res and min_cell_samples must be >= 1, cell_trim in [0, 0.5)")
        if self.appearance not in APPEARANCE_MODES or not self.appearance_deg > 0:
            raise ValueError(f"photometric: appearance must be one of {APPEARANCE_MODES}, appearance_deg > 0")
        if self.check_folds < 2 or not self.check_z >= 0:
            raise ValueError("photometric: check_folds must be >= 2 and check_z >= 0")
        if self.background not in ("auto", "off"):
            raise ValueError(f"photometric: background must be 'auto' or 'off', got {self.background!r}")


@dataclass(frozen=True)
class PhotometricResult:
    """Per-view colour corrections.

    Attributes:
        names: (V,) view names.
        gains: (V, 3) float64 linear multipliers applied to each view's colour (1 = unchanged).
        pairs: number of view pairs used.
        samples: correspondences used in all.
        unaligned: names of views with no usable pair (gain 1).
        reference: the gauge used (``median``, ``mean`` or a view name).
        residual: median absolute pair residual after the solve (log units).
        meta: JSON-able extras (``appearance``: how it was told apart (colour, smooth, none);
            ``appearance_share`` (colour): the share of the
            EV spread taken for appearance, ``appearance_to_exposure`` (smooth): the variance ratio of
            exposure_part; ``cells``: cell ratios used; ``check``: the held-back check,
            capture.photometric_check).
    """

    names: tuple[str, ...]
    gains: np.ndarray
    pairs: int
    samples: int
    unaligned: tuple[str, ...] = ()
    reference: str = "mean"
    residual: float = 0.0
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        g = np.asarray(self.gains, np.float64)
        if g.shape != (len(self.names), 3) or not np.all(np.isfinite(g)) or np.any(g <= 0):
            raise ValueError(f"photometric gains must be ({len(self.names)}, 3) positive finite, got {g.shape}")
        object.__setattr__(self, "gains", g)

    @property
    def ev(self) -> np.ndarray:
        """(V,) exposure correction in EV (stops): the mean over channels of log2 gain."""
        return np.log2(self.gains).mean(axis=1)

    @property
    def white_balance(self) -> np.ndarray:
        """(V, 3) per-channel gains left after the exposure (geometric mean 1)."""
        return self.gains / np.exp2(self.ev)[:, None]

    def record(self) -> dict:
        """JSON-able record (model.json params / the model report)."""
        return {"reference": self.reference, "pairs": self.pairs, "samples": self.samples,
                "residual_log": round(float(self.residual), 6), "unaligned": list(self.unaligned),
                **{k: (round(v, 6) if isinstance(v, float) else v) for k, v in self.meta.items()},
                "views": [{"name": n, "gain": [round(float(x), 6) for x in g], "ev": round(float(e), 5),
                           "wb": [round(float(x), 5) for x in w]}
                          for n, g, e, w in zip(self.names, self.gains, self.ev, self.white_balance, strict=True)]}


def identity(scans) -> PhotometricResult:
    """No correction (``--no-photometric``)."""
    return PhotometricResult(tuple(s.name for s in scans), np.ones((len(scans), 3)), 0, 0, reference="off")


def robust_location(r: np.ndarray, huber: float) -> tuple[np.ndarray, np.ndarray]:
    """Per column of (N, C) ``r``: (Huber M-estimate of the location, robust sigma)."""
    mu = np.median(r, axis=0)
    sigma = MAD_TO_SIGMA * np.median(np.abs(r - mu), axis=0) + SIGMA_FLOOR
    for _ in range(IRLS_STEPS):
        a = np.abs(r - mu) / (huber * sigma)
        w = np.where(a <= 1, 1.0, 1.0 / np.maximum(a, 1e-12))
        mu = (w * r).sum(axis=0) / w.sum(axis=0)
    return mu, sigma


# --------------------------------------------------------------------------- solve
def pair_edges(pairs: list[PairCells], huber: float, use=None) -> list:
    """Edges (i, j, d_ij (3,), sigma_ij (3,)) of the pairs: the robust location of their cells' ratios
    (only the cells where ``use[k]`` (M,) bool is set, for pair k; pairs left with fewer than 2 drop)."""
    edges = []
    for k, p in enumerate(pairs):
        d = p.d if use is None else p.d[use[k]]
        if len(d) < 2:
            continue
        mu, sigma = robust_location(d, huber)
        edges.append((p.i, p.j, mu, np.sqrt(sigma ** 2 / len(d) + PAIR_BIAS ** 2)))
    return edges


def solve_gains(n_views: int, edges: list[tuple[int, int, np.ndarray, np.ndarray]], huber: float):
    """Log gains x (V, 3) from edges (i, j, d_ij (3,), sigma_ij (3,)) meaning x_i - x_j = d_ij,
    sum of x = 0 per channel; Huber IRLS on the normalised residuals.  Returns (x, |residual| median)."""
    E = len(edges)
    A = np.zeros((E + 1, n_views))
    for e, (i, j, _, _) in enumerate(edges):
        A[e, i], A[e, j] = 1.0, -1.0
    A[E, :] = GAUGE_ROW_WEIGHT
    d = np.array([e[2] for e in edges]).reshape(E, 3)
    s = np.array([e[3] for e in edges]).reshape(E, 3)
    x = np.zeros((n_views, 3))
    robust = np.ones((E, 3))
    for _ in range(IRLS_STEPS):
        for c in range(3):
            w = np.sqrt(np.append(robust[:, c] / s[:, c] ** 2, 1.0))
            b = np.append(d[:, c], 0.0)
            x[:, c] = np.linalg.lstsq(A * w[:, None], b * w, rcond=None)[0]
        res = (A[:E] @ x - d) / s
        a = np.abs(res) / huber
        robust = np.where(a <= 1, 1.0, 1.0 / np.maximum(a, 1e-12))
    return x, float(np.median(np.abs(A[:E] @ x - d))) if E else 0.0


def _connected(n: int, edges) -> np.ndarray:
    """(V,) bool: views joined by at least one edge."""
    seen = np.zeros(n, bool)
    for i, j, *_ in edges:
        seen[i] = seen[j] = True
    return seen


def log_gains(n_views: int, pairs: list[PairCells], forward: np.ndarray, cfg: PhotometricConfig, use=None):
    """(x (V, 3) log gains, 0 for unlinked views; edges; |residual| median; (how appearance was told apart:
    colour, smooth or none; the share of the EV spread taken for it, or the variance ratio)): steps 2-4 on
    the pairs' cells (``use``: see :func:`pair_edges`)."""
    edges = pair_edges(pairs, cfg.huber, use)
    if not edges:
        return np.zeros((n_views, 3)), edges, 0.0, ("none", 0.0)
    x, resid = solve_gains(n_views, edges, cfg.huber)
    linked = _connected(n_views, edges)
    app, how = 0.0, "none"
    if cfg.appearance in ("auto", "colour"):
        x, app = colour_appearance_part(x, linked)
        how = "colour" if app else how
    if cfg.appearance == "smooth" or (cfg.appearance == "auto" and not app):
        chance = APPEARANCE_QUANTILE if cfg.appearance == "auto" else None
        x, app = exposure_part(x, forward, cfg.appearance_deg, chance)
        how = "smooth" if app else how
    x[~linked] = 0.0
    return x, edges, resid, (how, app)


def _gauge(x: np.ndarray, linked: np.ndarray, reference: str, names) -> np.ndarray:
    """Log gains with the gauge fixed (module docstring, step 3); unlinked views keep 0."""
    x = np.where(linked[:, None], x, np.nan)
    if not linked.any():
        return np.zeros_like(x)
    if reference == "median":
        x = x - np.nanmedian(x, axis=0)
    elif reference == "mean":
        x = x - np.nanmean(x, axis=0)
    else:   # a named view that is not linked keeps its colour; so does everything relative to it
        x = x - np.nan_to_num(x[list(names).index(reference)], nan=0.0)
    return np.nan_to_num(x, nan=0.0)


def estimate_gains(scans, cfg: PhotometricConfig | None = None, progress=None, bounds=None,
                   map_views=None) -> PhotometricResult:
    """Per-view gains of ``scans`` (module docstring); ``bounds`` (2, 3) metres: the cube of the cells
    (default: from the views' depth); ``map_views``: the passes over the views (capture.view_map;
    default: in this process)."""
    from capture.photometric_check import check_alignment

    cfg = cfg or PhotometricConfig()
    scans = list(scans)
    names = tuple(s.name for s in scans)
    if cfg.reference not in GAUGES and cfg.reference not in names:
        raise ValueError(f"photometric reference {cfg.reference!r} is neither {' nor '.join(GAUGES)} nor a view name "
                         f"(views: {', '.join(names[:6])}{', ...' if len(names) > 6 else ''})")
    step = cfg.stride or max(1, min(scans[0].depth.shape) // AUTO_STRIDE_PX) if scans else 1
    grid = cell_grid(scans, cfg.cell_res, bounds, cfg.cell_min_px * step, map_views)
    pairs = measure_pairs(scans, cfg, grid, progress, map_views)
    forward = np.stack([s.camera.forward for s in scans])
    x, edges, resid, app = log_gains(len(scans), pairs, forward, cfg)
    linked = _connected(len(scans), edges)
    meta = {"appearance": app[0], "cells": int(sum(len(p.cells) for p in pairs)),
            ("appearance_to_exposure" if app[0] == "smooth" else "appearance_share"): app[1]}
    if cfg.check and edges:
        check = check_alignment(len(scans), pairs, forward, cfg, grid)
        x = check.apply(x)
        meta["check"] = check.record()
    x = _gauge(x, linked, cfg.reference, names)
    return PhotometricResult(names, np.exp(x), len(edges), int(sum(int(p.samples.sum()) for p in pairs)),
                             tuple(n for n, k in zip(names, linked) if not k), cfg.reference, resid, meta)


def gain_view(scan, k, g: np.ndarray):
    """Per view: the scan with its linear colour times ``g`` (3,) (8-bit sRGB stays 8-bit, re-encoded
    and clipped; float linear stays float), or None when ``g`` is exactly 1."""
    if np.all(g == 1.0):
        return None, None
    if GAINS_ON_READ and isinstance(scan, SpilledScan) and scan.rgb_dtype == np.float32:
        return scan.with_gain(g.astype(np.float32)), None
    lin = scan.linear_rgb * g.astype(np.float32)
    rgb = to_uint8_srgb(lin) if scan.rgb.dtype == np.uint8 else lin.astype(np.float32)
    return Scan(rgb, scan.depth, scan.camera, scan.name, scan.alpha), None


def apply_gains(scans, gains: np.ndarray, keep=None, map_views=None) -> tuple[Scan, ...]:
    """The scans with their linear colour multiplied by ``gains`` (V, 3) (:func:`gain_view`; a view with
    gain exactly 1 is untouched), through ``map_views`` (capture.view_map; default: in this process,
    ``keep`` taking each new scan: capture.scan_store)."""
    g = np.asarray(gains, np.float64)
    return or_serial(map_views, keep)(gain_view, list(scans), PerView(tuple(g)), "photometric gains")[0]

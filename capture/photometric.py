"""Photometric alignment of the views: a per-view, per-channel gain in linear light.

Phones and RGB-D cameras choose exposure and white balance anew for every frame, so the same
surface point has a different colour in every view; blending such views mixes exposures.  Here
each view's colour is modelled as ``c_i = c / g_i`` (a gain per channel, linear light) and the
correction ``g_i`` is estimated from what neighbouring views see of the same surface points:

1. **Correspondences.**  Every ``stride``-th measured pixel of view i is back-projected with its
   depth and projected into each of its nearest views j (by viewing direction); it counts when
   j measures the same depth there (relative ``depth_tol``), both colours are neither dark
   (quantisation dominates the log) nor clipped, the depth is smooth around it in view i (no
   silhouette edge, ``edge_tol``) and, when a matte is known, both pixels are opaque.
2. **Pair ratios.**  For every pair, per channel, a robust location of ``log c_j - log c_i``
   (median, then Huber IRLS steps) and its weight (samples / robust variance): fur, glints and
   occlusion edges are view-dependent outliers, and the median over thousands of samples ignores
   them.
3. **Joint solve.**  ``x_i - x_j = d_ij`` (x = log gain) over all pairs, weighted least squares
   with Huber re-weighting of the pair residuals, all channels at once; the gauge (the one
   global gain no view can tell) is fixed afterwards: ``median`` (default) puts the median view's
   gain of every channel at 1 (the median of the log gains over views, per channel), ``mean``
   the mean, a view name fixes that view.
4. **Appearance is not exposure.**  Fur and needles look different from different directions
   (lit and unlit sides, hair lobes): on a fur ball at fixed exposure the solve of step 3 finds
   "gains" of +-0.5 EV that are real appearance, and applying them cost 0.5 dB held-out.  Exposure
   jumps independently from view to view; appearance changes smoothly with the viewing direction.
   :func:`exposure_part` splits the solved log gains into the two by maximum likelihood of their
   variances and keeps only the independent part (``appearance_deg``; 0 = off).

Views with no usable pair keep gain 1 (and are listed).  Everything is numpy over arrays of the
scans; :func:`apply_gains` returns the scans with corrected colour (8-bit sRGB stays 8-bit).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from capture.scan import Scan, srgb_to_linear, to_uint8_srgb
from capture.scan_store import keep_in_memory

#: Gauge choices besides a view name.
GAUGES = ("median", "mean")
#: MAD -> standard deviation of a normal distribution.
MAD_TO_SIGMA = 1.4826
#: Huber IRLS steps (pair locations and the joint solve).
IRLS_STEPS = 6
#: Floor of a pair's robust standard deviation (log units): keeps one very consistent pair from
#: dominating the solve.
SIGMA_FLOOR = 0.01
#: Automatic sampling stride: one step per this many pixels of the shorter image side.
AUTO_STRIDE_PX = 240
#: Ratios (appearance variance / exposure variance) tried by :func:`exposure_part`.
APPEARANCE_RATIOS = np.logspace(-3, 4, 29)
#: Systematic error of a pair's ratio (log units: view-dependent shading that does not average
#: out over its samples), added in quadrature to its statistical error.
PAIR_BIAS = 0.01
#: Weight of the temporary sum-to-zero row that makes the joint system full rank.
GAUGE_ROW_WEIGHT = 1e3
#: Views whose linear colour and usable mask stay in memory while the pairs are measured.
PREP_CACHE_VIEWS = 8


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
    edge_tol: float = 0.05
    """A sample's 3x3 depth range must stay within this fraction of its depth (no silhouette edge)."""
    min_linear: float = 0.004
    """Darkest linear value of a usable sample (every channel)."""
    max_srgb: float = 250 / 255
    """Brightest sRGB value of a usable sample (every channel): brighter may be clipped."""
    min_samples: int = 100
    """Correspondences a pair needs to count."""
    huber: float = 1.0
    """Huber threshold in robust standard deviations (pair locations and the joint solve)."""
    reference: str = "median"
    """Gauge: ``median``, ``mean`` or the name of the view whose colour is kept."""
    appearance_deg: float = 30.0
    """Correlation angle of view-dependent appearance between viewing directions (degrees), which
    separates it from per-view exposure (:func:`exposure_part`); 0 = take every difference between
    views for exposure."""
    affine: bool = False
    """Reserved: only the per-channel gain is estimated (an offset was not worth it, see the report)."""

    def __post_init__(self) -> None:
        if self.neighbours < 1 or self.stride < 0 or self.min_samples < 1:
            raise ValueError("photometric: neighbours and min_samples must be >= 1, stride >= 0")
        if not all(0 < v < 1 for v in (self.depth_tol, self.edge_tol, self.min_linear)) or not 0 < self.max_srgb <= 1:
            raise ValueError("photometric: depth_tol, edge_tol, min_linear and max_srgb must be in (0, 1)")
        if self.affine:
            raise ValueError("photometric: the affine colour model is not implemented (gains only)")


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
        meta: JSON-able extras (``appearance_to_exposure``: the variance ratio of exposure_part).
    """

    names: tuple[str, ...]
    gains: np.ndarray
    pairs: int
    samples: int
    unaligned: tuple[str, ...] = ()
    reference: str = "median"
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


# --------------------------------------------------------------------------- correspondences
def _usable(scan: Scan, cfg: PhotometricConfig) -> tuple[np.ndarray, np.ndarray]:
    """(linear colour (H, W, 3) float32, (H, W) bool usable samples) of a view."""
    import cv2

    lin = scan.linear_rgb.astype(np.float32)
    d = scan.depth
    hi = cv2.dilate(d, np.ones((3, 3), np.uint8))
    lo = cv2.erode(np.where(d > 0, d, np.inf).astype(np.float32), np.ones((3, 3), np.uint8))
    ok = (d > 0) & np.isfinite(lo) & (hi - lo <= cfg.edge_tol * d)
    ok &= np.all(lin >= cfg.min_linear, axis=2) & np.all(lin <= srgb_to_linear(np.float32(cfg.max_srgb)), axis=2)
    if scan.alpha is not None:
        ok &= scan.alpha >= 1.0 - 1e-3
    return lin, ok


def _usable_cache(scans, cfg: PhotometricConfig):
    """``prep(k)`` = :func:`_usable` of view k, the last PREP_CACHE_VIEWS views kept (the pairs run
    view by view, so a capture's float colour is never held for every view at once)."""
    from collections import OrderedDict

    cache: OrderedDict = OrderedDict()

    def prep(k: int):
        if k in cache:
            cache.move_to_end(k)
        else:
            cache[k] = _usable(scans[k], cfg)
            while len(cache) > PREP_CACHE_VIEWS:
                cache.popitem(last=False)
        return cache[k]

    return prep


def _bilinear(img: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """img (H, W, C) sampled at float pixel coordinates (inside the image)."""
    u0 = np.floor(u).astype(np.int64)
    v0 = np.floor(v).astype(np.int64)
    fu = (u - u0)[:, None]
    fv = (v - v0)[:, None]
    u1 = np.minimum(u0 + 1, img.shape[1] - 1)
    v1 = np.minimum(v0 + 1, img.shape[0] - 1)
    top = img[v0, u0] * (1 - fu) + img[v0, u1] * fu
    bot = img[v1, u0] * (1 - fu) + img[v1, u1] * fu
    return top * (1 - fv) + bot * fv


def pair_log_ratios(si: Scan, sj: Scan, prep_i, prep_j, cfg: PhotometricConfig) -> np.ndarray:
    """(N, 3) ``log c_j - log c_i`` over the correspondences of view i's samples in view j."""
    lin_i, ok_i = prep_i
    lin_j, ok_j = prep_j
    step = cfg.stride or max(1, min(ok_i.shape) // AUTO_STRIDE_PX)
    vv, uu = np.nonzero(ok_i[::step, ::step])
    vv, uu = vv * step, uu * step
    if len(uu) == 0:
        return np.zeros((0, 3))
    uv = np.stack([uu, vv], axis=1).astype(np.float64)
    pts = si.camera.unproject(uv, si.depth[vv, uu].astype(np.float64))
    pix, z = sj.camera.project(pts)
    H, W = sj.depth.shape
    inb = (z > 0) & (pix[:, 0] >= 0) & (pix[:, 0] <= W - 1) & (pix[:, 1] >= 0) & (pix[:, 1] <= H - 1)
    pix, z, vv, uu = pix[inb], z[inb], vv[inb], uu[inb]
    ni = np.clip(np.round(pix).astype(np.int64), 0, [W - 1, H - 1])
    dj = sj.depth[ni[:, 1], ni[:, 0]]
    agree = ok_j[ni[:, 1], ni[:, 0]] & (np.abs(dj - z) <= cfg.depth_tol * z)
    if not np.any(agree):
        return np.zeros((0, 3))
    cj = _bilinear(lin_j, pix[agree, 0], pix[agree, 1])
    ci = lin_i[vv[agree], uu[agree]]
    good = np.all(cj >= cfg.min_linear, axis=1)
    return np.log(cj[good].astype(np.float64)) - np.log(ci[good].astype(np.float64))


def robust_location(r: np.ndarray, huber: float) -> tuple[np.ndarray, np.ndarray]:
    """Per column of (N, C) ``r``: (Huber M-estimate of the location, robust sigma)."""
    mu = np.median(r, axis=0)
    sigma = MAD_TO_SIGMA * np.median(np.abs(r - mu), axis=0) + SIGMA_FLOOR
    for _ in range(IRLS_STEPS):
        a = np.abs(r - mu) / (huber * sigma)
        w = np.where(a <= 1, 1.0, 1.0 / np.maximum(a, 1e-12))
        mu = (w * r).sum(axis=0) / w.sum(axis=0)
    return mu, sigma


def neighbour_pairs(scans, cfg: PhotometricConfig) -> list[tuple[int, int]]:
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


# --------------------------------------------------------------------------- solve
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


def exposure_part(x: np.ndarray, forward: np.ndarray, corr_deg: float) -> tuple[np.ndarray, float]:
    """The per-view exposure in log gains ``x`` (V, 3), separated from view-dependent appearance.

    ``x = e + a``: exposure e is independent per view (covariance s_e I); appearance a is
    correlated between views that look from similar directions (covariance s_a K, K_ij =
    exp(-angle_ij^2 / 2 corr_deg^2) from the viewing directions ``forward`` (V, 3)).  The ratio
    s_a / s_e is chosen by maximum likelihood (profiled over s_e, the three channels pooled, the
    global gain projected out), and e is its posterior mean (Wiener filter).  A capture whose views
    differ only smoothly with the viewpoint (fur lit from one side) keeps its colours; one whose
    views jump independently (auto exposure) is corrected.  Returns (e, s_a / s_e)."""
    n = len(x)
    if n < 3:
        return x, 0.0
    cos = np.clip(forward @ forward.T, -1.0, 1.0)
    K = np.exp(-np.degrees(np.arccos(cos)) ** 2 / (2 * corr_deg ** 2))
    Q = np.linalg.svd(np.eye(n) - 1.0 / n, hermitian=True)[0][:, : n - 1]   # basis without the global gain
    y = Q.T @ x
    Kq = Q.T @ K @ Q
    best = None
    for r in APPEARANCE_RATIOS:
        M = np.eye(n - 1) + r * Kq
        sign, logdet = np.linalg.slogdet(M)
        quad = float(np.sum(y * np.linalg.solve(M, y)))
        nll = 3 * (n - 1) * np.log(quad / (3 * (n - 1)) + 1e-300) + 3 * logdet
        if best is None or nll < best[0]:
            best = (nll, r, M)
    _, r, M = best
    return Q @ np.linalg.solve(M, y), float(r)


def _connected(n: int, edges) -> np.ndarray:
    """(V,) bool: views joined by at least one edge."""
    seen = np.zeros(n, bool)
    for i, j, *_ in edges:
        seen[i] = seen[j] = True
    return seen


def estimate_gains(scans, cfg: PhotometricConfig | None = None, progress=None) -> PhotometricResult:
    """Per-view gains of ``scans`` (module docstring)."""
    cfg = cfg or PhotometricConfig()
    scans = list(scans)
    names = tuple(s.name for s in scans)
    if cfg.reference not in GAUGES and cfg.reference not in names:
        raise ValueError(f"photometric reference {cfg.reference!r} is neither {' nor '.join(GAUGES)} nor a view name "
                         f"(views: {', '.join(names[:6])}{', ...' if len(names) > 6 else ''})")
    prep = _usable_cache(scans, cfg)
    pairs = neighbour_pairs(scans, cfg)
    edges, samples = [], 0
    for i, j in (progress(pairs, "photometric pairs") if progress else pairs):
        r = pair_log_ratios(scans[i], scans[j], prep(i), prep(j), cfg)
        if len(r) < cfg.min_samples:
            continue
        mu, sigma = robust_location(r, cfg.huber)
        edges.append((i, j, mu, np.sqrt(sigma ** 2 / len(r) + PAIR_BIAS ** 2)))
        samples += len(r)
    x, resid = solve_gains(len(scans), edges, cfg.huber) if edges else (np.zeros((len(scans), 3)), 0.0)
    ratio = 0.0
    if cfg.appearance_deg > 0 and edges:
        x, ratio = exposure_part(x, np.stack([s.camera.forward for s in scans]), cfg.appearance_deg)
    linked = _connected(len(scans), edges)
    x[~linked] = np.nan
    if not linked.any():
        x[:] = 0.0
    elif cfg.reference == "median":
        x = x - np.nanmedian(x, axis=0)
    elif cfg.reference == "mean":
        x = x - np.nanmean(x, axis=0)
    else:   # a named view that is not linked keeps its colour; so does everything relative to it
        x = x - np.nan_to_num(x[names.index(cfg.reference)], nan=0.0)
    x = np.nan_to_num(x, nan=0.0)
    return PhotometricResult(names, np.exp(x), len(edges), samples, tuple(n for n, k in zip(names, linked) if not k),
                             cfg.reference, resid, {"appearance_to_exposure": ratio})


def apply_gains(scans, gains: np.ndarray, keep=None) -> tuple[Scan, ...]:
    """The scans with their linear colour multiplied by ``gains`` (V, 3); 8-bit sRGB stays 8-bit
    (re-encoded, clipped), float linear stays float; a view with gain exactly 1 is untouched.
    ``keep`` takes each new scan (capture.scan_store)."""
    keep = keep or keep_in_memory
    out = []
    for s, g in zip(scans, np.asarray(gains, np.float64), strict=True):
        if np.all(g == 1.0):
            out.append(s)
            continue
        lin = s.linear_rgb * g.astype(np.float32)
        rgb = to_uint8_srgb(lin) if s.rgb.dtype == np.uint8 else lin.astype(np.float32)
        out.append(keep(Scan(rgb, s.depth, s.camera, s.name, s.alpha)))
    return tuple(out)

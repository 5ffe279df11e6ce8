"""3D Gaussians (Kerbl et al. 2023's representation) built from a model's kept views (issue 33).

Not from the mesh: from the RGBz views with their matte (volume.rgbz_store.RgbzImages), one view
at a time (``rgbz.crop(n)``); the steps are in volume/splat_build.py:

1. **samples**: every pixel with depth and matte alpha >= ``SplatConfig.min_alpha`` of every kept
   view is back-projected to a world point with its footprint z / f (metres), alpha and colour;
2. **one layer**: a place seen by several views is kept from one of them, the one among those that
   see it (depth agreement) looking most outward at it (from the object's centre): the views'
   depth noise would otherwise stack one layer per view, each in front of the others somewhere;
3. **merge**: the points are binned on a grid of edge ``cell_footprints`` x the median footprint
   (one pixel's width on the object), grown until the Gaussians fit the budget (``budget_ratio``:
   the PLY at most that many times the model's size on disk); each occupied cell is a Gaussian at
   the mean of its points;
4. **shape**: the covariance of the points of the cell and its 26 neighbours gives the local
   structure -- a surface (one small axis: the normal), a strand (one long axis: its direction)
   or fuzz; the axes are its eigenvectors, the standard deviations ``shape_gain`` x
   sqrt(eigenvalue) clamped to [``sigma_min_cells``, ``sigma_max_cells``] cells;
5. **opacity**: the mean matte alpha of the cell's points (1 without a matte) times the share of
   the views that see the Gaussian among those that see it or look through its place (free
   space: their nearest pixel holds no depth, or one more than ``carve_tol_m`` behind it);
6. **colour**: spherical harmonics of degree ``sh_degree`` (volume/splat_sh.py) fitted by ridge
   least squares (``sh_ridge`` towards the DC term) to the colour every kept view recorded where it
   sees the Gaussian: its centre projected into the view, the 2 x 2 pixels around it resampled
   bilinearly, each counted when its depth agrees within max(``vis_tol_cells`` cells,
   ``vis_tol_m``) and weighted by its alpha.

**Colour convention.**  The coefficients hold display (sRGB-encoded) straight colour, as the
reference and every viewer that reads its PLY assume: a viewer blends ``0.5 + SH(dir)`` over its
background in display values.  furrow's splat renderer (render/splat/) blends the same values
front to back into (C, A) and hands its Frame ``srgb_to_linear(C / A) * A`` (premultiplied linear,
as every method): a single layer of alpha a and colour c then gives exactly the photograph's
premultiplied ``a * linear(c)`` over black.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from volume import splat_sh
from volume.splat_build import count_cells, merge, neighbourhood_covariance, owners, shapes, view_pass, view_samples

#: Opacity range of a built Gaussian: the PLY stores its logit, which must stay finite; below
#: 1/255 the reference draws nothing.
OPACITY_MIN = 1.0 / 255.0
OPACITY_MAX = 0.995
#: Growth factor of the merge grid's edge while the Gaussians exceed the budget.
CELL_GROWTH = 1.25
#: Most growth steps (the edge grows at most CELL_GROWTH ** MAX_GROWTH_STEPS, about 87x).
MAX_GROWTH_STEPS = 20
#: Bisection steps between the last edge over the budget and the first within it.
BISECT_STEPS = 4
#: Samples at most in one batch of the SH normal equations (bounds their memory).
FIT_BATCH = 200_000
#: Deflate level of volume.rgbz_store.save_crops (rgbz.npz), used to size a model on disk.
RGBZ_DEFLATE_LEVEL = 6


@dataclass(frozen=True)
class SplatConfig:
    """How :func:`build_splats` turns views into Gaussians (module docstring)."""

    cell_footprints: float = 1.0
    """Merge grid edge, in pixel footprints (median z / f over the samples), before any growth."""
    budget_ratio: float | None = 2.95
    """The PLY is at most this many times the model's size on disk (:func:`model_bytes`, a lower
    bound of it): the merge grid grows until it is; None: no budget."""
    sh_degree: int = 2
    """Degree of the view-dependent colour (0..3; 2: 9 coefficients per channel)."""
    sh_ridge: float = 0.05
    """Ridge on the non-DC coefficients, in units of one full-weight view sample."""
    vis_tol_cells: float = 2.0
    """A view sees a Gaussian where their depths agree within this many cells..."""
    vis_tol_m: float = 0.003
    """...or this many metres, whichever is larger (the depth sensor's noise; gather's 3 mm)."""
    carve_tol_m: float = 0.0015
    """A view looks through a Gaussian's place where its depth there is this much behind it."""
    one_layer: bool = True
    """Keep each place from one view (step 2); False keeps every view's samples."""
    shape_gain: float = 0.6
    """Standard deviation along an axis = this x sqrt(the neighbourhood's eigenvalue)."""
    sigma_min_cells: float = 0.1
    """Smallest standard deviation, in cells (the thickness of a surface or a strand)."""
    sigma_max_cells: float = 0.3
    """Largest standard deviation, in cells."""
    min_alpha: float = 0.25
    """Pixels whose matte alpha is below this are no samples (their straight colour is unreliable)."""

    def __post_init__(self) -> None:
        splat_sh.n_coeffs(self.sh_degree)
        for name in ("cell_footprints", "vis_tol_cells", "shape_gain", "sigma_min_cells", "sigma_max_cells"):
            if not getattr(self, name) > 0:
                raise ValueError(f"SplatConfig.{name} must be > 0, got {getattr(self, name)}")
        if self.sigma_max_cells < self.sigma_min_cells:
            raise ValueError("SplatConfig: sigma_max_cells must be >= sigma_min_cells")
        if self.budget_ratio is not None and not self.budget_ratio > 0:
            raise ValueError(f"SplatConfig.budget_ratio must be > 0 or None, got {self.budget_ratio}")
        if self.sh_ridge < 0 or self.vis_tol_m < 0 or self.carve_tol_m < 0 or not 0 <= self.min_alpha < 1:
            raise ValueError("SplatConfig: sh_ridge, vis_tol_m, carve_tol_m >= 0 and min_alpha in [0, 1) required")


@dataclass(frozen=True)
class Splats:
    """A set of 3D Gaussians in the world frame of the model (metres).

    Attributes:
        positions: (N, 3) float32 centres.
        scales: (N, 3) float32 standard deviations (metres, > 0) along the rotation's axes.
        rotations: (N, 4) float32 unit quaternions (w, x, y, z); the columns of their rotation
            matrix R are the axes, the covariance is R diag(scales^2) R^T.
        opacities: (N,) float32 in (0, 1).
        sh: (N, K, 3) float32 spherical-harmonic coefficients per channel, K = (degree + 1)^2,
            of the display colour 0.5 + SH(dir) (volume/splat_sh.py).
    """

    positions: np.ndarray
    scales: np.ndarray
    rotations: np.ndarray
    opacities: np.ndarray
    sh: np.ndarray

    def __post_init__(self) -> None:
        p = np.asarray(self.positions, np.float32).reshape(-1, 3)
        n = len(p)
        s = np.asarray(self.scales, np.float32).reshape(n, 3)
        q = np.asarray(self.rotations, np.float32).reshape(n, 4)
        o = np.asarray(self.opacities, np.float32).reshape(n)
        sh = np.asarray(self.sh, np.float32)
        if sh.ndim != 3 or sh.shape[0] != n or sh.shape[2] != 3:
            raise ValueError(f"Splats: sh must be ({n}, K, 3), got {sh.shape}")
        splat_sh.degree_of(sh.shape[1])
        if not all(np.all(np.isfinite(a)) for a in (p, s, q, o, sh)):
            raise ValueError("Splats: every array must be finite")
        if n and (s.min() <= 0 or o.min() <= 0 or o.max() >= 1):
            raise ValueError("Splats: scales must be > 0 and opacities in (0, 1)")
        if n and np.abs(np.linalg.norm(q, axis=1) - 1).max() > 1e-3:
            raise ValueError("Splats: rotations must be unit quaternions (w, x, y, z)")
        for name, a in (("positions", p), ("scales", s), ("rotations", q), ("opacities", o), ("sh", sh)):
            a = np.ascontiguousarray(a)
            a.setflags(write=False)
            object.__setattr__(self, name, a)

    def __len__(self) -> int:
        return len(self.positions)

    @property
    def degree(self) -> int:
        return splat_sh.degree_of(self.sh.shape[1])

    def rotation_matrices(self) -> np.ndarray:
        """(N, 3, 3) float64 rotation matrices of the quaternions."""
        return quat_to_matrix(self.rotations)

    def covariances(self) -> np.ndarray:
        """(N, 3, 3) float64 world covariances R diag(scales^2) R^T (m^2)."""
        r = self.rotation_matrices()
        return np.einsum("nij,nj,nkj->nik", r, self.scales.astype(np.float64) ** 2, r)


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotation matrices of quaternions (N, 4) (w, x, y, z), normalised first."""
    q = np.asarray(q, np.float64)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    return np.stack([np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
                     np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
                     np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)], 1)


def matrix_to_quat(r: np.ndarray) -> np.ndarray:
    """(N, 4) unit quaternions (w, x, y, z), w >= 0, of proper rotation matrices (N, 3, 3)."""
    r = np.asarray(r, np.float64)
    m00, m11, m22 = r[:, 0, 0], r[:, 1, 1], r[:, 2, 2]
    # squared magnitudes of the four components, each from the diagonal; take the largest for stability
    w2 = np.stack([1 + m00 + m11 + m22, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22], 1)
    k = np.argmax(w2, 1)
    big = 0.5 * np.sqrt(np.maximum(w2[np.arange(len(r)), k], 1e-300))
    d = 0.25 / big
    q = np.empty((len(r), 4))
    s21, s02, s10 = r[:, 2, 1] - r[:, 1, 2], r[:, 0, 2] - r[:, 2, 0], r[:, 1, 0] - r[:, 0, 1]
    a01, a02, a12 = r[:, 0, 1] + r[:, 1, 0], r[:, 0, 2] + r[:, 2, 0], r[:, 1, 2] + r[:, 2, 1]
    cases = [(big, s21 * d, s02 * d, s10 * d), (s21 * d, big, a01 * d, a02 * d),
             (s02 * d, a01 * d, big, a12 * d), (s10 * d, a02 * d, a12 * d, big)]
    for i, comps in enumerate(cases):
        m = k == i
        q[m] = np.stack([c[m] for c in comps], 1)
    q *= np.where(q[:, :1] < 0, -1.0, 1.0)
    return q / np.linalg.norm(q, axis=1, keepdims=True)




def ply_floats(degree: int) -> int:
    """float32 values per Gaussian in the reference PLY of SH degree ``degree``
    (position, normal, 3 x (degree + 1)^2 colour, opacity, 3 scales, 4 rotation)."""
    return 3 + 3 + 3 * splat_sh.n_coeffs(degree) + 1 + 3 + 4


def rgbz_bytes(rgbz) -> int:
    """Bytes the RGBz views take in a model folder (volume.model.save_model): a compact store's
    crops deflated as rgbz.npz deflates them (zlib level RGBZ_DEFLATE_LEVEL; within 0.1 % of the
    file measured), a dense store's float16 arrays as they are."""
    if not rgbz.compact:
        return sum(a.astype(np.float16).nbytes for a in (rgbz.rgb, rgbz.depth, rgbz.alpha) if a is not None)
    total = 0
    for n in range(len(rgbz)):
        c = rgbz.encoded(n)
        for a in (c.srgb, c.depth, c.alpha):
            if a is not None:
                total += len(zlib.compress(np.ascontiguousarray(a).tobytes(), RGBZ_DEFLATE_LEVEL))
    return total


def model_bytes(model) -> int:
    """A lower bound of the model folder's size: its RGBz views (:func:`rgbz_bytes`), mesh and
    spheres (stored uncompressed); the pyramid and model.json, small, are left out."""
    arrays = (model.mesh_vertices, model.mesh_faces, model.mesh_colors, model.spheres.centers, model.spheres.radii)
    return rgbz_bytes(model.rgbz) + sum(a.nbytes for a in arrays if a is not None)


def gaussian_budget(model, cfg: SplatConfig) -> int | None:
    """Most Gaussians of ``cfg``'s budget (SplatConfig.budget_ratio x :func:`model_bytes` of PLY),
    None without one."""
    if cfg.budget_ratio is None:
        return None
    return max(int(cfg.budget_ratio * model_bytes(model) / (4 * ply_floats(cfg.sh_degree))), 1)


def grid_edge(points: np.ndarray, edge: float, budget: int | None) -> tuple[float, int]:
    """(edge, cells): the merge grid's edge -- ``edge``, or when its occupied cells exceed
    ``budget`` the smallest edge found that fits it (grown by CELL_GROWTH, then bisected
    BISECT_STEPS times) -- and its cell count."""
    n = count_cells(points, edge)
    if budget is None or n <= budget:
        return edge, n
    lo, hi, n_hi = edge, edge, n
    for _ in range(MAX_GROWTH_STEPS):
        lo, hi = hi, hi * CELL_GROWTH
        n_hi = count_cells(points, hi)
        if n_hi <= budget:
            break
    for _ in range(BISECT_STEPS):
        mid = 0.5 * (lo + hi)
        n_mid = count_cells(points, mid)
        if n_mid <= budget:
            hi, n_hi = mid, n_mid
        else:
            lo = mid
    return hi, n_hi


@dataclass(frozen=True)
class BuildInfo:
    """How a build went: samples read and kept (one layer), the budget, the grid edge (metres and
    footprints) and the Gaussians made."""

    samples: int
    kept: int
    budget: int | None
    edge_m: float
    edge_footprints: float
    gaussians: int

    def record(self) -> dict:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def _samples(model, cfg: SplatConfig, track):
    """Every view's samples (volume.splat_build.view_samples), concatenated, with their view index
    and the median footprint; reduced to one layer (volume.splat_build.owners) when asked."""
    rgbz = model.rgbz
    parts = []
    for n in track(range(len(rgbz)), "splats: samples"):
        rect, rgb, depth, alpha = rgbz.crop(n)
        p, fp, a, c = view_samples(rgbz.cameras[n], rect, rgb, depth, alpha, cfg.min_alpha)
        parts.append((p, fp, a, c, np.full(len(p), n)))
    points, fps, alpha, colour, src = (np.concatenate(x) for x in zip(*parts))
    if not len(points):
        raise ValueError("build_splats: the model's views hold no depth: no Gaussian to build")
    total, footprint = len(points), float(np.median(fps))
    if cfg.one_layer:
        keep = owners(rgbz, points, src, np.asarray(model.bounds, float).mean(axis=0), cfg.vis_tol_m)
        points, alpha, colour = points[keep], alpha[keep], colour[keep]
    return points, alpha, colour, total, footprint


def build(model, config: SplatConfig | None = None, progress: Callable | None = None) -> tuple[Splats, BuildInfo]:
    """The Gaussians of ``model`` (a volume.model.Model) from its kept views (module docstring)
    and how the build went.  ``progress(iterable, description)`` wraps the passes over the views."""
    cfg = config or SplatConfig()
    rgbz = model.rgbz
    track = progress or (lambda it, _desc: it)
    if not len(rgbz):
        raise ValueError("build_splats: the model has no kept view")
    points, alpha, colour, total, footprint = _samples(model, cfg, track)
    budget = gaussian_budget(model, cfg)
    edge, _ = grid_edge(points, cfg.cell_footprints * footprint, budget)
    cells = merge(points, alpha, colour, edge)
    info = BuildInfo(total, len(points), budget, edge, edge / footprint, len(cells))
    del points, alpha, colour
    scales, axes = shapes(neighbourhood_covariance(cells), edge, cfg.shape_gain, cfg.sigma_min_cells,
                          cfg.sigma_max_cells)
    centres = cells.centres
    mean_colour = cells.colour / np.maximum(cells.alpha, 1e-12)[:, None]
    tol = max(cfg.vis_tol_cells * edge, cfg.vis_tol_m)
    eq = splat_sh.NormalEquations(len(cells), cfg.sh_degree)
    free = np.zeros(len(cells))
    for n in track(range(len(rgbz)), "splats: colour fit"):
        (idx, dirs, col, w), f = view_pass(rgbz.cameras[n], *rgbz.crop(n), centres, tol, cfg.carve_tol_m)
        for lo in range(0, len(idx), FIT_BATCH):
            sl = slice(lo, lo + FIT_BATCH)
            eq.add(idx[sl], dirs[sl], col[sl], w[sl])
        free += f
    share = eq.weight / np.maximum(eq.weight + free, 1e-12)
    opacity = np.clip(cells.alpha / cells.n * share, OPACITY_MIN, OPACITY_MAX)
    return Splats(centres, scales, matrix_to_quat(axes), opacity, eq.solve(cfg.sh_ridge, mean_colour)), info


def build_splats(model, config: SplatConfig | None = None, progress: Callable | None = None) -> Splats:
    """The Gaussians of ``model`` from its kept views (:func:`build`, without the report)."""
    return build(model, config, progress)[0]

"""The resolution choice L_opt (docs/methods.md §1.1, Eq. 1) and the LOD pyramid (docs/methods.md §1.7).

Eq. 1: with N_i = number of voxels whose signed distance differs from a face neighbour's by
more than alpha * w, stop at the first resolution L (from L_max halving down) with
N_i / L^3 <= t.  A true distance field is 1-Lipschitz (neighbours differ by at most w), so
flagged voxels are where the fused distances cannot be trusted at that scale.

Which volume Eq. 1 looks at.  The consensus fusion rejects samples the scans do not agree on
and fills the gaps with an exact distance transform, so its output is smooth by construction
and would hide exactly the inconsistency Eq. 1 is meant to detect (fur: every view sees the
strands at a different depth).  Eq. 1 is therefore evaluated on the *measured* field
(``FusedSdf.measured``: at every voxel with a surface sample, the nearest-surface cluster of
samples, confirmed by a quorum or not), comparing only pairs of voxels that both have a
measurement, and dividing by L^3 as the paper does.  For the TSDF peer the measured field is
its own band.  The pyramid stores the consensus field.

Reading of the loop (docs/methods.md §1.1, kept as the paper states it, measured 2026-11-22).  Flagged
voxels lie on the surface, so N_i grows like L^2 and N_i / L^3 falls roughly like 1/L: the
fraction is higher at every coarser level and the loop either keeps L_max or runs to the
coarsest level.  Demo fur ball (18 of 36 views, 320x240): N_i/L^3 = 0.24, 0.16, 0.088, 0.050,
0.030, 0.019 at 8..256 -> L_opt = 8; plant 0.31 .. 0.0076 (128) -> L_max; smooth torus 0.0002
at 128 -> L_max.  Normalising by the measured voxels instead (N_i / #measured, reported as
``eq1_flagged_per_measured``) is flat on fur (0.33-0.42 at every level), so no threshold
separates the levels either.  Held-out PSNR (furrow eval --holdout 2, level forced by a cap
with E = 1 px) favours the coarse levels on fur and plant at 320x240 (fur 21.36 / 20.86 /
20.64 dB at 8 / 16 / 32; plant 29.91 / 29.80 / 29.76) and differs by 0.3 dB at 640x480 (fur
19.90 / 20.13 / 20.20 / 20.10 at 8..64); at the default E = 8 px the renderer's Eq. 11
picks 8^3 on both sizes whatever L_opt is.  So L_opt = 8 on fur is what Eq. 1 says and costs
no measured PSNR at the default tolerance; it only caps the finest level a small E could use.

Surface voxels (docs/methods.md §1.1 step 2): |signed distance| <= half a voxel diagonal, plus
(with measured points) every voxel that contains measured depth points of at least
MEASURED_MIN_VIEWS scans.  Slices are only generated in surface voxels (docs/methods.md §1.2) and the
RGBz depth keeps every measured sample (volume.rgbz), so without these voxels the measured
fuzz outside the consensus surface (fur fringe, needles) would have depth but no slice to
land on.  Requiring two scans keeps isolated flyers out.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from capture.sampling import cell_index
from volume.model import SdfLevel, SdfPyramid

#: Surface-voxel threshold as a fraction of the voxel diagonal (docs/methods.md §1.1: "about half").
SURFACE_DIAGONAL_FRACTION = 0.5
#: A voxel holding measured depth points of at least this many scans is a surface voxel too.
MEASURED_MIN_VIEWS = 2
#: Coarsest level kept in the pyramid (and the lowest resolution Eq. 1 can fall back to).
MIN_RESOLUTION = 8
#: :func:`view_cell_keys` finds a view's cells with one mark per cell (a 16 MiB bool array at 256^3)
#: up to this many cells, and by sorting the points' cells above (np.unique).
BITMAP_CELLS = 1 << 24


@dataclass(frozen=True)
class LoptConfig:
    """Parameters of the L_opt search (docs/methods.md §1.1, paper values as defaults)."""

    max_res: int = 256
    """L_max: the resolution the search starts from (a power of two)."""
    alpha: float = 1.5
    """Tolerance: neighbours differing by more than alpha * w are flagged (alpha >= 1)."""
    t: float = 0.01
    """Largest accepted fraction N_i / L^3 of flagged voxels (Eq. 1)."""
    min_res: int = MIN_RESOLUTION
    """Coarsest resolution searched and kept (a power of two)."""

    def __post_init__(self) -> None:
        for name in ("max_res", "min_res"):
            v = getattr(self, name)
            if v < 1 or v & (v - 1):
                raise ValueError(f"--{name.replace('_', '-')} must be a power of two, got {v}")
        if self.min_res > self.max_res:
            raise ValueError(f"min_res {self.min_res} > max_res {self.max_res}")
        if self.alpha < 1:
            raise ValueError(f"--alpha must be >= 1 (docs/methods.md §1.1), got {self.alpha}")
        if not 0 <= self.t <= 1:
            raise ValueError(f"--t must be in [0, 1], got {self.t}")

    @property
    def resolutions(self) -> list[int]:
        """Every power of two from min_res to max_res, coarse -> fine."""
        out, L = [], self.min_res
        while L <= self.max_res:
            out.append(L)
            L *= 2
        return out


def discontinuity_mask(values: np.ndarray, voxel_size: float, alpha: float,
                       valid: np.ndarray | None = None) -> np.ndarray:
    """(L, L, L) bool: voxels whose value differs from a face neighbour's by > alpha * w.

    With ``valid`` (L, L, L) bool, only pairs of two valid voxels are compared.
    """
    v = np.asarray(values, np.float32)
    flag = np.zeros(v.shape, bool)
    lim = np.float32(alpha * voxel_size)
    for ax in range(v.ndim):
        jump = np.abs(np.diff(v, axis=ax)) > lim
        lo = [slice(None)] * v.ndim
        hi = [slice(None)] * v.ndim
        lo[ax] = slice(None, -1)
        hi[ax] = slice(1, None)
        if valid is not None:
            jump &= valid[tuple(lo)] & valid[tuple(hi)]
        flag[tuple(lo)] |= jump
        flag[tuple(hi)] |= jump
    return flag


def discontinuity_fraction(values: np.ndarray, voxel_size: float, alpha: float,
                           valid: np.ndarray | None = None, fast: bool = True) -> float:
    """N_i / L^3 of Eq. 1 (docs/methods.md §1.1 step iii); ``valid`` as in :func:`discontinuity_mask`.
    ``fast``: counted in one compiled pass over a 3-D volume (volume.pyramid_kernel, the same count),
    else from the mask (the reference)."""
    v = np.asarray(values)
    if fast and v.ndim == 3:
        from volume.pyramid_kernel import count_flagged

        return float(count_flagged(v, np.float32(alpha * voxel_size), valid)) / v.size
    return float(discontinuity_mask(v, voxel_size, alpha, valid).sum()) / v.size


def choose_l_opt(fractions: dict[int, float], t: float) -> int:
    """Eq. 1: from the finest resolution down, the first whose fraction is <= t; else the coarsest.

    The paper's loop as docs/methods.md §1.1 states it (see the module docstring for what it does on fur)."""
    res = sorted(fractions, reverse=True)
    for L in res:
        if fractions[L] <= t:
            return L
    return res[-1]


def surface_voxels(values: np.ndarray, voxel_size: float) -> np.ndarray:
    """(N, 3) int32 indices (i, j, k) with |d| <= half the voxel diagonal (docs/methods.md §1.1 step 2)."""
    thr = SURFACE_DIAGONAL_FRACTION * np.sqrt(3.0) * voxel_size
    return np.argwhere(np.abs(values) <= thr).astype(np.int32)


def measured_voxels(points, origin, voxel_size: float, L: int, min_views: int = MEASURED_MIN_VIEWS) -> np.ndarray:
    """(N, 3) int32 indices of the voxels of an L^3 grid holding points of >= ``min_views`` views.

    ``points``: one (M_v, 3) array of world points (metres) per view; points outside the cube are
    ignored.  Sorted by linear index (i major).
    """
    return measured_voxels_levels(points, origin, {L: voxel_size}, min_views)[L]


def measured_voxels_levels(points, origin, sizes: dict[int, float], min_views: int = MEASURED_MIN_VIEWS) -> dict:
    """{L: :func:`measured_voxels` of the L^3 grid of voxel size ``sizes[L]``} for every level at
    once: each view's points are made (a spilled scan read, back-projected) once, not once a level.
    The reference of :func:`measured_voxels_mapped` (every view in this process)."""
    return measured_from_keys((view_cell_keys(p, origin, sizes) for p in points), sizes, min_views)


def nested_finest(sizes: dict[int, float]) -> int | None:
    """The finest L of ``sizes`` when every level is it halved k times (L_f = 2^k L) with a voxel
    exactly 2^k times the finest's (what :func:`pyramid_sizes` gives: extent / L); else None."""
    lf = max(sizes)
    for L, w in sizes.items():
        s = lf // L
        if L < 1 or lf % L or s & (s - 1) or w != sizes[lf] * s:
            return None
    return lf


def _unique_keys(keys: np.ndarray, cells: int) -> np.ndarray:
    """np.unique of int64 ``keys`` in [0, cells): through a mark per cell where the grid is small."""
    if cells > BITMAP_CELLS:
        return np.unique(keys)
    mark = np.zeros(cells, bool)
    mark[keys] = True
    return np.flatnonzero(mark)


def view_cell_keys(points, origin, sizes: dict[int, float]) -> dict[int, np.ndarray]:
    """{L: sorted unique linear indices ((i * L + j) * L + k) of the L^3 cells of voxel size
    ``sizes[L]`` from ``origin`` holding one view's ``points`` (M, 3)}; points outside are ignored.

    With nested levels (:func:`nested_finest`) the points are binned once, at the finest level, and
    a coarser level's cells are the finest cells' indices shifted right: floor(x / (2^k w)) =
    floor(floor(x / w) / 2^k), and x / (2^k w) is (x / w) / 2^k in floating point too (a power of
    two), so the cells are those of :func:`view_cell_keys_reference` (tests/volume/test_pyramid.py);
    other sizes go to it."""
    lf = nested_finest(sizes) if sizes else None
    if lf is None:
        return view_cell_keys_reference(points, origin, sizes)
    p = np.asarray(points, np.float64).reshape(-1, 3) - np.asarray(origin, np.float64)
    g = cell_index(p, 0.0, sizes[lf])
    g = g[np.all((g >= 0) & (g < lf), axis=1)]
    fine = _unique_keys((g[:, 0] * lf + g[:, 1]) * lf + g[:, 2], lf ** 3)
    i, j, k = fine // (lf * lf), (fine // lf) % lf, fine % lf
    out = {}
    for L in sizes:
        s = (lf // L).bit_length() - 1
        out[L] = fine if L == lf else _unique_keys(((i >> s) * L + (j >> s)) * L + (k >> s), L ** 3)
    return out


def view_cell_keys_reference(points, origin, sizes: dict[int, float]) -> dict[int, np.ndarray]:
    """:func:`view_cell_keys` level by level: each level bins every point and sorts its cells."""
    p = np.asarray(points, np.float64).reshape(-1, 3) - np.asarray(origin, np.float64)
    out = {}
    for L, w in sizes.items():
        g = cell_index(p, 0.0, w)
        g = g[np.all((g >= 0) & (g < L), axis=1)]
        out[L] = np.unique((g[:, 0] * L + g[:, 1]) * L + g[:, 2])
    return out


def measured_keys_view(scan, k, arg):
    """Per view (capture.view_map; ``arg``: (origin, sizes)): (None, :func:`view_cell_keys` of the
    scan's measured points): what a worker hands back is a view's cells, not its points."""
    origin, sizes = arg
    return None, view_cell_keys(scan.points(), origin, sizes)


def measured_voxels_mapped(map_views, scans, origin, sizes: dict[int, float],
                           min_views: int = MEASURED_MIN_VIEWS) -> dict:
    """:func:`measured_voxels_levels` of the scans' measured points, each view's cells found through
    ``map_views`` (capture.view_map: the pipeline's pool, the views side by side): the same voxels
    (tests/volume/test_pyramid.py)."""
    keys = map_views(measured_keys_view, scans, (np.asarray(origin, np.float64), dict(sizes)), "pyramid")[1]
    return measured_from_keys(keys, sizes, min_views)


def measured_from_keys(view_keys, sizes: dict[int, float], min_views: int = MEASURED_MIN_VIEWS) -> dict:
    """{L: (N, 3) int32 indices of the cells found in >= ``min_views`` of ``view_keys`` (one
    :func:`view_cell_keys` dict per view, an iterable)}, sorted by linear index."""
    keys: dict[int, list] = {L: [] for L in sizes}
    for vk in view_keys:
        for L in sizes:
            keys[L].append(vk[L])
    out = {}
    for L, ks in keys.items():
        if not ks:
            out[L] = np.zeros((0, 3), np.int32)
            continue
        k, n = np.unique(np.concatenate(ks), return_counts=True)
        k = k[n >= max(int(min_views), 1)]
        out[L] = np.stack([k // (L * L), (k // L) % L, k % L], axis=1).astype(np.int32)
    return out


def union_voxels(a: np.ndarray, b: np.ndarray, L: int) -> np.ndarray:
    """(N, 3) int32 union of two index sets of an L^3 grid, sorted by linear index."""
    c = np.concatenate([np.asarray(a, np.int64).reshape(-1, 3), np.asarray(b, np.int64).reshape(-1, 3)])
    k = np.unique((c[:, 0] * L + c[:, 1]) * L + c[:, 2])
    return np.stack([k // (L * L), (k // L) % L, k % L], axis=1).astype(np.int32)


def build_pyramid(volumes: dict[int, np.ndarray], origin, extent: float, l_opt: int,
                  keep_values: bool = True, points=None, min_views: int = MEASURED_MIN_VIEWS,
                  measured: dict | None = None) -> SdfPyramid:
    """SdfPyramid of every level <= l_opt from the full volumes {L: (L,L,L) float32}.

    ``points`` (one (M_v, 3) world array per scan, or None): voxels holding measured points of
    at least ``min_views`` scans join each level's surface voxels (module docstring).  ``measured``:
    those voxels already found ({L: (N, 3) int32} for every kept level, :func:`measured_voxels_mapped`
    of :func:`pyramid_sizes`); ``points`` is then not read.
    """
    levels = []
    kept = [L for L in sorted(volumes) if L <= l_opt]
    if measured is None:
        measured = measured_voxels_levels(points, origin, pyramid_sizes(volumes, extent, l_opt), min_views) \
            if points is not None else {}
    for L in kept:
        w = extent / L
        v = np.asarray(volumes[L], np.float32)
        surf = surface_voxels(v, w)
        if L in measured:
            surf = union_voxels(surf, measured[L], L)
        levels.append(SdfLevel(L, np.asarray(origin, np.float64), w, surf, v if keep_values else None))
    return SdfPyramid(tuple(levels), l_opt)


def pyramid_sizes(volumes, extent: float, l_opt: int) -> dict[int, float]:
    """{L: voxel size} of the levels :func:`build_pyramid` keeps (those <= ``l_opt``)."""
    return {L: extent / L for L in sorted(volumes) if L <= l_opt}

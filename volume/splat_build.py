"""The steps of volume.splats.build_splats, each a function over numpy arrays and one view at a
time (the model's RGBz crops: ``rgbz.crop(n)`` gives rect, linear rgb, depth, alpha).

* :func:`view_samples`: a view's pixels as world points with footprint, alpha, display colour;
* :func:`owners`: which view keeps each point (the one that looks most outward at it);
* :func:`merge` / :class:`Cells`: points binned on a grid;
* :func:`neighbourhood_covariance` / :func:`shapes`: local structure -> scales and rotations;
* :func:`view_pass`: what a view tells each Gaussian: colour samples for the SH fit and
  free-space votes for the opacity.
"""

from __future__ import annotations

import numpy as np

from capture.scan import linear_to_srgb

#: Neighbour offsets of the shape estimate (the cell and its 26 neighbours).
_OFFSETS = np.stack(np.meshgrid(*[np.arange(-1, 2)] * 3, indexing="ij"), -1).reshape(-1, 3)
#: Bilinear taps: (dx, dy) of the 4 pixels around a projected point.
_TAPS = ((0, 0), (1, 0), (0, 1), (1, 1))


def view_samples(cam, rect, rgb, depth, alpha, min_alpha: float):
    """One view's samples: (points (M, 3) float64 world, footprint (M,) metres z / f, alpha (M,),
    straight display colour (M, 3)) of the crop pixels with depth (and alpha >= min_alpha)."""
    d = np.asarray(depth, np.float32)
    a = np.ones_like(d) if alpha is None else np.asarray(alpha, np.float32)
    mask = np.isfinite(d) & (d > 0) & (a >= max(min_alpha, 1e-6))
    v, u = np.nonzero(mask)
    uv = np.stack([u + float(rect[0]), v + float(rect[1])], -1).astype(np.float64)
    z = d[mask].astype(np.float64)
    f = 0.5 * (cam.K[0, 0] + cam.K[1, 1])
    return cam.unproject(uv, z), z / f, a[mask].astype(np.float64), linear_to_srgb(rgb[mask]).astype(np.float64)


def project(cam, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``Camera.project`` (OpenCV pixels, z-depth; NaN behind the camera) with element-wise
    arithmetic instead of a BLAS product: a (M, 3) x (3, 3) product spends its time in thread
    hand-offs on a busy machine (4x the wall time measured here)."""
    R, t, K = cam.cam_from_world[:3, :3], cam.cam_from_world[:3, 3], cam.K
    x, y, z = (points[:, 0] * R[i, 0] + points[:, 1] * R[i, 1] + points[:, 2] * R[i, 2] + t[i] for i in range(3))
    with np.errstate(divide="ignore", invalid="ignore"):
        xn, yn = np.where(z > 0, x / z, np.nan), np.where(z > 0, y / z, np.nan)
    return np.stack([K[0, 0] * xn + K[0, 1] * yn + K[0, 2], K[1, 1] * yn + K[1, 2]], -1), z


def nearest_depth(cam, rect, depth, points):
    """(z (M,) of the points in the camera, depth (M,) of their nearest crop pixel: 0 outside the
    crop or behind the camera, in_image (M,) bool: projected inside the image)."""
    uv, z = project(cam, points)
    uv = np.nan_to_num(uv, nan=-1e9)
    in_image = (z > 0) & (uv[:, 0] > -0.5) & (uv[:, 1] > -0.5) & (uv[:, 0] < cam.width - 0.5) & \
        (uv[:, 1] < cam.height - 0.5)
    x0, y0, w, h = (int(v) for v in rect)
    xi = np.round(uv[:, 0]).astype(np.int64) - x0
    yi = np.round(uv[:, 1]).astype(np.int64) - y0
    inside = in_image & (xi >= 0) & (yi >= 0) & (xi < w) & (yi < h)
    d = np.asarray(depth, np.float32)
    return z, np.where(inside, d[np.where(inside, yi, 0), np.where(inside, xi, 0)], 0.0), in_image


def owners(rgbz, points: np.ndarray, src: np.ndarray, centre: np.ndarray, tol: float) -> np.ndarray:
    """(M,) bool: the samples whose own view ``src`` is, among the views that see them (depth
    agreement within ``tol`` metres at the nearest pixel), the one looking most along the outward
    direction from the object's ``centre`` to the sample: every place is then kept from one view
    (one layer), not from each view with its own depth noise."""
    out_dir = points - centre
    out_dir /= np.maximum(np.linalg.norm(out_dir, axis=1, keepdims=True), 1e-12)
    best = np.full(len(points), -np.inf)
    who = np.full(len(points), -1)
    for n, cam in enumerate(rgbz.cameras):
        rect, _rgb, depth, _a = rgbz.crop(n)
        z, d, _ = nearest_depth(cam, rect, depth, points)
        sees = ((d > 0) & (np.abs(d - z) < tol)) | (src == n)
        to_cam = cam.center - points
        score = (to_cam * out_dir).sum(1) / np.sqrt((to_cam * to_cam).sum(1))
        better = sees & (score > best)
        best[better], who[better] = score[better], n
    return who == src


class Cells:
    """Samples binned on a grid (:func:`merge`): per cell the sample count ``n``, the sums of
    position ``s1`` (relative to ``origin``), of the outer products ``s2``, of alpha, of
    alpha x colour; the cells' integer ``keys`` (sorted) and the grid's ``origin``, ``edge``, ``dims``."""

    def __init__(self, keys, n, s1, s2, alpha, colour, origin, edge, dims):
        self.keys, self.n, self.s1, self.s2 = keys, n, s1, s2
        self.alpha, self.colour, self.origin, self.edge, self.dims = alpha, colour, origin, edge, dims

    def __len__(self) -> int:
        return len(self.keys)

    @property
    def centres(self) -> np.ndarray:
        """(N, 3) mean position of each cell's samples (world metres)."""
        return self.origin + self.s1 / self.n[:, None]


def cell_keys(points: np.ndarray, edge: float):
    """(keys (M,) int64, origin (3,), dims (3,)) of the grid cells of edge ``edge`` holding the points."""
    origin = points.min(0) - edge
    ijk = np.floor((points - origin) / edge).astype(np.int64)
    dims = ijk.max(0) + 2
    return (ijk[:, 0] * dims[1] + ijk[:, 1]) * dims[2] + ijk[:, 2], origin, dims


def count_cells(points: np.ndarray, edge: float) -> int:
    """Occupied cells of the grid of edge ``edge``."""
    return len(np.unique(cell_keys(points, edge)[0]))


def merge(points, alpha, colour, edge: float) -> Cells:
    """Bin samples (points (M, 3), alpha (M,), colour (M, 3)) on a grid of ``edge`` metres."""
    keys, origin, dims = cell_keys(points, edge)
    uniq, inv = np.unique(keys, return_inverse=True)
    m = len(uniq)
    rel = points - origin

    def sums(w):
        return np.bincount(inv, w, m)

    n = sums(None).astype(np.float64)
    s1 = np.stack([sums(rel[:, i]) for i in range(3)], 1)
    s2 = np.stack([np.stack([sums(rel[:, i] * rel[:, j]) for j in range(3)], 1) for i in range(3)], 1)
    col = np.stack([sums(alpha * colour[:, i]) for i in range(3)], 1)
    return Cells(uniq, n, s1, s2, sums(alpha), col, origin, float(edge), dims)


def neighbourhood_covariance(cells: Cells) -> np.ndarray:
    """(N, 3, 3) covariance (m^2) of the samples of each cell and its 26 neighbours."""
    d1, d2 = int(cells.dims[1]), int(cells.dims[2])
    n = np.zeros(len(cells))
    s1 = np.zeros((len(cells), 3))
    s2 = np.zeros((len(cells), 3, 3))
    for off in _OFFSETS:
        k = cells.keys + (off[0] * d1 + off[1]) * d2 + off[2]
        j = np.minimum(np.searchsorted(cells.keys, k), len(cells) - 1)
        hit = cells.keys[j] == k
        n[hit] += cells.n[j[hit]]
        s1[hit] += cells.s1[j[hit]]
        s2[hit] += cells.s2[j[hit]]
    m = s1 / n[:, None]
    return s2 / n[:, None, None] - m[:, :, None] * m[:, None, :]


def shapes(cov: np.ndarray, edge: float, gain: float, smin: float, smax: float):
    """(scales (N, 3) metres, rotation matrices (N, 3, 3), det +1) from covariances: the eigenvectors
    as axes, ``gain`` x sqrt(eigenvalue) clamped to [smin, smax] x ``edge`` as standard deviations."""
    lam, vec = np.linalg.eigh(cov)
    s = np.clip(gain * np.sqrt(np.maximum(lam, 0.0)), smin * edge, smax * edge)
    vec = vec.copy()
    vec[np.linalg.det(vec) < 0, :, 0] *= -1.0
    return s, vec


def view_pass(cam, rect, rgb, depth, alpha, positions: np.ndarray, tol: float, carve_tol: float):
    """What one view tells every Gaussian: ((Gaussian indices, unit directions camera ->
    Gaussian, straight display colour, weight) of those it sees -- the centre's 2 x 2 bilinear taps
    inside the crop whose depth agrees within ``tol`` metres, weighted by bilinear weight x alpha --,
    free (N,): 1 where the centre projects inside the image and each of its 4 taps holds no depth
    or one more than ``carve_tol`` behind the centre, i.e. the view looked through its place)."""
    uv, z = project(cam, positions)
    x0, y0, w, h = (int(v) for v in rect)
    in_image = (z > 0) & (uv[:, 0] > -0.5) & (uv[:, 1] > -0.5) & (uv[:, 0] < cam.width - 0.5) & \
        (uv[:, 1] < cam.height - 0.5)
    free = in_image.astype(np.float64)
    u, v = np.nan_to_num(uv[:, 0], nan=-9) - x0, np.nan_to_num(uv[:, 1], nan=-9) - y0
    ok = np.nonzero((z > 0) & (u > -1) & (v > -1) & (u < w) & (v < h))[0]
    u, v, z = u[ok], v[ok], z[ok]
    fu, fv = np.floor(u), np.floor(v)
    tu, tv = u - fu, v - fv
    d = np.asarray(depth, np.float32)
    a = np.ones_like(d) if alpha is None else np.asarray(alpha, np.float32)
    srgb = linear_to_srgb(np.asarray(rgb, np.float32))
    wsum = np.zeros(len(ok))
    csum = np.zeros((len(ok), 3))
    blocked = np.zeros(len(ok), bool)
    for dx, dy in _TAPS:
        bw = (tu if dx else 1 - tu) * (tv if dy else 1 - tv)
        x, y = fu.astype(np.int64) + dx, fv.astype(np.int64) + dy
        inside = (x >= 0) & (y >= 0) & (x < w) & (y < h)
        xi, yi = np.where(inside, x, 0), np.where(inside, y, 0)
        dz = np.where(inside, d[yi, xi], 0.0)
        blocked |= (dz > 0) & (dz <= z + carve_tol)
        wt = bw * a[yi, xi] * ((dz > 0) & (np.abs(dz - z) < tol))
        wsum += wt
        csum += wt[:, None] * srgb[yi, xi]
    free[ok[blocked]] = 0.0
    seen = wsum > 1e-6
    idx = ok[seen]
    dirs = positions[idx] - cam.center
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    return (idx, dirs, csum[seen] / wsum[seen, None], wsum[seen]), free

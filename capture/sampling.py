"""How furrow samples images and grids: the one sampler, cell centres, nearest pixel, boxes.

Beside the camera convention (``capture/camera.py``), the conventions of every lookup:

**Pixel and cell coordinates.**  furrow follows OpenCV: the centre of pixel (column i, row j) is at
(x, y) = (i, j), its area [i - 0.5, i + 0.5).  A GL texture of n texels in normalised coordinates s
puts texel i over [i / n, (i + 1) / n) with its centre at s = (i + 0.5) / n, so a furrow pixel
coordinate x is the texture coordinate s = (x + 0.5) / n (:func:`to_texcoord`, :func:`from_texcoord`).
A grid over an extent (the equirect's u and v, a voxel grid, a ground-shadow grid) has its cell k
centred at ``lo + (k + 0.5) * size``: :func:`cell_centres` (n cells tiling [lo, hi]) and
:func:`voxel_centres` (indices to world).  Grids sampled with :func:`sample_grid` are in *index*
coordinates, cell k's centre at k, on every axis: a world point p of a voxel grid is
``(p - origin) / size - 0.5`` (:func:`index_coords`).

**Nearest pixel** is ``floor(x + 0.5)`` (:func:`nearest_pixel`), never ``np.round``: numpy rounds
half to even (2.5 -> 2 but 3.5 -> 4), so ties would fall left or right by parity; ``floor(x + 0.5)``
always takes the upper pixel at a tie, which is what GL_NEAREST does (texel floor(s n) with
s n = x + 0.5).

**Filters** (:data:`FILTERS`), as a GL texture samples:

- ``"nearest"`` = GL_NEAREST: the value of cell :func:`nearest_pixel` along each axis.
- ``"linear"`` = GL_LINEAR: the 2^d cells around the point (floor(x) and floor(x) + 1 along each
  axis, weights 1 - t and t with t = x - floor(x)): bilinear on an image, trilinear on a volume.
- ``"edge"``: edge-aware, for depth and other maps where 0 means "no value" (no GL equivalent):
  linear where all 2^d cells hold a value (> 0) that agrees within ``rel`` of the smallest, else the
  nearest cell (so nothing is ever averaged across a depth edge or into a hole).

**Boundaries** (:data:`BOUNDARIES`), what a tap outside the grid reads (per axis, or one for all):

- ``"clamp"`` = CLAMP_TO_EDGE: the edge cell (a point beyond the last centre reads the edge value).
- ``"zero"`` = CLAMP_TO_BORDER with border colour 0: zero (half the edge value at x = -0.5,
  linear); cv2.remap BORDER_CONSTANT 0, scipy.ndimage "grid-constant".
- ``"wrap"`` = REPEAT: index modulo n (the equirect's longitude).

``tests/capture/test_sampling.py`` holds one table of cases, each checked against hand-computed
values, scipy.ndimage.map_coordinates and cv2.remap with the matching mode.
"""

from __future__ import annotations

import numpy as np

from capture.camera import HALF_PIXEL

#: Filters of sample_grid / sample_image (module docstring).
FILTERS = ("nearest", "linear", "edge")
#: What a tap outside the grid reads (module docstring).
BOUNDARIES = ("clamp", "zero", "wrap")
#: "edge" filter: the cells around a point are one surface when they differ by at most this
#: fraction of the smallest (capture.lens.DEPTH_AGREE_REL uses the same rule for undistorted depth).
EDGE_AGREE_REL = 0.03


def nearest_pixel(x) -> np.ndarray:
    """int64 index of the pixel (or cell) whose centre is nearest to coordinate ``x``: floor(x + 0.5)
    (ties go up, as GL_NEAREST; module docstring)."""
    return np.floor(np.asarray(x, np.float64) + HALF_PIXEL).astype(np.int64)


def to_texcoord(x, n: int) -> np.ndarray:
    """GL normalised texture coordinate of furrow pixel coordinate ``x`` in a texture of ``n`` texels."""
    return (np.asarray(x, np.float64) + HALF_PIXEL) / n


def from_texcoord(s, n: int) -> np.ndarray:
    """furrow pixel (index) coordinate of GL normalised texture coordinate ``s`` (``n`` texels)."""
    return np.asarray(s, np.float64) * n - HALF_PIXEL


def cell_centres(n: int, lo: float = 0.0, hi: float | None = None) -> np.ndarray:
    """(n,) float64 centres of ``n`` equal cells tiling [lo, hi] (default hi = lo + n: unit cells):
    lo + (k + 0.5) (hi - lo) / n.  ``cell_centres(n, 0, 1)`` are a texture's texel centres in GL's
    normalised coordinates; ``cell_centres(n, -1, 1)`` a cube face's."""
    hi = lo + n if hi is None else hi
    return lo + (np.arange(int(n)) + HALF_PIXEL) * (hi - lo) / n


def voxel_centres(ijk, origin, size, dtype=np.float64) -> np.ndarray:
    """(..., D) world centres ``origin + (ijk + 0.5) size`` of cell indices (..., D), computed in
    ``dtype`` (float64; float32 where a float32 twin must match bit for bit)."""
    return (np.asarray(origin, dtype) + (np.asarray(ijk, dtype) + dtype(HALF_PIXEL)) * dtype(size)).astype(dtype)


def cell_index(points, origin, size) -> np.ndarray:
    """(..., D) int64 index of the cell holding each point: floor((p - origin) / size) (the cell
    whose :func:`voxel_centres` is nearest)."""
    return np.floor((np.asarray(points, np.float64) - np.asarray(origin, np.float64)) / size).astype(np.int64)


def index_coords(points, origin, size) -> np.ndarray:
    """(..., D) index coordinates (cell k's centre at k) of world ``points`` in a grid of cells of
    ``size`` from ``origin``: the inverse of :func:`voxel_centres`, what :func:`sample_grid` takes."""
    return (np.asarray(points, np.float64) - np.asarray(origin, np.float64)) / size - HALF_PIXEL


def points_box(points) -> np.ndarray:
    """(2, D) float64 axis-aligned box (min, max) of (N, D) points (non-finite points ignored);
    ValueError when there is none."""
    p = np.asarray(points, np.float64)
    p = p.reshape(-1, p.shape[-1])
    p = p[np.all(np.isfinite(p), axis=1)]
    if not len(p):
        raise ValueError("no finite point to bound")
    return np.stack([p.min(axis=0), p.max(axis=0)])


def mask_box(mask) -> tuple[int, int, int, int] | None:
    """(row0, row1, col0, col1) of the rows and columns holding True in a 2-D ``mask``
    (half-open: ``mask[row0:row1, col0:col1]`` holds every True), or None when it holds none."""
    m = np.asarray(mask, bool)
    rows, cols = np.flatnonzero(m.any(axis=1)), np.flatnonzero(m.any(axis=0))
    if not len(rows):
        return None
    return int(rows[0]), int(rows[-1]) + 1, int(cols[0]), int(cols[-1]) + 1


def _per_axis(boundary, d: int) -> tuple[str, ...]:
    out = (boundary,) * d if isinstance(boundary, str) else tuple(boundary)
    if len(out) != d or any(b not in BOUNDARIES for b in out):
        raise ValueError(f"boundary must be one of {BOUNDARIES} or one per axis ({d}), got {boundary!r}")
    return out


def _index(i: np.ndarray, n: int, boundary: str) -> tuple[np.ndarray, np.ndarray | None]:
    """(index safe to read, inside mask or None) of integer cell indices ``i`` along an axis of ``n``."""
    if boundary == "wrap":
        return i % n, None
    if boundary == "clamp":
        return np.clip(i, 0, n - 1), None
    return np.clip(i, 0, n - 1), (i >= 0) & (i < n)


def _read(data: np.ndarray, idx, inside) -> np.ndarray:
    """data at the cells ``idx`` (one index array per axis), 0 where a tap is outside (zero boundary)."""
    v = data[tuple(idx)]
    ok = None
    for m in inside:
        if m is not None:
            ok = m if ok is None else ok & m
    if ok is None:
        return v
    ok = ok.reshape(ok.shape + (1,) * (v.ndim - ok.ndim))
    return np.where(ok, v, 0)


def _nearest(data, coords, bounds):
    idx, inside = zip(*(_index(nearest_pixel(coords[..., k]), data.shape[k], b) for k, b in enumerate(bounds)))
    return _read(data, idx, inside)


def _axis_taps(coords, shape, bounds):
    """Per axis k: ((lower, upper) cell index safe to read, (lower, upper) inside mask or None,
    (1 - t, t) weights) of a linear lookup."""
    out = []
    for k, b in enumerate(bounds):
        x = coords[..., k]
        lo = np.floor(x).astype(np.int64)
        t = x - lo
        (i0, m0), (i1, m1) = _index(lo, shape[k], b), _index(lo + 1, shape[k], b)
        out.append(((i0, i1), (m0, m1), (1.0 - t, t)))
    return out


def linear_taps(coords, shape, boundary="clamp") -> list[tuple[tuple, np.ndarray | None, np.ndarray]]:
    """The 2^d taps of a linear lookup at ``coords`` (..., d) in a grid of ``shape`` (its first d
    axes): per tap (index arrays, one per axis, safe to read; inside mask, None unless a zero
    boundary reaches outside; weight (...)), corners in row-major order (the upper cell of the last
    axis changes fastest).  For lookups that act on each tap before weighting (a shadow map's depth
    comparison, an edge-aware choice)."""
    coords = np.asarray(coords, np.float64)
    d = coords.shape[-1]
    axes = _axis_taps(coords, shape, _per_axis(boundary, d))
    taps = []
    for corner in range(2 ** d):
        idx, inside, w = [], None, 1.0
        for k, (ii, mm, ww) in enumerate(axes):
            up = (corner >> (d - 1 - k)) & 1
            idx.append(ii[up])
            m = mm[up]
            inside = m if inside is None else (inside if m is None else inside & m)
            w = w * ww[up]
        taps.append((tuple(idx), inside, w))
    return taps


def _corners(data, coords, bounds):
    """(values, weights) of the 2^d linear taps: lists of (..., *C) values and (...,) weights, read
    through flat indices (one gather per tap)."""
    d = coords.shape[-1]
    flat_data = data.reshape((-1,) + data.shape[d:])
    strides = [int(np.prod(data.shape[k + 1:d], dtype=np.int64)) for k in range(d)]
    values, weights = [], []
    for idx, inside, w in linear_taps(coords, data.shape, bounds):
        flat = idx[0] * strides[0]
        for k in range(1, d):
            flat = flat + idx[k] * strides[k]
        values.append(_read(flat_data, (flat,), [inside]))
        weights.append(w)
    return values, weights


def _weighted(values, weights) -> np.ndarray:
    out = 0.0
    for v, w in zip(values, weights):
        out = out + v * np.reshape(w, np.shape(w) + (1,) * (v.ndim - np.ndim(w)))
    return out


def sample_grid(data, coords, filter: str = "linear", boundary="clamp", rel: float = EDGE_AGREE_REL) -> np.ndarray:
    """``data`` (n_0, ..., n_{d-1}, *C) sampled at ``coords`` (..., d) in index coordinates (cell k's
    centre at k along axis k; module docstring): (..., *C).  ``filter`` one of FILTERS (linear: the
    result in float64 or the data's wider float), ``boundary`` one of BOUNDARIES or one per axis;
    ``rel``: the "edge" filter's agreement (single-channel data only)."""
    data = np.asarray(data)
    coords = np.asarray(coords, np.float64)
    d = coords.shape[-1]
    if data.ndim < d:
        raise ValueError(f"sample_grid: {d} coordinates for data of shape {data.shape}")
    bounds = _per_axis(boundary, d)
    if filter == "nearest":
        return _nearest(data, coords, bounds)
    if filter not in FILTERS:
        raise ValueError(f"unknown filter {filter!r}; use one of {FILTERS}")
    values, weights = _corners(data, coords, bounds)
    out = _weighted(values, weights)
    if filter == "linear":
        return out
    if data.ndim != d:
        raise ValueError("the edge filter samples single-channel data")
    taps = np.stack(values)
    lo, hi = taps.min(axis=0), taps.max(axis=0)
    smooth = (lo > 0) & (hi - lo <= rel * lo)
    return np.where(smooth, out, _nearest(data, coords, bounds))


def sample_image(img, x, y, filter: str = "linear", boundary="clamp", rel: float = EDGE_AGREE_REL) -> np.ndarray:
    """Image ``img`` (H, W[, C]) at furrow pixel coordinates ``x`` (column) and ``y`` (row), arrays
    of one shape S: (*S[, C]).  :func:`sample_grid` on the (row, column) axes; ``boundary`` one for
    both or (rows, columns)."""
    xy = np.broadcast_arrays(np.asarray(y, np.float64), np.asarray(x, np.float64))
    return sample_grid(img, np.stack(xy, axis=-1), filter, boundary, rel)

"""The voxel cube shared by every level of the pyramid (docs/methods.md §1.1).

A level of resolution L covers the cube ``origin + [0, L*w]^3``; voxel (i, j, k) (x, y, z
order) has its centre at ``origin + (ijk + 0.5) * w``.  All levels share origin and extent,
so level L/2's voxel (i, j, k) is the union of level L's voxels (2i..2i+1, ...).
"""

from __future__ import annotations

import numpy as np

#: Extra room around the object's bounds, as a fraction of their largest side, so that the
#: surface never touches the cube's border (the SDF must change sign inside the cube).
CUBE_MARGIN = 0.06


def cube_for_bounds(bounds: np.ndarray, margin: float = CUBE_MARGIN) -> tuple[np.ndarray, float]:
    """(origin (3,), extent) of the axis-aligned cube centred on ``bounds`` (2, 3), grown by margin."""
    b = np.asarray(bounds, dtype=np.float64)
    if b.shape != (2, 3) or not np.all(np.isfinite(b)) or np.any(b[1] <= b[0]):
        raise ValueError(f"bounds must be a finite (2, 3) [min, max] box, got {b.tolist()}")
    side = float((b[1] - b[0]).max()) * (1.0 + 2.0 * margin)
    centre = 0.5 * (b[0] + b[1])
    return centre - 0.5 * side, side


def voxel_centers_of(ijk, origin, voxel_size: float) -> np.ndarray:
    """(..., 3) float64 world centres ``origin + (ijk + 0.5) w`` of voxel indices (..., 3)."""
    return np.asarray(origin, np.float64) + (np.asarray(ijk) + 0.5) * voxel_size


def voxel_centers(origin: np.ndarray, voxel_size: float, resolution: int, start: int = 0,
                  stop: int | None = None, dtype=np.float64) -> np.ndarray:
    """World centres (M, 3) of the voxels with flat index in [start, stop) (C order over i, j, k)."""
    L = int(resolution)
    stop = L ** 3 if stop is None else stop
    flat = np.arange(start, stop, dtype=np.int64)
    i, rem = np.divmod(flat, L * L)
    j, k = np.divmod(rem, L)
    ijk = np.stack([i, j, k], axis=1).astype(dtype)
    return (np.asarray(origin, dtype) + (ijk + dtype(0.5)) * dtype(voxel_size)).astype(dtype)

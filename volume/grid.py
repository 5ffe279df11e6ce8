"""The voxel cube shared by every level of the pyramid (docs/methods.md §1.1).

A level of resolution L covers the cube ``origin + [0, L*w]^3``; voxel (i, j, k) (x, y, z
order) has its centre at ``origin + (ijk + 0.5) * w`` (capture.sampling.voxel_centres).  All
levels share origin and extent, so level L/2's voxel (i, j, k) is the union of level L's voxels
(2i..2i+1, ...).
"""

from __future__ import annotations

import numpy as np

from capture.sampling import voxel_centres

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


def voxel_centers(origin: np.ndarray, voxel_size: float, resolution: int, start: int = 0,
                  stop: int | None = None, dtype=np.float64) -> np.ndarray:
    """World centres (M, 3) of the voxels with flat index in [start, stop) (C order over i, j, k),
    computed in ``dtype`` (capture.sampling.voxel_centres)."""
    L = int(resolution)
    stop = L ** 3 if stop is None else stop
    return voxel_centres(flat_voxel_indices(np.arange(start, stop, dtype=np.int64), L), origin, voxel_size, dtype)


def flat_voxel_indices(flat: np.ndarray, resolution: int) -> np.ndarray:
    """(M, 3) int64 (i, j, k) of flat voxel indices (C order) of a cube of ``resolution``^3."""
    L = int(resolution)
    i, rem = np.divmod(np.asarray(flat, np.int64), L * L)
    j, k = np.divmod(rem, L)
    return np.stack([i, j, k], axis=1)

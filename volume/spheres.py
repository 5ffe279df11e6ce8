"""Occluder sphere sets from the signed distance volume (docs/methods.md §3).

Greedy maximal-ball cover: every interior voxel (d < 0) is a candidate sphere with its centre
at the voxel centre and radius -d + RADIUS_PAD_VOXELS * w (about the largest ball there that
stays inside the solid).  Repeatedly take the uncovered interior voxel with the largest
radius, add its sphere and mark the interior voxels whose centres it contains, until the
volume IoU between the union of spheres and the solid (both sampled at the voxel centres)
reaches 1 - ``error``.  The count is therefore chosen by the error target, not fixed.
"""

from __future__ import annotations

import numpy as np

from capture.sampling import points_box
from volume.grid import voxel_centers
from volume.model import SdfLevel, SphereSet

#: Hard cap on the number of spheres (the SSDF shader loops over all of them).
MAX_SPHERES = 4096
#: Radii are -d plus this many voxels: the distance at a voxel centre understates the ball that
#: fits around the voxel by up to half a voxel diagonal (0.87); 0.5 keeps the union close to the
#: solid (the IoU check counts any overshoot).
RADIUS_PAD_VOXELS = 0.5
#: Pads tried in turn (see fit_spheres).
RADIUS_PADS = (RADIUS_PAD_VOXELS, 0.0)


def union_mask(centers: np.ndarray, radii: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(M,) bool: points inside at least one sphere (reference, O(M * N) in chunks)."""
    out = np.zeros(len(points), bool)
    for s in range(0, len(centers), 256):
        c, r = centers[s:s + 256], radii[s:s + 256]
        d2 = ((points[:, None, :] - c[None]) ** 2).sum(-1)
        out |= (d2 <= r[None] ** 2).any(1)
    return out


def volume_iou(spheres: SphereSet, level: SdfLevel) -> float:
    """IoU of the union of spheres with the solid (d < 0), sampled at every voxel centre."""
    L, w = level.resolution, level.voxel_size
    solid = level.values.reshape(-1) < 0
    if not solid.any():
        return 1.0 if len(spheres) == 0 else 0.0
    pts = voxel_centers(level.origin, w, L)
    # only voxels inside the spheres' bounding box can be covered
    inside = np.zeros(L ** 3, bool)
    if len(spheres):
        r = spheres.radii[:, None]
        lo, hi = points_box(np.concatenate([spheres.centers - r, spheres.centers + r]))
        box = np.all((pts >= lo) & (pts <= hi), axis=1)
        inside[box] = union_mask(spheres.centers, spheres.radii, pts[box])
    inter = (inside & solid).sum()
    union = (inside | solid).sum()
    return float(inter) / float(union)


def fit_spheres(level: SdfLevel, error: float, max_spheres: int = MAX_SPHERES) -> tuple[SphereSet, float]:
    """Greedy cover (module docstring) until 1 - IoU <= error; returns (spheres, 1 - IoU).

    When the padded spheres overshoot the solid so much that the target cannot be reached,
    the cover is redone without the pad (spheres strictly inside); the best result is returned
    (its error can exceed the target when even that fails: the caller reports it).
    """
    best = None
    for pad in RADIUS_PADS:
        sph, err = _greedy_cover(level, error, max_spheres, pad)
        if best is None or err < best[1]:
            best = (sph, err)
        if err <= error:
            return sph, err
    return best


def _greedy_cover(level: SdfLevel, error: float, max_spheres: int, pad_voxels: float) -> tuple[SphereSet, float]:
    """One greedy cover with radii -d + pad_voxels * w.

    The IoU is tracked exactly and incrementally over all voxel centres (a KD-tree of them
    answers which centres each new sphere covers); :func:`volume_iou` is the brute-force
    reference it is tested against.
    """
    from scipy.spatial import cKDTree

    if not 0 <= error < 1:
        raise ValueError(f"--sphere-error must be in [0, 1), got {error}")
    v = level.values
    if v is None:
        raise ValueError(f"level {level.resolution} has no signed distance values")
    L, w = level.resolution, level.voxel_size
    flat = v.reshape(-1)
    solid = flat < 0
    n_solid = int(solid.sum())
    if n_solid == 0:
        return SphereSet(np.zeros((0, 3)), np.zeros(0)), 0.0
    idx = np.arange(L ** 3)
    pts = voxel_centers(level.origin, w, L)
    sub = idx
    tree = cKDTree(pts[sub])
    sub_solid = solid[sub]
    order = np.nonzero(sub_solid)[0]
    rad_all = -flat[sub].astype(np.float64) + pad_voxels * w
    order = order[np.argsort(-rad_all[order], kind="stable")]
    covered = np.zeros(len(sub), bool)
    inter = 0  # covered solid voxels
    extra = 0  # covered non-solid voxels
    centers, radii = [], []
    ptr = 0
    err = 1.0
    while err > error and len(centers) < max_spheres:
        while ptr < len(order) and covered[order[ptr]]:
            ptr += 1
        if ptr >= len(order):
            break
        q = order[ptr]
        c, r = pts[sub[q]], rad_all[q]
        centers.append(c)
        radii.append(r)
        hit = np.asarray(tree.query_ball_point(c, r), dtype=np.int64)
        new = hit[~covered[hit]]
        covered[new] = True
        inter += int(sub_solid[new].sum())
        extra += int((~sub_solid[new]).sum())
        if not covered[q]:  # the centre is always covered
            covered[q] = True
            inter += 1
        err = 1.0 - inter / (n_solid + extra)
    sph = SphereSet(np.array(centers).reshape(-1, 3), np.array(radii))
    return sph, err

"""Known pose perturbations for registration tests and benchmarks (seeded)."""

from __future__ import annotations

import numpy as np

from capture.camera import invert_rigid
from capture.rotations import rotation


def perturb_poses(poses: list[np.ndarray], rot_deg: float, trans_m: float, center: np.ndarray,
                  seed: int = 0, keep: tuple[int, ...] = (0,)) -> list[np.ndarray]:
    """Move every camera (except ``keep``) by a rotation of exactly ``rot_deg`` about a random axis
    through ``center`` and a translation of exactly ``trans_m`` in a random direction.

    Args/returns: (4, 4) OpenCV cam_from_world poses.
    """
    rng = np.random.default_rng(seed)
    c = np.asarray(center, dtype=np.float64)
    out = []
    for k, p in enumerate(poses):
        if k in keep:
            out.append(np.array(p, dtype=np.float64))
            continue
        ax = rng.normal(size=3)
        dr = rng.normal(size=3)
        dr /= np.linalg.norm(dr)
        M = np.eye(4)
        M[:3, :3] = rotation(ax, np.radians(rot_deg))
        M[:3, 3] = c - M[:3, :3] @ c + trans_m * dr
        # world_from_cam' = M @ world_from_cam
        out.append(invert_rigid(M @ invert_rigid(np.asarray(p, dtype=np.float64))))
    return out

"""Accuracy of a signed distance volume against ground truth (tests and `furrow bench model`).

* surface-voxel precision / recall / F1: both sets use the same rule, |d| <= half the voxel
  diagonal (docs/methods.md §1.1 step 2), on the same grid;
* sign accuracy over the voxels within ``band_voxels`` voxels of the true surface (far voxels
  are trivially right and would hide the differences);
* mean |d - d_gt| over voxels within one voxel of the true surface, in voxels.
Ground truth from a triangle mesh (gt/mesh.ply of a synthetic capture) uses Open3D's
RaycastingScene: unsigned distance to the triangles, sign from its occupancy test.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from volume.grid import voxel_centers
from volume.pyramid import SURFACE_DIAGONAL_FRACTION

#: Sign accuracy is measured within this many voxels of the true surface.
SIGN_BAND_VOXELS = 3.0


def surface_mask(values: np.ndarray, voxel_size: float) -> np.ndarray:
    return np.abs(values) <= SURFACE_DIAGONAL_FRACTION * np.sqrt(3.0) * voxel_size


def sdf_scores(values: np.ndarray, gt: np.ndarray, voxel_size: float) -> dict:
    """Precision, recall, F1 of surface voxels, sign accuracy near the surface, distance error."""
    s, g = surface_mask(values, voxel_size), surface_mask(gt, voxel_size)
    tp = int((s & g).sum())
    p = tp / max(int(s.sum()), 1)
    r = tp / max(int(g.sum()), 1)
    near = np.abs(gt) < SIGN_BAND_VOXELS * voxel_size
    sign = float(((values > 0) == (gt > 0))[near].mean()) if near.any() else 1.0
    at = np.abs(gt) < voxel_size
    err = float(np.abs(values - gt)[at].mean() / voxel_size) if at.any() else 0.0
    return {"precision": p, "recall": r, "f1": 2 * p * r / max(p + r, 1e-12), "sign_accuracy": sign,
            "dist_error_voxels": err, "surface_voxels": int(s.sum()), "gt_surface_voxels": int(g.sum())}


def mesh_sdf(verts: np.ndarray, faces: np.ndarray, origin, voxel_size: float, resolution: int,
             nsamples: int = 3) -> np.ndarray:
    """(L, L, L) float32 signed distance of a triangle mesh at the voxel centres (Open3D)."""
    import open3d as o3d

    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(np.ascontiguousarray(verts, np.float32)),
                        o3d.core.Tensor(np.ascontiguousarray(faces, np.uint32)))
    x = voxel_centers(origin, voxel_size, resolution, dtype=np.float32)
    q = o3d.core.Tensor(x)
    dist = scene.compute_distance(q).numpy()
    occ = scene.compute_occupancy(q, nsamples=nsamples).numpy() > 0.5
    L = int(resolution)
    return np.where(occ, -dist, dist).astype(np.float32).reshape(L, L, L)


def read_ply_mesh(path) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (V, 3) float32, faces (F, 3) int32) of a triangle mesh file (Open3D reader);
    FileNotFoundError / ValueError naming the file when it is missing / has no triangles."""
    import open3d as o3d

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: mesh file not found")
    m = o3d.io.read_triangle_mesh(str(path))
    if len(m.triangles) == 0:
        raise ValueError(f"{path}: no triangles in the mesh (unreadable or empty)")
    return np.asarray(m.vertices, np.float32), np.asarray(m.triangles, np.int32)

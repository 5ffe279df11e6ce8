"""Exact depth + colour of a triangle mesh seen by a camera, by ray casting (Open3D RaycastingScene).

The reference renderer of registration tests and benchmarks: no rasterisation, no GL, each
pixel centre's ray (OpenCV convention, ``Camera.pixel_rays``) hits the mesh exactly.
"""

from __future__ import annotations

import numpy as np

from capture.camera import Camera
from capture.scan import Scan


def raycast_scan(vertices: np.ndarray, faces: np.ndarray, camera: Camera, vertex_colors: np.ndarray | None = None,
                 name: str = "", texture_fn=None) -> Scan:
    """Ray-cast a mesh into ``camera``.

    Args:
        vertices: (V, 3) world metres. faces: (F, 3) int. vertex_colors: (V, 3) linear [0, 1] or None (grey).
        texture_fn: optional ``f(points (N, 3) world) -> (N, 3)`` linear colour at the hit points
            (a solid texture; overrides ``vertex_colors``).
    Returns:
        a :class:`Scan` with z-depth (0 = miss) and float32 linear colour (barycentric interpolation).
    """
    import open3d as o3d

    v = np.asarray(vertices, dtype=np.float32)
    f = np.asarray(faces, dtype=np.uint32)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(v), o3d.core.Tensor(f))
    uv = camera.pixel_grid().reshape(-1, 2)
    d_cam = camera.pixel_rays(uv)  # z = 1: the hit distance t is the z-depth
    wfc = camera.world_from_cam
    d_w = d_cam @ wfc[:3, :3].T
    o_w = np.broadcast_to(wfc[:3, 3], d_w.shape)
    rays = np.concatenate([o_w, d_w], axis=1).astype(np.float32)
    hit = scene.cast_rays(o3d.core.Tensor(rays))
    t = hit["t_hit"].numpy().astype(np.float64)
    miss = ~np.isfinite(t)
    depth = np.where(miss, 0.0, t).reshape(camera.height, camera.width).astype(np.float32)
    rgb = np.full((len(t), 3), 0.5, dtype=np.float32)
    if vertex_colors is not None:
        prim = hit["primitive_ids"].numpy().astype(np.int64)
        bu = hit["primitive_uvs"].numpy().astype(np.float64)
        ok = ~miss
        tri = f[prim[ok]].astype(np.int64)
        c = np.asarray(vertex_colors, dtype=np.float64)
        w0 = 1.0 - bu[ok, 0] - bu[ok, 1]
        rgb[ok] = (c[tri[:, 0]] * w0[:, None] + c[tri[:, 1]] * bu[ok, 0:1] + c[tri[:, 2]] * bu[ok, 1:2])
    if texture_fn is not None:
        ok = ~miss
        hits = o_w[ok] + d_w[ok] * t[ok, None]
        rgb[ok] = np.asarray(texture_fn(hits), dtype=np.float32)
    rgb[miss] = 0.0
    return Scan(rgb.reshape(camera.height, camera.width, 3), depth, camera, name)

"""Exact depth + colour of a triangle mesh seen by a camera, by ray casting (``capture.raycast``).

The reference renderer of registration tests and benchmarks: no rasterisation, no GL, each
pixel centre's ray (OpenCV convention, ``Camera.pixel_rays``) hits the mesh exactly.
"""

from __future__ import annotations

import numpy as np

from capture.camera import Camera
from capture.raycast import cast_pixel_rays, mesh_scene
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
    f = np.asarray(faces, dtype=np.uint32)
    z, hit = cast_pixel_rays(mesh_scene(vertices, f), camera)
    miss = ~np.isfinite(hit["t_hit"].numpy())
    depth = z.reshape(camera.height, camera.width).astype(np.float32)
    rgb = np.full((len(z), 3), 0.5, dtype=np.float32)
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
        hits = camera.unproject(camera.pixel_grid().reshape(-1, 2)[ok], z[ok])
        rgb[ok] = np.asarray(texture_fn(hits), dtype=np.float32)
    rgb[miss] = 0.0
    return Scan(rgb.reshape(camera.height, camera.width, 3), depth, camera, name)

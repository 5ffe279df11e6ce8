"""Exact z-depth of a triangle mesh seen by cameras, by ray casting (Open3D RaycastingScene):
one unit ray from the camera centre through every pixel centre (OpenCV convention,
``Camera.pixel_rays``), no rasterisation and no GL. Used for RGBz geometry depth
(``volume.rgbz``), the fixed-mesh baseline's textures and the registration test scenes."""

from __future__ import annotations

import numpy as np

from capture.camera import Camera


def mesh_scene(vertices: np.ndarray, faces: np.ndarray):
    """Open3D ``RaycastingScene`` holding the triangles (vertices (V, 3) metres, faces (F, 3) int)."""
    import open3d as o3d

    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(np.ascontiguousarray(vertices, np.float32)),
                        o3d.core.Tensor(np.ascontiguousarray(faces, np.uint32)))
    return scene


def unit_pixel_rays(camera: Camera) -> np.ndarray:
    """(H*W, 3) float32 unit camera-frame ray of every pixel centre, row by row."""
    rays_c = camera.pixel_rays(camera.pixel_grid()).reshape(-1, 3)
    return (rays_c / np.linalg.norm(rays_c, axis=1, keepdims=True)).astype(np.float32)


def cast_pixel_rays(scene, camera: Camera, dirs_c: np.ndarray | None = None) -> tuple[np.ndarray, dict]:
    """(z-depth (H*W,) float32, 0 = miss; Open3D's answer dict) of every pixel centre's ray.
    ``dirs_c``: the camera's :func:`unit_pixel_rays` when already computed (cameras with equal
    intrinsics share them)."""
    import open3d as o3d

    dirs_c = unit_pixel_rays(camera) if dirs_c is None else dirs_c
    rays = np.empty((len(dirs_c), 6), np.float32)
    rays[:, :3] = camera.center
    rays[:, 3:] = dirs_c @ camera.cam_from_world[:3, :3].astype(np.float32)  # R^T applied to row vectors
    ans = scene.cast_rays(o3d.core.Tensor(rays))
    t = ans["t_hit"].numpy()
    return np.where(np.isfinite(t), t * dirs_c[:, 2], np.float32(0)), ans


def raycast_depth(verts: np.ndarray, faces: np.ndarray, cameras) -> np.ndarray:
    """(N, H, W) float32 z-depth of the mesh in every camera (0 = miss)."""
    N = len(cameras)
    H, W = (cameras[0].height, cameras[0].width) if N else (0, 0)
    out = np.zeros((N, H, W), np.float32)
    if len(faces) == 0 or N == 0:
        return out
    scene = mesh_scene(verts, faces)
    dirs_cache: dict = {}
    for n, cam in enumerate(cameras):
        key = cam.K.tobytes()
        if key not in dirs_cache:
            dirs_cache[key] = unit_pixel_rays(cam)
        out[n] = cast_pixel_rays(scene, cam, dirs_cache[key])[0].reshape(H, W)
    return out

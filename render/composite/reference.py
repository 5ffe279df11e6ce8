"""Numpy twin of ``composite_frag.glsl`` (:func:`composite_reference`) and the exact sphere scene the
compositing tests and ``furrow bench glare`` use (:func:`raycast_sphere`)."""

from __future__ import annotations

import numpy as np

from capture.camera import Camera
from render.composite.ground_shadow import GroundPlane, ratio_lookup
from render.shading.envmap import EnvMap


def pixel_world_dirs(camera: Camera) -> np.ndarray:
    """(H, W, 3) world direction (not unit) of every pixel centre: R^T K^-1 (u, v, 1)."""
    return camera.pixel_rays(camera.pixel_grid()) @ camera.cam_from_world[:3, :3]


def raycast_sphere(camera: Camera, centre, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Analytic ray-sphere hit per pixel: z-depth (H, W) in metres and world normals (H, W, 3),
    0 off the sphere (the exact scene the compositing tests and ``furrow bench glare`` use)."""
    centre = np.asarray(centre, np.float64)
    d = pixel_world_dirs(camera)
    dn = d / np.linalg.norm(d, axis=-1, keepdims=True)
    o = camera.center - centre
    b = dn @ o
    disc = b**2 - (o @ o - radius**2)
    hit = disc > 0
    t = np.where(hit, -b - np.sqrt(np.maximum(disc, 0)), 0)
    P = camera.center + t[..., None] * dn
    z = np.where(hit, (P - camera.center) @ camera.forward, 0.0)
    n = np.where(hit[..., None], (P - centre) / radius, 0.0)
    return z, n


def composite_reference(rgb, depth, camera: Camera, env: EnvMap, exposure: float = 1.0,
                        ground: GroundPlane | None = None, ratio_grid=None, normals=None, spec=None,
                        sources=None, alpha=None) -> np.ndarray:
    """(H, W, 3) float64 numpy twin of composite_frag.glsl: exposure x (premult object + alpha x its
    light-reflection map when normals / spec / sources are given, + (1 - alpha) x the environment
    in the pixel's direction, times the ground shadow ratio).  Without ``alpha``: ``rgb`` straight,
    alpha = depth > 0; with it, ``rgb`` premultiplied (render.composite.gl.premultiplied_rgba)."""
    from render.composite.gl import premultiplied_rgba

    H, W = camera.height, camera.width
    rgba = premultiplied_rgba(rgb, depth, alpha, H, W).astype(np.float64)
    rgb, a = rgba[..., :3], rgba[..., 3:]
    d = pixel_world_dirs(camera)
    rgb = np.asarray(rgb, np.float64)
    if spec is not None and sources is not None:
        from render.shading.glare_maps import light_reflection_map

        view = -d / np.linalg.norm(d, axis=-1, keepdims=True)
        rgb = rgb + a * light_reflection_map(normals, view, np.where((np.asarray(depth) > 0)[..., None], spec, 0.0),
                                             sources)
    col = env.sample(d)
    if ground is not None and ratio_grid is not None:
        eye = camera.center
        hit = (d[..., 2] < 0) & (eye[2] > ground.height)
        t = np.where(hit, (ground.height - eye[2]) / np.where(hit, d[..., 2], -1.0), 0.0)
        xy = eye[:2] + t[..., None] * d[..., :2]
        col = np.where(hit[..., None], col * ratio_lookup(ratio_grid, ground, xy), col)
    return exposure * (rgb + (1.0 - a) * col)

"""Compositing a captured object into an environment (issue 6 item 6; seed 004 Eq. 16-17):
the background seen through a camera from the environment map, exposure and tone mapping, and
the object's shadow on a ground plane as the ratio of occluded to unoccluded irradiance
(spherical-Gaussian lighting, SSDF visibility from the object's sphere set, analytic ground)
multiplied onto the background. Pieces only: wiring them into ``furrow render --env`` is the
renderer's job.
"""

from __future__ import annotations

import numpy as np

from render.shading.envmap import EnvMap
from render.shading.sg import COS_LOBE_LAMBDA, COS_LOBE_MU, fh_fit, sg_product
from render.shading.ssdf import ssdf_ground, ssdf_spheres

LUMA = np.array([0.2126, 0.7152, 0.0722])


def view_directions(camera) -> np.ndarray:
    """(H, W, 3) unit world directions of the camera's pixel rays (capture.camera.Camera)."""
    rays = camera.pixel_rays(camera.pixel_grid())
    d = rays @ camera.world_from_cam[:3, :3].T
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def background(env: EnvMap, camera) -> np.ndarray:
    """(H, W, 3) float32 linear radiance of the environment seen through ``camera``."""
    return env.sample(view_directions(camera)).astype(np.float32)


def tonemap(img, exposure: float = 1.0, mode: str = "reinhard") -> np.ndarray:
    """Linear display values in [0, 1]: exposure then 'clamp' or 'reinhard' (x / (1 + x) on
    luminance, hue kept)."""
    x = np.asarray(img, np.float64) * float(exposure)
    if mode == "clamp":
        return np.clip(x, 0, 1).astype(np.float32)
    if mode != "reinhard":
        raise ValueError(f"tonemap: unknown mode {mode!r} (clamp, reinhard)")
    lum = x @ LUMA
    scale = np.where(lum > 0, 1.0 / (1.0 + lum), 1.0)
    return np.clip(x * scale[..., None], 0, 1).astype(np.float32)


def ground_hits(camera, plane_z: float = 0.0):
    """(points (H, W, 3), hit (H, W) bool): where the pixel rays meet the plane z = plane_z in
    front of the camera (camera above the plane)."""
    d = view_directions(camera)
    o = camera.center
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (plane_z - o[2]) / d[..., 2]
    hit = np.isfinite(t) & (t > 0)
    pts = o + np.where(hit, t, 0.0)[..., None] * d
    return pts, hit


def sg_irradiance_visible(points, normal, axes, lams, mus, centers, radii, ground_z=None) -> np.ndarray:
    """(P, 3) diffuse irradiance of SG lighting (K lobes) at points with one shared unit normal,
    with visibility: the light-times-cosine product SGs (seed 004 Eq. 11-15) integrated with the
    fitted f_h at the SSDF of their axes (spheres, plus the analytic ground plane z=ground_z)."""
    x = np.atleast_2d(np.asarray(points, np.float64))
    n = np.asarray(normal, np.float64) / np.linalg.norm(normal)
    pa, pl, pm = sg_product(np.asarray(axes, np.float64), np.asarray(lams, np.float64),
                            np.asarray(mus, np.float64), n[None], COS_LOBE_LAMBDA, COS_LOBE_MU)
    s = ssdf_spheres(x, np.broadcast_to(n, x.shape), pa, centers, radii) if len(np.atleast_1d(radii)) \
        else np.full((len(x), len(pl)), np.pi / 2)
    if ground_z is not None:
        s = np.minimum(s, ssdf_ground(pa)[None])
    f = fh_fit(s, pl[None])  # (P, K)
    return f @ pm


def ground_shadow_ratio(points, axes, lams, mus, centers, radii, ground_z: float = 0.0) -> np.ndarray:
    """(P,) seed 004 Eq. 16-17: occluded / unoccluded luminance irradiance on the ground plane
    (normal +z) at ``points``; 1 where nothing occludes, smaller in the object's shadow."""
    up = np.array([0.0, 0.0, 1.0])
    occ = sg_irradiance_visible(points, up, axes, lams, mus, centers, radii, ground_z) @ LUMA
    free = sg_irradiance_visible(points, up, axes, lams, mus, np.zeros((0, 3)), np.zeros(0), ground_z) @ LUMA
    return np.clip(np.where(free > 0, occ / np.where(free > 0, free, 1.0), 1.0), 0.0, 1.0)


def ground_shadow_ratio_raycast(env: EnvMap, points, vertices, faces) -> np.ndarray:
    """Reference for :func:`ground_shadow_ratio`: the exact pixel sum of L cos V Omega with V
    ray-cast against the object's mesh, over the same sum without the object (ground normal +z)."""
    from render.shading.ssdf import raycast_visibility

    d = env.pixel_directions().reshape(-1, 3)
    w = (env.data.reshape(-1, 3).astype(np.float64) @ LUMA) * env.pixel_solid_angles().reshape(-1) \
        * np.maximum(d[:, 2], 0)
    up = d[:, 2] > 0
    vis = raycast_visibility(vertices, faces, np.atleast_2d(points), d[up])
    return (vis.astype(np.float64) @ w[up]) / w[up].sum()


def composite(bg, obj_rgb=None, obj_alpha=None, shadow=None, ground=None) -> np.ndarray:
    """(H, W, 3): background times the shadow ratio on the ground pixels, then the object over it
    (premultiplied-free 'over' with alpha in [0, 1])."""
    out = np.asarray(bg, np.float64).copy()
    if shadow is not None:
        s = np.asarray(shadow, np.float64)
        out = out * (np.where(ground, s, 1.0)[..., None] if ground is not None else s[..., None])
    if obj_rgb is not None:
        a = np.clip(np.asarray(obj_alpha, np.float64), 0, 1)[..., None]
        out = np.asarray(obj_rgb, np.float64) * a + out * (1 - a)
    return out.astype(np.float32)

"""A small analytic test scene for the renderers: a union of textured spheres.

Everything is exact: the signed distance (surface voxels of every level), the RGBz images
(ray-cast in float64) and a marching-cubes mesh, so renderer tests do not depend on the
volume stage.  Colour is a smooth procedural function of the world position (linear).
"""

from __future__ import annotations

import numpy as np

from capture import orbit
from capture.camera import Camera
from volume.model import Model, RgbzImages, SdfLevel, SdfPyramid, SphereSet

SPHERES = np.array([[0.0, 0.0, 0.0, 0.07], [0.055, 0.03, 0.045, 0.04], [-0.05, -0.04, -0.03, 0.045]])
BOUNDS = np.array([[-0.128, -0.128, -0.128], [0.128, 0.128, 0.128]])


def colour_at(p: np.ndarray) -> np.ndarray:
    """(N, 3) linear colour of world points (smooth stripes, different per channel)."""
    p = np.asarray(p, dtype=np.float64)
    r = 0.15 + 0.7 * (0.5 + 0.5 * np.sin(70 * p[:, 0] + 20 * p[:, 2]))
    g = 0.1 + 0.6 * (0.5 + 0.5 * np.sin(55 * p[:, 1] - 30 * p[:, 0]))
    b = 0.1 + 0.5 * (0.5 + 0.5 * np.cos(90 * p[:, 2]))
    return np.stack([r, g, b], axis=1)


def sdf(p: np.ndarray) -> np.ndarray:
    p = np.asarray(p, dtype=np.float64).reshape(-1, 3)
    d = np.linalg.norm(p[:, None, :] - SPHERES[None, :, :3], axis=2) - SPHERES[None, :, 3]
    return d.min(axis=1)


def ring_cameras(n: int, width: int = 96, height: int = 72, radius: float = 0.45, elevation_deg: float = 15.0,
                 focal: float | None = None, phase_deg: float = 0.0) -> list[Camera]:
    """n cameras on a ring around +z looking at the origin (turntable)."""
    az = [np.radians(phase_deg) + 2 * np.pi * i / n for i in range(n)]
    return orbit.ring_cameras(n, width, height, focal if focal is not None else 1.1 * width, radius,
                              (elevation_deg,), az, name="cam_{:03d}.png")


def raycast(cam: Camera) -> tuple[np.ndarray, np.ndarray]:
    """Exact (H, W, 3) linear colour and (H, W) z-depth (0 = background) of the spheres."""
    rays = cam.pixel_rays(cam.pixel_grid().reshape(-1, 2)) @ cam.world_from_cam[:3, :3].T
    o = cam.center
    best = np.full(len(rays), np.inf)
    for cx, cy, cz, r in SPHERES:
        oc = o - np.array([cx, cy, cz])
        a = (rays * rays).sum(1)
        b = 2 * rays @ oc
        c = oc @ oc - r * r
        disc = b * b - 4 * a * c
        with np.errstate(invalid="ignore"):
            t = (-b - np.sqrt(disc)) / (2 * a)
        t = np.where((disc >= 0) & (t > 0), t, np.inf)
        best = np.minimum(best, t)
    hit = np.isfinite(best)
    pts = o + np.where(hit, best, 0)[:, None] * rays
    col = np.where(hit[:, None], colour_at(pts), 0.0)
    H, W = cam.height, cam.width
    return col.reshape(H, W, 3).astype(np.float32), np.where(hit, best, 0).reshape(H, W).astype(np.float32)


def pyramid(resolutions=(4, 8, 16, 32), empty: tuple[int, ...] = ()) -> SdfPyramid:
    """Surface voxels |sdf| <= half a voxel diagonal (METHODS §1.1) on every level."""
    origin = BOUNDS[0]
    extent = float(BOUNDS[1, 0] - BOUNDS[0, 0])
    levels = []
    for L in resolutions:
        w = extent / L
        ijk = np.stack(np.meshgrid(*[np.arange(L)] * 3, indexing="ij"), -1).reshape(-1, 3)
        d = sdf(origin + (ijk + 0.5) * w)
        surf = ijk[np.abs(d) <= 0.5 * np.sqrt(3) * w] if L not in empty else np.zeros((0, 3), int)
        levels.append(SdfLevel(L, origin, w, surf.astype(np.int32)))
    return SdfPyramid(tuple(levels), resolutions[-1])


def mesh(resolution: int = 48):
    from skimage.measure import marching_cubes

    extent = float(BOUNDS[1, 0] - BOUNDS[0, 0])
    w = extent / resolution
    g = BOUNDS[0, 0] + (np.arange(resolution) + 0.5) * w
    X, Y, Z = np.meshgrid(g, g, g, indexing="ij")
    vals = sdf(np.stack([X, Y, Z], -1).reshape(-1, 3)).reshape(X.shape)
    verts, faces, _, _ = marching_cubes(vals, 0.0, spacing=(w, w, w))
    verts = verts + BOUNDS[0] + 0.5 * w
    return verts.astype(np.float32), faces[:, ::-1].astype(np.int32)


def build_model(cameras, resolutions=(4, 8, 16, 32), empty=()) -> Model:
    rgb, depth = zip(*[raycast(c) for c in cameras])
    v, f = mesh()
    return Model(pyramid=pyramid(resolutions, empty), rgbz=RgbzImages(np.stack(rgb), np.stack(depth), tuple(cameras)),
                 spheres=SphereSet(SPHERES[:, :3], SPHERES[:, 3]), mesh_vertices=v, mesh_faces=f,
                 mesh_colors=colour_at(v).astype(np.float32), bounds=BOUNDS, params={}, provenance={"scene": "spheres"})

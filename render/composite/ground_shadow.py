"""The ground shadow of a captured object (docs/methods.md §3, seed 004 Eq. 16-17): the ground plane, the
shadow ratio of its points (numpy reference of ``composite_shadow_frag.glsl``), a ray-cast reference
and the bilinear lookup of the ratio grid.

The ground plane z = h (the environment's up axis is +z). At a ground point x with the lighting as
K spherical Gaussians (seed 004: fitted with L-BFGS-B, ``render.shading.sg_fit``), each times the
clamped-cosine SG at the up normal,

    ratio(x) = sum_k mu_k f_h(min(SSDF_spheres(x, p_k), SSDF_ground(p_k)), lambda_k)
             / sum_k mu_k f_h(SSDF_ground(p_k), lambda_k)

= irradiance with the object / without it, per RGB channel (SSDF and f_h from
``render.shading.ssdf`` / ``render.shading.sg``, GLSL ``shading_ssdf.glsl`` / ``shading_sg.glsl``).
It is computed per texel of a grid over the object's surroundings (like seed 001's per-vertex SSDF,
interpolated) and multiplied onto the background pixels whose ray meets the ground; outside the
grid the ratio is 1. Reference: :func:`shadow_ratio_raycast` (Open3D ray casting against a mesh).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from capture.sampling import from_texcoord, points_box, sample_image, voxel_centres
from render.shading.sg import COS_LOBE_LAMBDA, COS_LOBE_MU, fh_fit, sg_product
from render.shading.ssdf import combine_ssdf, ssdf_ground, ssdf_spheres

#: Lighting SG lobes fitted to the environment for the shadow ratio (seed 004 uses 10).
SHADOW_SG_K = 10
#: L-BFGS-B iterations of that fit (:func:`shadow_sg_fit`).  render.shading.sg_fit's default 300 stopped the
#: studio map's fit unconverged on an AVX-512 machine (relative error 0.287 against 0.120 at 1,000 and 0.094
#: at 3,000; procedural sky 0.111 -> 0.053, forest 0.284 -> 0.239), and its ground shadow then missed the
#: ray-cast environment by a mean 0.100 / max 0.431 instead of 0.049 / 0.167 (docs/relight.md "The shadow
#: lighting's fit").  Where it already converged (sunset, courtyard) nothing moves.
SHADOW_SG_MAXITER = 1000


def shadow_sg_fit(env):
    """The SG fit of ``env`` that lights the ground shadow: SHADOW_SG_K lobes, SHADOW_SG_MAXITER iterations
    (render.shading.sg_fit.fit_env_sg), what the compositor and the viewer fit once per map."""
    from render.shading.sg_fit import fit_env_sg

    return fit_env_sg(env, SHADOW_SG_K, maxiter=SHADOW_SG_MAXITER)


#: Shadow grid: texels per side, and half-size = horizontal radius + this many object heights.
SHADOW_GRID = 128
SHADOW_EXTENT_HEIGHTS = 4.0


@dataclass(frozen=True)
class GroundPlane:
    """The ground z = ``height`` (m) and the square grid its shadow ratio is computed on.

    height: plane height along world +z (the environment's up axis), metres.
    centre: (2,) world xy of the grid centre, metres.
    half_size: half the grid's side, metres (> 0).
    resolution: texels per side.
    """

    height: float
    centre: tuple = (0.0, 0.0)
    half_size: float = 1.0
    resolution: int = SHADOW_GRID

    def __post_init__(self):
        c = tuple(float(v) for v in np.asarray(self.centre, np.float64).reshape(2))
        object.__setattr__(self, "centre", c)
        if not np.isfinite(self.height) or not np.all(np.isfinite(c)):
            raise ValueError("GroundPlane: height and centre must be finite")
        if not self.half_size > 0 or int(self.resolution) < 2:
            raise ValueError(f"GroundPlane: half_size > 0 and resolution >= 2 "
                             f"(got {self.half_size}, {self.resolution})")

    @property
    def origin(self) -> np.ndarray:
        return np.asarray(self.centre) - self.half_size

    @property
    def cell(self) -> float:
        return 2 * self.half_size / int(self.resolution)

    def grid_points(self) -> np.ndarray:
        """(G, G, 3) world texel centres; [j, i] = origin + (i + 0.5, j + 0.5) * cell."""
        t = voxel_centres(np.arange(int(self.resolution)), 0.0, self.cell)
        xx, yy = np.meshgrid(self.origin[0] + t, self.origin[1] + t)
        return np.stack([xx, yy, np.full_like(xx, self.height)], -1)


def ground_from_spheres(spheres, height: float | None = None, resolution: int = SHADOW_GRID) -> GroundPlane:
    """Ground under a sphere set: the lowest sphere point along +z (or ``height``); grid centred
    on the set's xy bounds, half-size = horizontal radius + SHADOW_EXTENT_HEIGHTS x its height."""
    c = np.asarray(spheres.centers, np.float64)
    r = np.asarray(spheres.radii, np.float64)
    if len(r) == 0:
        raise ValueError("ground_from_spheres: empty sphere set")
    lo, hi = points_box(np.concatenate([c - r[:, None], c + r[:, None]]))
    h = float(lo[2]) if height is None else float(height)
    mid = (lo[:2] + hi[:2]) / 2
    rad = float(np.max(np.linalg.norm(c[:, :2] - mid, axis=1) + r))
    return GroundPlane(h, mid, rad + SHADOW_EXTENT_HEIGHTS * max(float(hi[2]) - h, 1e-6), resolution)


# -- shadow ratio (numpy reference of composite_shadow_frag.glsl) -------------------------------------
def _cosine_products(fit):
    up = np.array([0.0, 0.0, 1.0])
    return sg_product(np.asarray(fit.axes, np.float64), np.asarray(fit.lams, np.float64),
                      np.asarray(fit.mus, np.float64), up, COS_LOBE_LAMBDA, COS_LOBE_MU)


def shadow_ratio(points, spheres, fit, plane_z: float) -> np.ndarray:
    """(P, 3) ratio of occluded to unoccluded irradiance at ground points (P, 3) (z = plane_z,
    normal +z) under the SG lighting ``fit`` (axes, lams, mus) with the sphere set's SSDF
    (seed 004 Eq. 16-17; see the module doc). 1 where the unoccluded irradiance is 0."""
    x = np.asarray(points, np.float64).reshape(-1, 3)
    p, lam, mu = _cosine_products(fit)
    tg = ssdf_ground(p)  # (K,)
    up = np.broadcast_to([0.0, 0.0, 1.0], x.shape)
    ts = (ssdf_spheres(x, up, p, spheres.centers, spheres.radii) if len(spheres)
          else np.full((len(x), len(lam)), np.pi / 2))
    occ = fh_fit(combine_ssdf(ts, tg[None]), lam[None]) @ mu  # (P, 3)
    un = fh_fit(tg, lam) @ mu  # (3,)
    return np.where(un > 0, occ / np.where(un > 0, un, 1.0), 1.0)


def spheres_mesh(spheres, resolution: int = 24):
    """(vertices (V, 3) float32, faces (F, 3) int32) of the union of the spheres (Open3D UV
    spheres, merged; not boolean-united -- enough for ray casting)."""
    import open3d as o3d

    vs, fs, off = [], [], 0
    for c, r in zip(spheres.centers, spheres.radii):
        m = o3d.geometry.TriangleMesh.create_sphere(radius=float(r), resolution=resolution)
        v = np.asarray(m.vertices) + c
        vs.append(v)
        fs.append(np.asarray(m.triangles) + off)
        off += len(v)
    return np.concatenate(vs).astype(np.float32), np.concatenate(fs).astype(np.int32)


def shadow_ratio_raycast(points, vertices, faces, radiance_fn, n_dirs: int = 4096) -> np.ndarray:
    """Reference ratio: sum L(w) max(0, w_z) V(x, w) / sum L(w) max(0, w_z) over n_dirs Fibonacci
    directions of the sphere, V by Open3D ray casting against the mesh (render.shading.ssdf).
    ``radiance_fn(dirs (D, 3)) -> (D, 3)``: the environment (``env.sample``) or its SG fit."""
    from render.shading.ssdf import fibonacci_directions, raycast_visibility

    d = fibonacci_directions(n_dirs)
    d = d[d[:, 2] > 0]
    w = np.asarray(radiance_fn(d), np.float64) * d[:, 2:3]
    vis = raycast_visibility(vertices, faces, np.asarray(points, np.float64).reshape(-1, 3), d, eps=1e-5)
    un = w.sum(0)
    return np.where(un > 0, (vis.astype(np.float64) @ w) / np.where(un > 0, un, 1.0), 1.0)


def ratio_lookup(grid, ground: GroundPlane, xy) -> np.ndarray:
    """(..., 3) bilinear lookup of a (G, G, 3) ratio grid at world xy (..., 2) as GL's LINEAR +
    CLAMP_TO_EDGE sampling does; 1 outside the grid square."""
    g = np.asarray(grid, np.float64)
    G = g.shape[0]
    uv = (np.asarray(xy, np.float64) - ground.origin) / (2 * ground.half_size)
    inside = np.all((uv >= 0) & (uv <= 1), axis=-1)
    v = sample_image(g, from_texcoord(uv[..., 0], G), from_texcoord(uv[..., 1], G), "linear", "clamp")
    return np.where(inside[..., None], v, 1.0)

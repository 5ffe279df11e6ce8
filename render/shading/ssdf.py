"""Visibility as a spherical signed distance function (SSDF) from a set of spheres
(docs/methods.md §3; seed 001 §4.4 Algorithm 1), its analytic ground plane, and the ray-cast reference.

SSDF(x, zeta): + angle from direction zeta to the nearest occluded direction when zeta is
visible from x, - angle to the nearest visible direction when occluded; capped at pi/2 (the
initial value of Algorithm 1). With occluders = spheres (c_j, r_j), the occluded directions of
sphere j form a cone around (c_j - x) of half-angle asin(r_j / |c_j - x|), so

    SSDF = min(pi/2, min_j [angle(zeta, c_j - x) - asin(r_j / |c_j - x|)])

skipping spheres that contain x, and (tangent-plane culling) spheres that lie entirely below the
tangent plane at x: n . normalize(c_j + n r_j - x) < 0. The visibility-weighted SG integral is
then ``mu * fh_fit(SSDF, lambda)`` (render.shading.sg).

Hard cases handled: x inside a sphere (skipped), x on / tangent to a sphere (asin argument
clipped to 1), zeta parallel to c_j - x (acos argument clipped). GLSL twin:
``render/shaders/shading_ssdf.glsl``. Reference: Open3D RaycastingScene against the mesh.
"""

from __future__ import annotations

import numpy as np

#: SSDF cap and initial value (Algorithm 1).
SSDF_MAX = np.pi / 2
#: Spheres per chunk of the vectorised loop (memory: points x chunk x axes floats).
SSDF_CHUNK = 64


def ssdf_spheres(points, normals, axes, centers, radii, cull: bool = True) -> np.ndarray:
    """(P, K) SSDF at points (P,3) with normals (P,3) (used only for culling; may be None when
    cull=False) for axes (K,3) or per-point axes (P,K,3), spheres centers (S,3), radii (S,)."""
    x = np.asarray(points, np.float64)
    z = np.asarray(axes, np.float64)
    per_point = z.ndim == 3
    c = np.asarray(centers, np.float64).reshape(-1, 3)
    r = np.asarray(radii, np.float64).reshape(-1)
    P = len(x)
    K = z.shape[1] if per_point else z.shape[0]
    out = np.full((P, K), SSDF_MAX)
    if cull:
        n = np.asarray(normals, np.float64)
    for a in range(0, len(c), SSDF_CHUNK):
        cc, rr = c[a:a + SSDF_CHUNK], r[a:a + SSDF_CHUNK]
        d = cc[None] - x[:, None]  # (P, S, 3)
        dist = np.linalg.norm(d, axis=-1)
        ok = dist > rr[None]  # skip points inside (or on) a sphere
        if cull:
            top = d + n[:, None] * rr[None, :, None]
            tl = np.linalg.norm(top, axis=-1)
            ok &= np.einsum("psk,pk->ps", top, n) >= 0 * tl  # sphere not entirely below the plane
        dn = d / np.where(dist > 0, dist, 1.0)[..., None]
        half = np.arcsin(np.clip(rr[None] / np.where(dist > 0, dist, 1.0), 0.0, 1.0))
        if per_point:
            cosz = np.einsum("psk,pjk->psj", dn, z)
        else:
            cosz = dn @ z.T  # (P, S, K)
        val = np.arccos(np.clip(cosz, -1.0, 1.0)) - half[..., None]
        val = np.where(ok[..., None], val, SSDF_MAX)
        out = np.minimum(out, val.min(1))
    return out


def ssdf_ground(axes, plane_z: float = 0.0, points=None) -> np.ndarray:
    """SSDF of an infinite ground plane z = plane_z seen from points above it: the occluded
    directions are those pointing down, so SSDF = elevation of zeta = asin(zeta_z), in
    [-pi/2, pi/2]. axes (K,3) -> (K,), or (P,K,3) -> (P,K). Points on or below the plane raise."""
    if points is not None and np.any(np.asarray(points, np.float64)[..., 2] < plane_z):
        raise ValueError("ssdf_ground: points below the ground plane")
    z = np.asarray(axes, np.float64)
    zz = z[..., 2] / np.linalg.norm(z, axis=-1)
    return np.arcsin(np.clip(zz, -1.0, 1.0))


def combine_ssdf(*fields) -> np.ndarray:
    """SSDF of the union of occluders: the minimum (Algorithm 1 applied to all of them)."""
    out = fields[0]
    for f in fields[1:]:
        out = np.minimum(out, f)
    return out


# -- ray-cast reference ---------------------------------------------------------------------------
def fibonacci_directions(n: int) -> np.ndarray:
    """(n, 3) nearly uniform unit directions (Fibonacci sphere); each covers 4 pi / n sr."""
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    phi = np.pi * (1 + 5**0.5) * i
    s = np.sqrt(1 - z * z)
    return np.stack([s * np.cos(phi), s * np.sin(phi), z], -1)


def raycast_visibility(vertices, faces, points, dirs, eps: float = 1e-6) -> np.ndarray:
    """(P, D) bool: True where the ray from points[p] (offset eps along the ray) in dirs[d]
    (shared (D,3) or per point (P,D,3)) hits no triangle of the mesh (Open3D RaycastingScene)."""
    import open3d as o3d

    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(np.asarray(vertices, np.float32)),
                        o3d.core.Tensor(np.asarray(faces, np.uint32)))
    x = np.asarray(points, np.float64)
    d = np.asarray(dirs, np.float64)
    if d.ndim == 2:
        d = np.broadcast_to(d[None], (len(x),) + d.shape)
    P, D = d.shape[:2]
    org = np.broadcast_to(x[:, None], (P, D, 3)) + eps * d
    rays = np.concatenate([org, d], -1).reshape(-1, 6).astype(np.float32)
    hit = np.empty(P * D, bool)
    step = 1 << 20
    for a in range(0, len(rays), step):
        ans = scene.cast_rays(o3d.core.Tensor(rays[a:a + step]))
        hit[a:a + step] = np.isfinite(ans["t_hit"].numpy())
    return ~hit.reshape(P, D)


def ssdf_from_visibility(vis, dirs, axes) -> np.ndarray:
    """Reference SSDF from sampled visibility (P, D) over directions (D, 3): for each axis,
    + angle to the nearest occluded sample if the axis' nearest sample is visible, - angle to
    the nearest visible one otherwise; capped at pi/2. Resolution ~ sqrt(4 pi / D) rad."""
    ang = np.arccos(np.clip(np.asarray(axes, np.float64) @ np.asarray(dirs, np.float64).T, -1, 1))  # (K, D)
    out = np.empty((vis.shape[0], ang.shape[0]))
    nearest = ang.argmin(1)
    for p in range(vis.shape[0]):
        v = vis[p]
        occ_ang = np.where(~v[None], ang, np.inf).min(1)
        vis_ang = np.where(v[None], ang, np.inf).min(1)
        visible = v[nearest]
        out[p] = np.where(visible, np.minimum(occ_ang, SSDF_MAX), -np.minimum(vis_ang, SSDF_MAX))
    return out


def sg_visible_integral_raycast(vis, dirs, axes, lams) -> np.ndarray:
    """(P, K) integral of G(i; axis_k, lam_k, 1) V(x_p, i) by the quadrature of uniform sample
    directions (D,3) (each 4 pi / D sr) with sampled visibility (P, D)."""
    g = np.exp(np.asarray(lams, np.float64)[:, None]
               * (np.asarray(axes, np.float64) @ np.asarray(dirs, np.float64).T - 1.0))  # (K, D)
    return (vis.astype(np.float64) @ g.T) * (4 * np.pi / len(dirs))

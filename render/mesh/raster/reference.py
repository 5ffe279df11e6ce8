"""Slow, obviously-correct numpy twin of the GL mesh rasteriser (render/mesh/raster/gl.py).

:func:`rasterize_reference` loops over triangles and tests every pixel centre (OpenCV
convention, ``camera.project``) with screen-space barycentrics, interpolates perspective-
correctly (depth = 1 / sum(b_i / z_i)) and keeps the nearest.  :func:`shade_reference` applies
the shaded mode of ``raster_shaded_frag.glsl`` to the interpolated attributes with the numpy
twins of the shading module (ambient: ``render.shading.irradiance.irradiance_lookup`` of the
irradiance table, or ``render.shading.sh.sh9_irradiance``; lobes:
``render.shading.brdf.blinn_phong_normalized``).  For small scenes only (tests).
"""

from __future__ import annotations

import numpy as np

from capture.camera import Camera
from render.mesh.raster.gl import HAIR_TANGENT_SQ, MIN_NEAR, Lighting, RasterMesh, RasterResult, face_normals
from render.shading.brdf import blinn_phong_normalized
from render.shading.irradiance import irradiance_lookup
from render.shading.sh import sh9_irradiance


def interpolate_reference(mesh: RasterMesh, camera: Camera, attrs: np.ndarray | None = None, near: float = MIN_NEAR):
    """Rasterise ``mesh`` at the pixel centres of ``camera``.

    Returns (depth (H, W) float64 with inf = background, face index (H, W) int (-1 = none),
    interpolated ``attrs`` (H, W, C) float64 (perspective-correct; C = 0 when None)).
    Triangles with a vertex nearer than ``near`` are skipped (no clipping).
    """
    H, W = camera.height, camera.width
    attrs = np.zeros((len(mesh.vertices), 0)) if attrs is None else np.asarray(attrs, np.float64)
    depth = np.full((H, W), np.inf)
    face = np.full((H, W), -1, np.int64)
    out = np.zeros((H, W, attrs.shape[1]))
    uv, z = camera.project(mesh.vertices.astype(np.float64))
    for fi, (a, b, c) in enumerate(mesh.faces):
        if min(z[a], z[b], z[c]) <= near:
            continue
        p = uv[[a, b, c]]
        area = (p[1, 0] - p[0, 0]) * (p[2, 1] - p[0, 1]) - (p[2, 0] - p[0, 0]) * (p[1, 1] - p[0, 1])
        if abs(area) < 1e-12:
            continue
        i0, i1 = max(int(np.ceil(p[:, 0].min())), 0), min(int(np.floor(p[:, 0].max())), W - 1)
        j0, j1 = max(int(np.ceil(p[:, 1].min())), 0), min(int(np.floor(p[:, 1].max())), H - 1)
        if i0 > i1 or j0 > j1:
            continue
        jj, ii = np.mgrid[j0 : j1 + 1, i0 : i1 + 1].astype(np.float64)
        # edge functions -> screen-space barycentrics
        w0 = ((p[2, 0] - p[1, 0]) * (jj - p[1, 1]) - (p[2, 1] - p[1, 1]) * (ii - p[1, 0])) / area
        w1 = ((p[0, 0] - p[2, 0]) * (jj - p[2, 1]) - (p[0, 1] - p[2, 1]) * (ii - p[2, 0])) / area
        w2 = 1.0 - w0 - w1
        inside = (w0 >= 0) & (w1 >= 0) & (w2 >= 0)
        if not inside.any():
            continue
        zs = z[[a, b, c]]
        q = np.stack([w0 / zs[0], w1 / zs[1], w2 / zs[2]], -1)  # perspective-correct weights
        zpix = 1.0 / q.sum(-1)
        sub = depth[j0 : j1 + 1, i0 : i1 + 1]
        win = inside & (zpix < sub)
        if not win.any():
            continue
        sub[win] = zpix[win]
        face[j0 : j1 + 1, i0 : i1 + 1][win] = fi
        out[j0 : j1 + 1, i0 : i1 + 1][win] = (q[win] * zpix[win][:, None]) @ attrs[[a, b, c]]
    return depth, face, out


def _facing_normals(mesh, camera, face, n_interp, pts):
    """Unit normals (interpolated, or flat where absent) turned towards the eye; (M, 3)."""
    fn = face_normals(mesh.vertices, mesh.faces)[face]
    n = n_interp if mesh.normals is not None else fn
    use = np.sum(n * n, -1) > 1e-12
    n = np.where(use[:, None], n, fn)
    n = n / np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-300)
    flip = np.sum(n * (camera.center - pts), -1) < 0
    n[flip] *= -1
    return n


def rasterize_reference(mesh: RasterMesh, camera: Camera, near: float = MIN_NEAR) -> RasterResult:
    """Unshaded reference render: per-vertex colour at the pixel centre, z-depth, normals
    facing the camera (interpolated, or flat when the mesh has none); ``alpha == mask``."""
    normals = mesh.normals if mesh.normals is not None else np.zeros_like(mesh.vertices)
    depth, face, att = interpolate_reference(mesh, camera, np.concatenate([mesh.colors, normals], 1), near)
    mask = face >= 0
    H, W = mask.shape
    normal = np.zeros((H, W, 3))
    if mask.any():
        pts = camera.unproject(camera.pixel_grid()[mask], depth[mask])
        normal[mask] = _facing_normals(mesh, camera, face[mask], att[mask][:, 3:6], pts)
    return RasterResult(color=np.where(mask[..., None], att[..., :3], 0).astype(np.float32),
                        depth=np.where(mask, depth, 0).astype(np.float32), normal=normal.astype(np.float32),
                        mask=mask, alpha=mask.astype(np.float32))


def shade_reference(mesh: RasterMesh, camera: Camera, lighting: Lighting, visibility: np.ndarray,
                    near: float = MIN_NEAR) -> np.ndarray:
    """(H, W, 3) float64 shaded colour at the pixel centres, the numpy twin of
    raster_shaded_frag.glsl; ``visibility`` (V, K) per-vertex light visibility (e.g.
    ``MeshRasterizer.vertex_visibility``)."""
    V = len(mesh.vertices)
    K = len(lighting.light_dirs)
    zeros = np.zeros((V, 3))
    att = np.concatenate([
        mesh.colors, mesh.normals if mesh.normals is not None else zeros,
        mesh.tangents if mesh.tangents is not None else zeros,
        (mesh.occlusion if mesh.occlusion is not None else np.ones(V))[:, None],
        (mesh.specular if mesh.specular is not None else np.zeros(V))[:, None],
        np.asarray(visibility, np.float64).reshape(V, K)], axis=1)
    depth, face, img = interpolate_reference(mesh, camera, att, near)
    mask = face >= 0
    a = img[mask]
    pts = camera.unproject(camera.pixel_grid()[mask], depth[mask])
    col, nrm, tan, occ, spec, vis = a[:, :3], a[:, 3:6], a[:, 6:9], a[:, 9], a[:, 10], a[:, 11:]
    view = camera.center - pts
    view /= np.linalg.norm(view, axis=-1, keepdims=True)
    N = _facing_normals(mesh, camera, face[mask], nrm, pts)
    hair = np.sum(tan * tan, -1) > HAIR_TANGENT_SQ
    T = tan / np.maximum(np.linalg.norm(tan, axis=-1, keepdims=True), 1e-300)
    if lighting.ambient == "table":
        irr = irradiance_lookup(lighting.irradiance, N) * occ[:, None]
    else:
        irr = np.maximum(sh9_irradiance(lighting.sh9, N), 0) * occ[:, None]
    specular = np.zeros_like(irr)
    for i in range(K):
        L = lighting.light_dirs[i].astype(np.float64)
        Hv = L + view
        Hv /= np.linalg.norm(Hv, axis=-1, keepdims=True)
        tl, th = T @ L, np.sum(T * Hv, -1)
        nl = np.maximum(N @ L, 0)
        cos_d = np.where(hair, np.sqrt(np.maximum(0, 1 - tl * tl)), nl)
        lobe = np.where(hair, blinn_phong_normalized(np.sqrt(np.maximum(0, 1 - th * th)), lighting.hair_shininess),
                        np.where(nl > 0,
                                 blinn_phong_normalized(np.maximum(np.sum(N * Hv, -1), 0), lighting.shininess), 0))
        c = lighting.light_colors[i].astype(np.float64)
        irr += c * (vis[:, i] * cos_d)[:, None]
        specular += c * (vis[:, i] * lobe)[:, None]
    out = np.zeros(mask.shape + (3,))
    out[mask] = lighting.exposure * (col / np.pi * irr + spec[:, None] * specular)
    return out

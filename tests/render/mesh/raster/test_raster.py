"""GL mesh rasteriser against the numpy reference rasteriser (render/mesh/raster/gl.py)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from capture.camera import Camera, look_at, make_K
from render.mesh.raster.gl import MeshRasterizer, RasterError, RasterMesh
from render.mesh.raster.reference import rasterize_reference
from tests.conftest import assert_images_close

#: Interior depth agreement GL vs numpy (metres): float32 eye-z interpolation error only.
DEPTH_TOL_M = 1e-4
#: Interior colour agreement: mean below one 8-bit level, max two levels.
COLOR_MEAN_TOL = 1.0 / 255.0
COLOR_MAX_TOL = 2.0 / 255.0
#: Interior normals: max angle between GL and numpy normals (degrees).
NORMAL_TOL_DEG = 0.5


def _box(center, size, color_seed):
    """A cube (12 triangles) with distinct per-vertex colours and no normals."""
    c = np.asarray(center, float)
    s = np.asarray(size, float) / 2
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float) * s + c
    q = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    faces = [f for a, b, cc, d in q for f in ((a, b, cc), (a, cc, d))]
    rng = np.random.default_rng(color_seed)
    return corners, np.array(faces), rng.uniform(0.1, 0.9, (8, 3))


def _scene() -> RasterMesh:
    """Overlapping boxes, a slanted quad with smooth normals and a tilted triangle, 0.2 m wide."""
    parts = [_box((0.0, 0.0, 0.0), (0.08, 0.06, 0.05), 1), _box((0.04, -0.05, 0.03), (0.05, 0.05, 0.05), 2)]
    quad = np.array([[-0.1, 0.05, -0.06], [0.02, 0.09, -0.06], [0.02, 0.06, 0.08], [-0.1, 0.02, 0.08]])
    parts.append((quad, np.array([[0, 1, 2], [0, 2, 3]]),
                  np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0]], float)))
    tri = np.array([[-0.09, -0.09, -0.04], [-0.02, -0.1, 0.0], [-0.06, -0.04, 0.07]])
    parts.append((tri, np.array([[0, 1, 2]]), np.array([[0.9, 0.5, 0.1], [0.2, 0.8, 0.3], [0.4, 0.4, 0.9]])))
    verts, faces, cols, off = [], [], [], 0
    for v, f, c in parts:
        verts.append(v)
        faces.append(f + off)
        cols.append(c)
        off += len(v)
    return RasterMesh(np.concatenate(verts), np.concatenate(faces), np.concatenate(cols))


def _smooth_sphere(n=24) -> RasterMesh:
    th, ph = np.meshgrid(np.linspace(0.15, np.pi - 0.15, n),
                         np.linspace(0, 2 * np.pi, 2 * n, endpoint=False), indexing="ij")
    d = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], -1).reshape(-1, 3)
    faces = []
    for i in range(n - 1):
        for j in range(2 * n):
            a, b = i * 2 * n + j, i * 2 * n + (j + 1) % (2 * n)
            faces += [(a, b, b + 2 * n), (a, b + 2 * n, a + 2 * n)]
    return RasterMesh(0.08 * d, np.array(faces), 0.5 + 0.4 * d, normals=d)


def _camera(W=96, H=72, az=30.0, el=25.0, cx_shift=0.0) -> Camera:
    a, e = np.radians(az), np.radians(el)
    eye = 0.45 * np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
    K = make_K(2.2 * W, 2.2 * W, (W - 1) / 2 + cx_shift, (H - 1) / 2 - 1.3)
    return Camera(K, look_at(eye, (0, 0, 0)), W, H)


def _interior(*masks):
    m = np.logical_and.reduce(masks)
    return ndimage.binary_erosion(m, iterations=1)


@pytest.fixture(scope="module")
def rast(gl_ctx):
    with MeshRasterizer(gl_ctx) as r:
        yield r


@pytest.mark.parametrize("az", [30.0, 160.0, 280.0])
def test_gl_matches_numpy_reference(rast, az):
    mesh = _scene()
    cam = _camera(az=az)
    rast.set_mesh(mesh)
    gl = rast.render(cam)
    ref = rasterize_reference(mesh, cam)
    assert ref.mask.sum() > 800, "scene must cover a good part of the image"
    inner = _interior(gl.mask, ref.mask)
    # coverage differs only in the 1-px band around the reference silhouette
    band = ndimage.binary_dilation(ref.mask) & ~ndimage.binary_erosion(ref.mask)
    assert not np.any((gl.mask ^ ref.mask) & ~band), "coverage differs away from silhouettes"
    assert np.mean(gl.mask ^ ref.mask) < 0.01
    # depth: interior pixels away from depth discontinuities (where the two may pick different faces)
    jump = ndimage.maximum_filter(ref.depth, 3) - ndimage.minimum_filter(ref.depth, 3) > 5e-3
    ok = inner & ~jump
    assert ok.sum() > 500
    dz = np.abs(gl.depth - ref.depth)[ok]
    assert dz.max() < DEPTH_TOL_M, f"max depth diff {dz.max():.2e} m"
    assert_images_close(gl.color, ref.color, mean_tol=COLOR_MEAN_TOL, max_tol=COLOR_MAX_TOL, mask=ok,
                        what="GL vs numpy colour")
    cosang = np.clip(np.sum(gl.normal * ref.normal, -1)[ok], -1, 1)
    assert np.degrees(np.arccos(cosang)).max() < NORMAL_TOL_DEG
    assert np.all(gl.depth[~gl.mask] == 0) and np.all(gl.color[~gl.mask] == 0)


@pytest.mark.parametrize("ss", [2, 3])
def test_smooth_normals_and_supersampling(gl_ctx, ss):
    mesh = _smooth_sphere()
    cam = _camera(W=80, H=60, az=10)
    ref = rasterize_reference(mesh, cam)
    with MeshRasterizer(gl_ctx, supersample=ss) as r:
        r.set_mesh(mesh)
        gl = r.render(cam)
    inner = _interior(gl.mask, ref.mask)
    assert np.abs(gl.depth - ref.depth)[inner].max() < DEPTH_TOL_M
    cosang = np.clip(np.sum(gl.normal * ref.normal, -1)[inner], -1, 1)
    assert np.degrees(np.arccos(cosang)).max() < NORMAL_TOL_DEG
    # supersampled colour = box average over the pixel: equal to the centre value on smooth interiors
    assert_images_close(gl.color, ref.color, mean_tol=COLOR_MEAN_TOL, max_tol=COLOR_MAX_TOL, mask=inner,
                        what="supersampled colour")
    # coverage fraction is fractional only on the silhouette band
    frac = (gl.alpha > 0.01) & (gl.alpha < 0.99)
    band = ndimage.binary_dilation(ref.mask, iterations=1) & ~ndimage.binary_erosion(ref.mask, iterations=1)
    assert frac.sum() > 20 and np.all(frac <= band)
    assert np.all(gl.alpha[inner] == 1.0)


def test_half_pixel_shift_is_caught(rast):
    """The comparison must see a half-pixel error in the principal point (docs/design.md)."""
    mesh = _scene()
    rast.set_mesh(mesh)
    ref = rasterize_reference(mesh, _camera())
    gl = rast.render(_camera(cx_shift=0.5))
    inner = _interior(gl.mask, ref.mask)
    assert np.abs(gl.depth - ref.depth)[inner].max() > 10 * DEPTH_TOL_M
    band = ndimage.binary_dilation(ref.mask) & ~ndimage.binary_erosion(ref.mask)
    assert np.mean((gl.mask ^ ref.mask)[band]) > 0.1


def test_release_and_errors(gl_ctx):
    r = MeshRasterizer(gl_ctx)
    with pytest.raises(RasterError, match="set_mesh"):
        r.render(_camera())
    r.release()
    r.release()
    with pytest.raises(RasterError, match="release"):
        r.set_mesh(_scene())
    with pytest.raises(RasterError, match="out of range"):
        RasterMesh(np.zeros((3, 3)), np.array([[0, 1, 3]]), np.zeros((3, 3)))


# ------------------------------------------------------------------------------ shaded mode
def _lighting(exposure=0.6, ambient="sh9"):
    from render.mesh.raster.gl import Lighting
    from render.shading.envmap import bundled_envmap, procedural_sky
    from render.shading.irradiance import irradiance_table
    from render.shading.lights import dominant_lights, env_minus_lights
    from render.shading.sh import sh9_project

    # the table test uses a real map, whose residual SH9 cannot follow (the twin test must tell them apart)
    env = procedural_sky(32) if ambient == "sh9" else bundled_envmap("studio").resized(64)
    lights = dominant_lights(env, 1)
    rest = env_minus_lights(env, 1)
    if ambient == "sh9":
        amb, scale = {"sh9": sh9_project(rest)}, float(lights.power.max())
    else:  # exposure from the ambient so that it dominates the image
        table = irradiance_table(rest, 16)
        amb, scale = {"sh9": None, "irradiance": table}, float(table.max())
    return Lighting(**amb, light_dirs=lights.dirs, light_colors=lights.power,
                    exposure=exposure / scale, shininess=30.0, hair_shininess=50.0)


def _shaded_scene() -> RasterMesh:
    """A smooth sphere with specular, plus three thick strands (tubes with tangents)."""
    from datasets_synthetic.geometry import merge, tube_sweep

    sph = _smooth_sphere()
    sph = RasterMesh(sph.vertices * 0.8, sph.faces, sph.colors, sph.normals, occlusion=np.full(len(sph.vertices), 0.7),
                     specular=np.full(len(sph.vertices), 0.3))
    s = np.linspace(0, 1, 7)[:, None]
    paths = np.stack([np.array([x, -0.02, -0.07]) + s * np.array([0.0, 0.12, 0.14]) + s**2 * np.array([0.03, 0, 0])
                      for x in (-0.03, 0.0, 0.03)])
    hair = tube_sweep(paths, np.full((3, 7), 0.006), 6, np.array([[0.7, 0.4, 0.2], [0.3, 0.3, 0.3], [0.8, 0.7, 0.5]]),
                      np.linspace(0.3, 1, 7)[None].repeat(3, 0), 0.5)
    return merge([sph, hair])


@pytest.mark.parametrize("ambient", ["sh9", "table"])
def test_shaded_gl_matches_numpy_shading(gl_ctx, ambient):
    from render.mesh.raster.reference import shade_reference

    mesh, lt = _shaded_scene(), _lighting(exposure=0.6 if ambient == "sh9" else 2.0, ambient=ambient)
    assert lt.ambient == ambient
    cam = _camera(W=160, H=120, az=40, el=20)
    with MeshRasterizer(gl_ctx) as r:
        r.set_mesh(mesh)
        r.set_lighting(lt)
        gl = r.render(cam)
        vis = r.vertex_visibility
    assert vis.shape == (len(mesh.vertices), 1) and 0.05 < vis.mean() < 0.95  # the strands shadow the sphere
    ref = shade_reference(mesh, cam, lt, vis)
    refm = rasterize_reference(mesh, cam)
    inner = _interior(gl.mask, refm.mask)
    jump = ndimage.maximum_filter(refm.depth, 3) - ndimage.minimum_filter(refm.depth, 3) > 5e-3
    ok = inner & ~jump
    assert ok.sum() > 2000 and ref[ok].max() > 0.3
    assert_images_close(gl.color, ref.astype(np.float32), mean_tol=COLOR_MEAN_TOL, max_tol=COLOR_MAX_TOL,
                        mask=ok, what="shaded GL vs numpy")
    if ambient == "table":  # the comparison can tell the table from SH9 of the same residual map
        from dataclasses import replace

        from render.shading.envmap import bundled_envmap
        from render.shading.lights import env_minus_lights
        from render.shading.sh import sh9_project

        sh = sh9_project(env_minus_lights(bundled_envmap("studio").resized(64), 1))
        ref_sh = shade_reference(mesh, cam, replace(lt, sh9=sh, irradiance=None), vis)
        assert np.abs(ref_sh - ref)[ok].mean() > 1.5 * COLOR_MEAN_TOL  # measured 1.9x


def test_shadow_map_visibility_matches_raycasting(gl_ctx):
    """Per-vertex shadow-map visibility against open3d ray casting towards the light."""
    import open3d as o3d

    from datasets_synthetic.geometry import merge, tube_sweep
    from render.mesh.raster.gl import SHADOW_BIAS_TEXELS, SHADOW_BOX_MARGIN, SHADOW_MAP_SIZE

    g = np.linspace(-0.1, 0.1, 121)
    xx, yy = np.meshgrid(g, g)
    plane_v = np.stack([xx.ravel(), yy.ravel(), np.full(xx.size, -0.08)], 1)
    idx = np.arange(121 * 121).reshape(121, 121)
    pf = np.concatenate([np.stack([idx[:-1, :-1], idx[:-1, 1:], idx[1:, 1:]], -1).reshape(-1, 3),
                         np.stack([idx[:-1, :-1], idx[1:, 1:], idx[1:, :-1]], -1).reshape(-1, 3)])
    plane = RasterMesh(plane_v, pf, np.full((len(plane_v), 3), 0.5), np.tile([0, 0, 1.0], (len(plane_v), 1)))
    sph = _smooth_sphere()
    sph = RasterMesh(sph.vertices * 0.5, sph.faces, sph.colors, sph.normals)
    rng = np.random.default_rng(0)
    s = np.linspace(0, 1, 5)[:, None]
    starts = rng.uniform(-0.08, 0.08, (40, 3)) * [1, 1, 0] + [0, 0, -0.02]
    paths = starts[:, None] + s[None] * np.array([0.0, 0.03, 0.04])
    hair = tube_sweep(paths, np.full((40, 5), 0.0004), 3, np.full((40, 3), 0.5))
    mesh = merge([plane, sph, hair])
    lt = _lighting()
    with MeshRasterizer(gl_ctx) as r:
        r.set_mesh(mesh)
        r.set_lighting(lt)
        vis = r.vertex_visibility[:, 0]
    b = mesh.bounds
    texel = float(np.linalg.norm(b[1] - b[0])) * (1 + SHADOW_BOX_MARGIN) / SHADOW_MAP_SIZE
    L = lt.light_dirs[0].astype(np.float64)
    rc = o3d.t.geometry.RaycastingScene()
    rc.add_triangles(o3d.core.Tensor(mesh.vertices), o3d.core.Tensor(mesh.faces.astype(np.uint32)))
    origin = mesh.vertices + SHADOW_BIAS_TEXELS * texel * L
    rays = np.concatenate([origin, np.broadcast_to(L, origin.shape)], 1).astype(np.float32)
    lit = ~np.isfinite(rc.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy())
    on_plane = np.arange(len(mesh.vertices)) < len(plane_v)
    # plane vertices away from shadow edges (all 4-neighbours agree in the ray-cast answer)
    lg = lit[on_plane].reshape(121, 121)
    stable = ndimage.binary_erosion(lg, border_value=1) | ndimage.binary_erosion(~lg, border_value=1)
    agree = (vis[on_plane].reshape(121, 121) > 0.5) == lg
    assert (~lg).sum() > 500 and (~lg & ~ndimage.binary_erosion(~lg)).sum() > 50  # sphere + strand shadows
    assert agree[stable].mean() > 0.995, agree[stable].mean()
    assert agree.mean() > 0.97, agree.mean()

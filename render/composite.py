"""Compositing a captured object into an environment (METHODS §3 seed 004 Eq. 16-17, §4 glare).

Pipeline of :func:`composite_frame` (GL; numpy twins beside every pass):

1. **Background** from the environment map for the camera: the world direction of each pixel
   looked up with the ONE equirect mapping (``render.shading.envmap``; GLSL twin
   ``shading_envmap.glsl``).
2. **Ground shadow** (seed 004 Eq. 16-17): the ground plane z = h (the environment's up axis is
   +z). At a ground point x with the lighting as K spherical Gaussians (seed 004: fitted with
   L-BFGS-B, ``render.shading.sg_fit``), each times the clamped-cosine SG at the up normal,

       ratio(x) = sum_k mu_k f_h(min(SSDF_spheres(x, p_k), SSDF_ground(p_k)), lambda_k)
                / sum_k mu_k f_h(SSDF_ground(p_k), lambda_k)

   = irradiance with the object / without it, per RGB channel (SSDF and f_h from
   ``render.shading.ssdf`` / ``render.shading.sg``, GLSL ``shading_ssdf.glsl`` /
   ``shading_sg.glsl``). It is computed per texel of a grid over the object's surroundings
   (like seed 001's per-vertex SSDF, interpolated) and multiplied onto the background pixels whose
   ray meets the ground; outside the grid the ratio is 1. Reference: :func:`shadow_ratio_raycast`
   (Open3D ray casting against a mesh).
3. **Object** pixels (depth > 0) replace the background; optionally with the light-reflection map
   (``render.shading.glare_maps``) of a specular-parameter map added.
4. **Exposure** (a linear factor), **glare** (``render.shading.glare``: the excess above the
   display white becomes streaks, energy kept) and **tone mapping** (:func:`tonemap`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from capture.camera import Camera, gl_rows_to_image
from capture.depth_normals import depth_normals
from capture.rotations import rotation_between
from render.shading.envmap import EnvMap
from render.shading.sg import COS_LOBE_LAMBDA, COS_LOBE_MU, fh_fit, fh_glsl_params, fh_texture, sg_product
from render.shading.ssdf import combine_ssdf, ssdf_ground, ssdf_spheres

#: Tone-mapping operators: "clamp" (display = min(x, 1)), "reinhard" (extended Reinhard with white
#: point TONE_WHITE: x (1 + x / w^2) / (1 + x), exactly 1 at x = w and clipped above).
TONE_MAPS = ("clamp", "reinhard")
TONE_WHITE = 4.0
#: Lighting SG lobes fitted to the environment for the shadow ratio (seed 004 uses 10).
SHADOW_SG_K = 10
#: Most SG lobes the shadow shader takes (its uniform arrays).
MAX_SG = 128
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
            raise ValueError(f"GroundPlane: half_size > 0 and resolution >= 2 (got {self.half_size}, {self.resolution})")

    @property
    def origin(self) -> np.ndarray:
        return np.asarray(self.centre) - self.half_size

    @property
    def cell(self) -> float:
        return 2 * self.half_size / int(self.resolution)

    def grid_points(self) -> np.ndarray:
        """(G, G, 3) world texel centres; [j, i] = origin + (i + 0.5, j + 0.5) * cell."""
        g = int(self.resolution)
        t = (np.arange(g) + 0.5) * self.cell
        xx, yy = np.meshgrid(self.origin[0] + t, self.origin[1] + t)
        return np.stack([xx, yy, np.full_like(xx, self.height)], -1)


def ground_from_spheres(spheres, height: float | None = None, resolution: int = SHADOW_GRID) -> GroundPlane:
    """Ground under a sphere set: the lowest sphere point along +z (or ``height``); grid centred
    on the set's xy bounds, half-size = horizontal radius + SHADOW_EXTENT_HEIGHTS x its height."""
    c = np.asarray(spheres.centers, np.float64)
    r = np.asarray(spheres.radii, np.float64)
    if len(r) == 0:
        raise ValueError("ground_from_spheres: empty sphere set")
    lo, hi = (c - r[:, None]).min(0), (c + r[:, None]).max(0)
    h = float(lo[2]) if height is None else float(height)
    mid = (lo[:2] + hi[:2]) / 2
    rad = float(np.max(np.linalg.norm(c[:, :2] - mid, axis=1) + r))
    return GroundPlane(h, mid, rad + SHADOW_EXTENT_HEIGHTS * max(float(hi[2]) - h, 1e-6), resolution)


# -- tone mapping ------------------------------------------------------------------------------------
def tonemap(linear, exposure: float = 1.0, method: str = "reinhard", white: float = TONE_WHITE) -> np.ndarray:
    """Display-referred linear RGB in [0, 1] from scene-linear RGB: f(exposure * x) per channel,
    f monotone non-decreasing, f(0) = 0, f(x) = 1 for x >= display_white(method, white)."""
    if method not in TONE_MAPS:
        raise ValueError(f"tonemap: unknown method {method!r} (have {TONE_MAPS})")
    if not exposure > 0:
        raise ValueError(f"tonemap: exposure must be > 0, got {exposure}")
    x = np.maximum(np.asarray(linear, np.float64) * exposure, 0.0)
    if method == "clamp":
        return np.minimum(x, 1.0)
    if not white > 0:
        raise ValueError(f"tonemap: white must be > 0, got {white}")
    return np.minimum(x * (1 + x / white**2) / (1 + x), 1.0)


def display_white(method: str = "reinhard", white: float = TONE_WHITE) -> float:
    """The scene-linear value (after exposure) the tone map shows as full white."""
    return 1.0 if method == "clamp" else float(white)


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
    ts = ssdf_spheres(x, up, p, spheres.centers, spheres.radii) if len(spheres) else np.full((len(x), len(lam)), np.pi / 2)
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
    x = np.clip(uv[..., 0] * G - 0.5, 0, G - 1)
    y = np.clip(uv[..., 1] * G - 0.5, 0, G - 1)
    x0 = np.minimum(np.floor(x).astype(np.int64), G - 2)
    y0 = np.minimum(np.floor(y).astype(np.int64), G - 2)
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]
    v = (g[y0, x0] * (1 - fx) * (1 - fy) + g[y0, x0 + 1] * fx * (1 - fy)
         + g[y0 + 1, x0] * (1 - fx) * fy + g[y0 + 1, x0 + 1] * fx * fy)
    return np.where(inside[..., None], v, 1.0)


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
                        sources=None) -> np.ndarray:
    """(H, W, 3) float64 numpy twin of composite_frag.glsl: exposure x (object where depth > 0,
    plus its light-reflection map when normals / spec / sources are given; else the environment
    in the pixel's direction, times the ground shadow ratio)."""
    d = pixel_world_dirs(camera)
    rgb = np.asarray(rgb, np.float64)
    if spec is not None and sources is not None:
        from render.shading.glare_maps import light_reflection_map

        view = -d / np.linalg.norm(d, axis=-1, keepdims=True)
        rgb = rgb + light_reflection_map(normals, view, np.where((np.asarray(depth) > 0)[..., None], spec, 0.0), sources)
    col = env.sample(d)
    if ground is not None and ratio_grid is not None:
        eye = camera.center
        hit = (d[..., 2] < 0) & (eye[2] > ground.height)
        t = np.where(hit, (ground.height - eye[2]) / np.where(hit, d[..., 2], -1.0), 0.0)
        xy = eye[:2] + t[..., None] * d[..., :2]
        col = np.where(hit[..., None], col * ratio_lookup(ratio_grid, ground, xy), col)
    obj = np.asarray(depth) > 0
    col = np.where(obj[..., None], np.asarray(rgb, np.float64), col)
    return exposure * col


def normals_from_depth(depth, camera: Camera) -> np.ndarray:
    """(H, W, 3) world unit normals of a z-depth map (``capture.depth_normals``, central
    differences of the back-projected points, facing the camera); 0 where a neighbour is empty."""
    dep = np.asarray(depth, np.float64)
    P = camera.unproject(camera.pixel_grid(), dep)
    return depth_normals(P, dep > 0, "central", eye=camera.center)[0]


# -- GL ------------------------------------------------------------------------------------------------
def _set(prog, name, value):
    if name in prog:
        prog[name].value = value


class Compositor:
    """Owns the GL objects of the compositing passes (programs, environment / fh / ratio
    textures). Context passed in; ``release()`` (or ``with``) frees them."""

    def __init__(self, ctx):
        from render.gl import program

        self.ctx = ctx
        self._shadow = program(ctx, "composite_vert.glsl", "composite_shadow_frag.glsl",
                               defines={"SG_FH_TABLE": 1, "MAX_SG": MAX_SG})
        self._comp = program(ctx, "composite_vert.glsl", "composite_frag.glsl")
        self._vao_s = ctx.vertex_array(self._shadow, [])
        self._vao_c = ctx.vertex_array(self._comp, [])
        self._fh = fh_texture(ctx)
        self._env = None
        self._env_key = None
        self._ratio = None
        self._grid_key = self._grid = None
        self._src_key = self._src = None
        self._glare = None
        self._dummy_ratio = ctx.texture((2, 2), 4, np.ones((2, 2, 4), np.float32).tobytes(), dtype="f4")

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.release()

    def release(self) -> None:
        for o in (self._vao_s, self._vao_c, self._shadow, self._comp, self._fh, self._env, self._ratio,
                  self._dummy_ratio, self._glare):
            if o is not None:
                o.release()
        self._env = self._ratio = self._glare = None

    # -- inputs ---------------------------------------------------------------------------------
    def set_env(self, env: EnvMap) -> None:
        """Upload the environment (RGB32F, LINEAR, wrap in u, clamp in v); cached by identity."""
        import moderngl

        if self._env_key is env:
            return
        if self._env is not None:
            self._env.release()
        d = np.ascontiguousarray(env.data, np.float32)
        self._env = self.ctx.texture((env.width, env.height), 3, d.tobytes(), dtype="f4")
        self._env.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self._env.repeat_x, self._env.repeat_y = True, False
        self._env_key = env

    def glare_layer(self, width: int, height: int, supersample: int | None = None):
        """A render.glare.GlareLayer for this size, kept and reused (re-made when the size changes)."""
        from render.glare import GLARE_SUPERSAMPLE, GlareLayer

        s = GLARE_SUPERSAMPLE if supersample is None else int(supersample)
        g = self._glare
        if g is None or g.size != (int(width), int(height)) or g.s != s:
            if g is not None:
                g.release()
            self._glare = GlareLayer(self.ctx, width, height, s)
        return self._glare

    def light_sources(self, env: EnvMap):
        """The environment's light sources for the light-reflection map
        (render.shading.glare_maps.light_sources of its light_source_map), cached by identity."""
        from render.shading.glare_maps import light_source_map, light_sources

        if self._src_key is not env:
            self._src, self._src_key = light_sources(light_source_map(env)), env
        return self._src

    def shadow_grid(self, spheres, fit, ground: GroundPlane) -> np.ndarray:
        """Compute the (G, G, 3) shadow-ratio grid on the GPU (twin: :func:`shadow_ratio` at
        ``ground.grid_points()``), keep it as the ratio texture and return it. Cached: the same
        spheres and fit objects and an equal ground reuse the last grid."""
        import moderngl

        key = self._grid_key
        if key is not None and key[0] is spheres and key[1] is fit and key[2] == ground:
            return self._grid
        ctx = self.ctx
        k = len(fit.lams)
        if k > MAX_SG:
            raise ValueError(f"Compositor.shadow_grid: {k} SG lobes > MAX_SG = {MAX_SG}")
        G = int(ground.resolution)
        tex = ctx.texture((G, G), 4, dtype="f4")
        fbo = ctx.framebuffer(color_attachments=[tex])
        sph = np.zeros((max(len(spheres), 1), 4), np.float32)
        if len(spheres):
            sph[:, :3] = spheres.centers
            sph[:, 3] = spheres.radii
        ssbo = ctx.buffer(sph.tobytes())
        try:
            ssbo.bind_to_storage_buffer(5)
            p = self._shadow
            pad = lambda a, w: np.concatenate([np.asarray(a, np.float32).reshape(k, w),
                                               np.zeros((MAX_SG - k, w), np.float32)]).tobytes()
            p["u_sg_axis"].write(pad(fit.axes, 3))
            p["u_sg_lambda"].write(pad(fit.lams, 1))
            p["u_sg_mu"].write(pad(fit.mus, 3))
            _set(p, "u_sg_count", k)
            _set(p, "u_ssdf_count", len(spheres))
            _set(p, "u_grid_origin", tuple(ground.origin))
            _set(p, "u_grid_cell", (ground.cell, ground.cell))
            _set(p, "u_plane_z", float(ground.height))
            _set(p, "u_fh_params", fh_glsl_params())
            self._fh.use(0)
            _set(p, "u_fh_table", 0)
            fbo.use()
            fbo.viewport = (0, 0, G, G)
            ctx.disable(moderngl.BLEND | moderngl.DEPTH_TEST)
            self._vao_s.render(moderngl.TRIANGLES, vertices=3)
            grid = np.frombuffer(fbo.read(components=4, dtype="f4"), np.float32).reshape(G, G, 4)[..., :3].copy()
        finally:
            fbo.release()
            ssbo.release()
        tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
        tex.repeat_x = tex.repeat_y = False
        if self._ratio is not None:
            self._ratio.release()
        self._ratio = tex
        self._grid_key, self._grid = (spheres, fit, ground), grid
        return grid

    def composite(self, rgb, depth, camera: Camera, env: EnvMap, exposure: float = 1.0,
                  ground: GroundPlane | None = None, normals=None, spec=None, sources=None) -> np.ndarray:
        """(H, W, 3) float32 HDR composite, exposure applied (twin: :func:`composite_reference`).
        The ground shadow uses the last :meth:`shadow_grid` (none if ``ground`` is None). With
        ``normals`` (H, W, 3) world, ``spec`` (H, W, 2) and light ``sources``
        (render.shading.glare_maps.LightSources) the light-reflection map is added to the object."""
        import moderngl

        ctx = self.ctx
        H, W = camera.height, camera.width
        rgb = np.ascontiguousarray(np.asarray(rgb, np.float32).reshape(H, W, 3))
        dep = np.ascontiguousarray(np.asarray(depth, np.float32).reshape(H, W))
        self.set_env(env)
        t_rgb = ctx.texture((W, H), 3, rgb.tobytes(), dtype="f4")
        t_dep = ctx.texture((W, H), 1, dep.tobytes(), dtype="f4")
        out = ctx.texture((W, H), 4, dtype="f4")
        fbo = ctx.framebuffer(color_attachments=[out])
        lrm = spec is not None and sources is not None and len(sources.dirs) > 0
        if lrm:
            nrm = np.ascontiguousarray(np.asarray(normals, np.float32).reshape(H, W, 3))
            sp = np.ascontiguousarray(np.asarray(spec, np.float32).reshape(H, W, 2))
            src = np.zeros((len(sources.dirs), 2, 4), np.float32)
            src[:, 0, :3] = sources.dirs
            src[:, 1, :3] = sources.irradiance
        else:
            nrm, sp, src = np.zeros((1, 1, 3), np.float32), np.zeros((1, 1, 2), np.float32), np.zeros((1, 2, 4), np.float32)
        t_nrm = ctx.texture(nrm.shape[1::-1], 3, nrm.tobytes(), dtype="f4")
        t_sp = ctx.texture(sp.shape[1::-1], 2, sp.tobytes(), dtype="f4")
        t_src = ctx.buffer(src.tobytes())
        try:
            t_src.bind_to_storage_buffer(6)
            t_nrm.use(4)
            t_sp.use(5)
            _set(self._comp, "u_normal", 4)
            _set(self._comp, "u_spec", 5)
            _set(self._comp, "u_lrm_count", len(sources.dirs) if lrm else 0)
            p = self._comp
            self._env.use(0)
            t_rgb.use(1)
            t_dep.use(2)
            use_ground = ground is not None and self._ratio is not None
            (self._ratio if use_ground else self._dummy_ratio).use(3)
            for name, unit in (("u_env", 0), ("u_rgb", 1), ("u_depth", 2), ("u_ratio", 3)):
                _set(p, name, unit)
            ray = camera.cam_from_world[:3, :3].T @ np.linalg.inv(camera.K)
            _set(p, "u_ray", tuple(ray.T.reshape(-1)))  # column-major
            _set(p, "u_eye", tuple(camera.center))
            _set(p, "u_height", H)
            _set(p, "u_ground", 1 if use_ground else 0)
            if use_ground:
                _set(p, "u_plane_z", float(ground.height))
                _set(p, "u_grid_origin", tuple(ground.origin))
                _set(p, "u_grid_size", (2 * ground.half_size,) * 2)
            _set(p, "u_exposure", float(exposure))
            fbo.use()
            fbo.viewport = (0, 0, W, H)
            ctx.disable(moderngl.BLEND | moderngl.DEPTH_TEST)
            self._vao_c.render(moderngl.TRIANGLES, vertices=3)
            img = np.frombuffer(fbo.read(components=4, dtype="f4"), np.float32).reshape(H, W, 4)[..., :3]
        finally:
            for o in (fbo, out, t_rgb, t_dep, t_nrm, t_sp, t_src):
                o.release()
        return gl_rows_to_image(img).copy()


def rotation_to_z(up) -> np.ndarray:
    """(3, 3) rotation taking the unit vector ``up`` to +z (the smallest one; a half turn about x
    for up = -z)."""
    try:
        return rotation_between(up, (0.0, 0.0, 1.0))
    except ValueError:
        raise ValueError(f"rotation_to_z: up must be a non-zero 3-vector, got {up!r}") from None


def composite_frame(ctx, rgb_linear, depth, camera: Camera, env: EnvMap, spheres=None, ground=None,
                    exposure: float = 1.0, glare: bool = True, specular=None, normals=None, up=(0.0, 0.0, 1.0),
                    tone: str = "reinhard", white: float = TONE_WHITE, output: str = "display",
                    sg_fit=None, glare_config=None, stats: dict | None = None, compositor=None) -> np.ndarray:
    """Composite a captured object into an environment (see the module doc).

    rgb_linear (H, W, 3) linear object colour; depth (H, W) z-depth in metres, 0 = empty;
    camera: the view (its size must match); env: the environment (its +z is up).
    up: the capture world's up direction: the world is turned so that ``up`` is the environment's
        +z (cameras, spheres, normals rotated by :func:`rotation_to_z`); the ground plane is
        perpendicular to it and its height is measured along it.
    spheres: the object's ``volume.model.SphereSet`` (shadow caster) or None (no shadow).
    ground: None = under the spheres (lowest sphere point along ``up``); a float = the plane height
        along ``up`` (m); a :class:`GroundPlane` (in the turned frame: +z = up); False = no shadow.
    exposure: linear factor applied to everything before glare / tone mapping.
    glare: draw streaks for pixels brighter than the display white (energy moved, not added).
    specular: (H, W, 2) specular-parameter map (k_s, n) -> the light-reflection map of the
        environment's light sources is added to the object (normals: (H, W, 3) world, else from
        the depth); its n also shapes the streaks.
    tone / white: the tone map (:func:`tonemap`). output: "display" (tone-mapped linear in
        [0, 1]) or "linear" (exposed HDR with glare, before tone mapping).
    sg_fit: the environment's SG fit (render.shading.sg_fit.SGFit); fitted with SHADOW_SG_K lobes
        when needed and None. stats: filled with timings / counts when given.
    compositor: a :class:`Compositor` to reuse across frames (programs compiled once, the
        environment uploaded once); by default one is made and released per call.
    Returns (H, W, 3) float32.
    """
    import time

    if output not in ("display", "linear"):
        raise ValueError(f"composite_frame: output must be 'display' or 'linear', got {output!r}")
    H, W = camera.height, camera.width
    rgb = np.asarray(rgb_linear, np.float64)
    dep = np.asarray(depth, np.float64)
    if rgb.shape != (H, W, 3) or dep.shape != (H, W):
        raise ValueError(f"composite_frame: rgb {rgb.shape} / depth {dep.shape} do not match the camera {H}x{W}")
    dep = np.where(np.isfinite(dep), dep, 0.0)
    R = rotation_to_z(up)
    if not np.allclose(R, np.eye(3)):
        T = np.eye(4)
        T[:3, :3] = R.T
        camera = Camera(camera.K, camera.cam_from_world @ T, camera.width, camera.height, camera.name)
        if spheres is not None:
            spheres = type(spheres)(np.asarray(spheres.centers) @ R.T, spheres.radii)
        if normals is not None:
            normals = np.asarray(normals, np.float64) @ R.T
    st = stats if stats is not None else {}
    t0 = time.perf_counter()
    obj = dep > 0
    nrm = spec = None
    if specular is not None:
        spec = np.asarray(specular, np.float64)
        if spec.shape != (H, W, 2):
            raise ValueError(f"composite_frame: specular must be ({H}, {W}, 2), got {spec.shape}")
        nrm = normals_from_depth(dep, camera) if normals is None else np.asarray(normals, np.float64)
        if nrm.shape != (H, W, 3):
            raise ValueError(f"composite_frame: normals must be ({H}, {W}, 3), got {nrm.shape}")
        spec = np.where((obj & (np.linalg.norm(nrm, axis=-1) > 0))[..., None], spec, 0.0)
    gp = None
    if ground is not False and (spheres is not None and len(spheres)):
        if isinstance(ground, GroundPlane):
            gp = ground
        else:
            gp = ground_from_spheres(spheres, None if ground is None else float(ground))
    comp = Compositor(ctx) if compositor is None else compositor
    try:
        sources = comp.light_sources(env) if spec is not None else None
        if sources is not None:
            st["light_sources"] = len(sources.dirs)
        if gp is not None:
            if sg_fit is None:
                from render.shading.sg_fit import fit_env_sg
                sg_fit = fit_env_sg(env, SHADOW_SG_K)
                st["sg_fit_s"] = sg_fit.seconds
            t1 = time.perf_counter()
            comp.shadow_grid(spheres, sg_fit, gp)
            st["shadow_ms"] = 1e3 * (time.perf_counter() - t1)
        t1 = time.perf_counter()
        hdr = comp.composite(rgb, dep, camera, env, exposure, gp, nrm, spec, sources).astype(np.float64)
        st["composite_ms"] = 1e3 * (time.perf_counter() - t1)
        if glare:
            hdr = apply_glare_gl(ctx, hdr, display_white(tone, white), spec=specular, config=glare_config, stats=st,
                                 layer=comp.glare_layer(W, H))
    finally:
        if compositor is None:
            comp.release()
    st["total_ms"] = 1e3 * (time.perf_counter() - t0)
    if output == "linear":
        return hdr.astype(np.float32)
    return tonemap(hdr, 1.0, tone, white).astype(np.float32)


def apply_glare_gl(ctx, hdr, display_max: float, spec=None, config=None, mask=None, stats: dict | None = None,
                   supersample: int | None = None, layer=None):
    """Energy-preserving glare on an exposed HDR image (H, W, 3): the excess of the pixels above
    ``display_max`` (render.shading.glare_maps.glare_sources) is removed and redrawn as streak pairs
    (make_streaks) by render.glare.GlareLayer; n per pixel from ``spec`` (H, W, 2) or
    GLARE_DEFAULT_N. config: render.shading.glare.GlareConfig. layer: a GlareLayer of this size to
    reuse (else one is made for the call). Returns float64 (H, W, 3)."""
    import time

    from render.glare import GLARE_SUPERSAMPLE, GlareLayer
    from render.shading.glare import GlareConfig
    from render.shading.glare_maps import glare_sources, make_streaks, remove_excess

    cfg = config if config is not None else GlareConfig(display_max=display_max)
    H, W = hdr.shape[:2]
    t0 = time.perf_counter()
    src = glare_sources(hdr, display_max, mask=mask, spec=spec, default_n=GLARE_DEFAULT_N)
    streaks = make_streaks(src, cfg)
    if layer is not None:
        light = layer.render(streaks)
    else:
        with GlareLayer(ctx, W, H, GLARE_SUPERSAMPLE if supersample is None else supersample) as own:
            light = own.render(streaks)
    if stats is not None:
        stats.update(glare_ms=1e3 * (time.perf_counter() - t0), bright_pixels=len(src.centres),
                     streak_pairs=len(streaks), glare_excess=src.excess.sum(0).tolist(),
                     glare_drawn=light.sum((0, 1)).astype(float).tolist())
    return remove_excess(hdr, src) + light


#: Blinn-Phong exponent for the streak shape where no specular-parameter map is given.
GLARE_DEFAULT_N = 100.0

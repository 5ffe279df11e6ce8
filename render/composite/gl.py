"""The GL owner of the compositing passes (docs/methods.md §3, §4): shadow-ratio grid
(``composite_shadow_frag.glsl``, twin ``render.composite.ground_shadow.shadow_ratio``) and the composite of an
object over its environment (``composite_frag.glsl``, twin
``render.composite.reference.composite_reference``)."""

from __future__ import annotations

import numpy as np

from capture.camera import Camera, gl_rows_to_image
from render.composite.ground_shadow import GroundPlane
from render.owner import GLOwner
from render.shading.envmap import EnvMap
from render.shading.sg import fh_glsl_params, fh_texture

#: Most SG lobes the shadow shader takes (its uniform arrays).
MAX_SG = 128


def _set(prog, name, value):
    if name in prog:
        prog[name].value = value


def same_spheres(a, b) -> bool:
    """Whether two sphere sets (``centers``, ``radii``) are the same object or hold equal values."""
    if a is b:
        return True
    return (a is not None and b is not None and np.array_equal(a.centers, b.centers)
            and np.array_equal(a.radii, b.radii))


def premultiplied_rgba(rgb, depth, alpha, H: int, W: int) -> np.ndarray:
    """(H, W, 4) float32 premultiplied colour + alpha of an object: without ``alpha`` the straight
    ``rgb`` over the binary mask depth > 0; with one, ``rgb`` is already premultiplied by it."""
    rgb = np.asarray(rgb, np.float32).reshape(H, W, 3)
    if alpha is None:
        a = (np.nan_to_num(np.asarray(depth, np.float32).reshape(H, W)) > 0).astype(np.float32)
        rgb = rgb * a[..., None]
    else:
        a = np.clip(np.asarray(alpha, np.float32).reshape(H, W), 0.0, 1.0)
    return np.concatenate([rgb, a[..., None]], -1)


class Compositor(GLOwner):
    """Owns the GL objects of the compositing passes (programs, environment / fh / ratio
    textures). Context passed in; ``release()`` (or ``with``) frees them."""

    def __init__(self, ctx):
        from render.gl import program

        super().__init__(ctx)
        self._shadow = self.own(program(ctx, "composite_vert.glsl", "composite_shadow_frag.glsl",
                                        defines={"SG_FH_TABLE": 1, "MAX_SG": MAX_SG}))
        self._comp = self.own(program(ctx, "composite_vert.glsl", "composite_frag.glsl"))
        self._vao_s = self.own(ctx.vertex_array(self._shadow, []))
        self._vao_c = self.own(ctx.vertex_array(self._comp, []))
        self._fh = self.own(fh_texture(ctx))
        self._env = None
        self._env_key = None
        self._ratio = None
        self._grid_key = self._grid = None
        self._src_key = self._src = None
        self._glare = None
        self._dummy_ratio = self.own(ctx.texture((2, 2), 4, np.ones((2, 2, 4), np.float32).tobytes(), dtype="f4"))

    # -- inputs ---------------------------------------------------------------------------------
    def set_env(self, env: EnvMap) -> None:
        """Upload the environment (RGB32F, LINEAR, wrap in u, clamp in v); cached by identity."""
        import moderngl

        if self._env_key is env:
            return
        self.free(self._env)
        d = np.ascontiguousarray(env.data, np.float32)
        self._env = self.own(self.ctx.texture((env.width, env.height), 3, d.tobytes(), dtype="f4"))
        self._env.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self._env.repeat_x, self._env.repeat_y = True, False
        self._env_key = env

    def glare_layer(self, width: int, height: int, supersample: int | None = None):
        """A render.composite.glare_layer.GlareLayer for this size, kept and reused (re-made when the size changes)."""
        from render.composite.glare_layer import GLARE_SUPERSAMPLE, GlareLayer

        s = GLARE_SUPERSAMPLE if supersample is None else int(supersample)
        g = self._glare
        if g is None or g.size != (int(width), int(height)) or g.s != s:
            self.free(g)
            self._glare = self.own(GlareLayer(self.ctx, width, height, s))
        return self._glare

    def light_sources(self, env: EnvMap):
        """The environment's light sources for the light-reflection map
        (render.shading.glare_maps.light_sources of its light_source_map), cached by identity."""
        from render.shading.glare_maps import light_source_map, light_sources

        if self._src_key is not env:
            self._src, self._src_key = light_sources(light_source_map(env)), env
        return self._src

    def shadow_grid(self, spheres, fit, ground: GroundPlane) -> np.ndarray:
        """Compute the (G, G, 3) shadow-ratio grid on the GPU (twin:
        ``render.composite.ground_shadow.shadow_ratio`` at ``ground.grid_points()``), keep it as the ratio
        texture and return it. Cached: equal spheres (composite_frame turns them to the map's up
        in a new object every frame), the same fit object and an equal ground reuse the last grid."""
        import moderngl

        key = self._grid_key
        if key is not None and same_spheres(key[0], spheres) and key[1] is fit and key[2] == ground:
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
        self.free(self._ratio)
        self._ratio = self.own(tex)
        self._grid_key, self._grid = (spheres, fit, ground), grid
        return grid

    def composite(self, rgb, depth, camera: Camera, env: EnvMap, exposure: float = 1.0,
                  ground: GroundPlane | None = None, normals=None, spec=None, sources=None, alpha=None) -> np.ndarray:
        """(H, W, 3) float32 HDR composite, exposure applied (twin:
        ``render.composite.reference.composite_reference``): ``rgb`` straight over the object
        (depth > 0) without ``alpha``; with an (H, W) matte ``alpha``, ``rgb`` is premultiplied and
        the result premult + (1 - alpha) background (render.frame.Frame). The ground shadow uses the last
        :meth:`shadow_grid` (none if ``ground`` is None). With
        ``normals`` (H, W, 3) world, ``spec`` (H, W, 2) and light ``sources``
        (render.shading.glare_maps.LightSources) the light-reflection map is added to the object."""
        import moderngl

        ctx = self.ctx
        H, W = camera.height, camera.width
        rgba = np.ascontiguousarray(premultiplied_rgba(rgb, depth, alpha, H, W))
        self.set_env(env)
        t_rgb = ctx.texture((W, H), 4, rgba.tobytes(), dtype="f4")
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
            nrm, sp, src = (np.zeros((1, 1, 3), np.float32), np.zeros((1, 1, 2), np.float32),
                            np.zeros((1, 2, 4), np.float32))
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
            use_ground = ground is not None and self._ratio is not None
            (self._ratio if use_ground else self._dummy_ratio).use(3)
            for name, unit in (("u_env", 0), ("u_rgb", 1), ("u_ratio", 3)):
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
            for o in (fbo, out, t_rgb, t_nrm, t_sp, t_src):
                o.release()
        return gl_rows_to_image(img).copy()

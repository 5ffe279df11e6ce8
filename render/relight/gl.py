"""Relighting a captured model for a new environment (issue 15): one GL owner that any client
(``furrow render --relight``, ``furrow eval``, the benchmarks, the viewer) puts after any method's
frame::

    with Relighter.from_model(ctx, model, bundled_envmap("sunset")) as rel:
        frame = rel.apply(renderer.render(camera), camera)      # the object as lit by the new map

The capture lighting A is the model's (``volume.model.CaptureLighting``, stored by
``furrow model --capture-env``); a model without it cannot be relit (:class:`NotRelightable`).
Two passes (numpy twin ``render.relight.reference``, environment maths
``render.shading.transfer``):

1. once per (model, A, B): the share volume -- on the cube of a coarse pyramid level, the share
   of each lighting the sphere set leaves visible near the surface (``relight_volume_frag.glsl``);
2. per frame, deferred: each pixel's world point from the frame's depth, its orientation (the
   smoothed SDF's gradient), the direction to the camera, the shares, the gain B / A of the
   transfer quotient, times the colour (``relight_apply_frag.glsl``).  Black stays black, the
   coverage and depth are the frame's, so the result composites like any frame (``--env MAP
   --ground``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from capture.camera import Camera, gl_rows_to_image
from render.frame import Frame
from render.owner import FrameTimer, GLOwner
from render.relight.reference import (
    ORIENTATION_MAX_RES,
    ORIENTATION_SMOOTH,
    VISIBILITY_BAND_VOXELS,
    VISIBILITY_LIFT_VOXELS,
    orientation_grid,
    sdf_gradient,
    smoothed,
    unit_normals,
)
from render.relight.strands import POWER_STEPS, STRAND_RES, strand_colour, strand_field, tensor_volume
from render.shading import hair_transfer as ht
from render.shading import transfer as rl
from render.shading.envmap import EnvMap

#: RelightConfig.kernel that fits the transfer to the capture (render.relight.calibrate).
AUTO_KERNEL = "auto"
#: Most SG lobes per lighting the volume pass takes (its uniform arrays).
MAX_RELIGHT_SG = 32


def _padded(arr, width: int) -> bytes:
    """float32 bytes of (k, width) rows padded with zeros to MAX_RELIGHT_SG rows (a uniform array)."""
    a = np.asarray(arr, np.float32).reshape(-1, width)
    return np.concatenate([a, np.zeros((MAX_RELIGHT_SG - len(a), width), np.float32)]).tobytes()


class NotRelightable(ValueError):
    """The model stores no capture lighting."""


@dataclass(frozen=True)
class RelightConfig:
    """Knobs of the relighting (defaults measured in ``furrow bench relight``)."""

    #: Transfer kernel: "auto" (default): kernel, forward and forward_g fitted to the model's own capture
    #: views (render.relight.calibrate; measured +0.48 dB on average over the fixed wrap transfer on seven
    #: relit pairs of our fur balls and plants, docs/relight.md); forward and forward_g given here are then
    #: replaced, and a model whose views cannot be fitted keeps render.shading.transfer.DEFAULT_KERNEL with
    #: them.  Or one of render.shading.transfer.KERNELS, or a ``mix:w0,w1,w2,w3`` over its MIX_BASIS.
    kernel: str = "auto"
    #: SG lobes fitted to each environment (visible share, forward scattering).
    sg_lobes: int = rl.RELIGHT_SG_K
    #: Weight of the forward-scattered (view-dependent) transfer; 0 = view-independent.
    forward: float = rl.FORWARD_SCATTER
    #: Asymmetry g of the scattering phase (> 0 forwards, < 0 backwards).
    forward_g: float = rl.FORWARD_G
    #: Self-visibility from the model's sphere set (SSDF); False: unoccluded transfers.  Off by
    #: default: measured neutral on the fur ball and -0.03 to -0.08 dB on the plant (their sphere
    #: sets fill fuzzy shells), at 2-3 s of setup; it matters for concave solids.
    visibility: bool = False
    #: Regularisation of the quotient (fraction of the reference transfers).
    regularise: float = rl.REGULARISE
    #: Largest gain as a multiple of the global gain.
    max_gain: float = rl.MAX_GAIN
    #: Finest pyramid resolution of the orientation / gain volume.
    volume_res: int = ORIENTATION_MAX_RES
    #: Smoothing of the orientation, fraction of the cube's side.
    smooth: float = ORIENTATION_SMOOTH
    #: Strand-aware transfer (issue 23): tangents and fibre colours from the capture views
    #: (render.relight.strands), the strand gain (render.shading.hair_transfer) where the structure is
    #: strand-like; False: the surface transfer everywhere (issue 15's relighting).  Off by default:
    #: measured within -0.18..+0.22 dB of the surface transfer on the fur ball and the plant, no better on
    #: the whole (docs/relight.md).
    strands: bool = False
    #: Voxels per side of the strand volume (over the orientation cube).
    strand_res: int = STRAND_RES
    #: The strand gain's weight is this times the strand score (clamped to 1): 0.5 measured better than 1
    #: on all five bench pairs (+0.1 to +0.4 dB; docs/relight.md).
    strand_weight: float = 0.5

    def __post_init__(self) -> None:
        if self.kernel != AUTO_KERNEL:
            rl.kernel_fn(self.kernel)
        if not 1 <= int(self.sg_lobes) <= MAX_RELIGHT_SG:
            raise ValueError(f"sg_lobes must be 1..{MAX_RELIGHT_SG}, got {self.sg_lobes}")
        if not self.strand_weight >= 0:
            raise ValueError(f"strand_weight must be >= 0, got {self.strand_weight}")
        if int(self.strand_res) < 2:
            raise ValueError(f"strand_res must be >= 2, got {self.strand_res}")
        if not (self.regularise >= 0 and self.max_gain > 0 and self.smooth >= 0 and self.volume_res >= 2
                and self.forward >= 0 and -1 < self.forward_g < 1):
            raise ValueError("RelightConfig: regularise >= 0, max_gain > 0, smooth >= 0, volume_res >= 2, forward >= 0")

    def gain_kwargs(self) -> dict:
        """The keyword arguments of ``render.shading.transfer.relight_gain`` this config sets."""
        return {"forward": self.forward, "forward_g": self.forward_g, "regularise": self.regularise,
                "max_gain": self.max_gain}


def capture_envmap_of(model) -> tuple[EnvMap, np.ndarray]:
    """(the model's capture lighting as an EnvMap, rotated as stored; its world up), or
    NotRelightable naming what to do."""
    cap = getattr(model, "capture_env", None)
    if cap is None:
        src = (getattr(model, "provenance", None) or {}).get("source")
        where = f" (built from {src})" if src else ""
        raise NotRelightable(f"the model{where} stores no capture lighting, so it cannot be relit; rebuild it "
                             "with `furrow model SCANS --capture-env MAP` (or --capture-env-fisheye / "
                             "--capture-env-mirrorball)")
    env = EnvMap(np.asarray(cap.radiance, np.float32), cap.source or "capture")
    if cap.rotation_deg:
        env = env.rotated(np.radians(cap.rotation_deg))
    return env, np.asarray(cap.up, np.float64)


class Relighter(GLOwner):
    """Owns the GL objects of the relighting (see the module doc): programs, the two SDF volumes,
    the transfer tables, the gain volume.  ``capture_env`` / ``new_env``: EnvMaps (already turned
    about up as wanted); ``up``: the world direction of the maps' +z."""

    def __init__(self, ctx, model, capture_env: EnvMap, new_env: EnvMap, config: RelightConfig | None = None,
                 up=(0.0, 0.0, 1.0)) -> None:
        from render.shading.sg import fh_texture

        super().__init__(ctx)
        self.config = config if config is not None else RelightConfig()
        self.up = np.asarray(up, np.float64)
        self.model = model
        self.raw = orientation_grid(model, self.config.volume_res)
        self.smooth = smoothed(self.raw, self.config.smooth * self.raw.resolution)
        self.setup_seconds: dict = {}
        #: The transfer fitted to the capture (``render.relight.calibrate.TransferFit``) with kernel "auto";
        #: ``fit_note``: why there is none although "auto" was asked for ("" otherwise); ``choice``: the
        #: transfer relit with for the new map and why (``render.relight.trust.RelightChoice``: the fitted one,
        #: or the default transfer or the single gain where the fit cannot be trusted for that map).
        self.fit = None
        self.fit_note = ""
        self.choice = None
        self._capture_env = capture_env
        self._capture_sg = None  # the capture map's SG fit, made once when the transfer is fitted
        self._fit_samples = None
        self._programs: tuple = ()
        if self.config.kernel == AUTO_KERNEL:
            self._calibrate(capture_env)
            if self.fit is not None:
                self._choose(new_env)
        self._build_programs()
        self._fh = self.own(fh_texture(ctx))
        self._sdf_raw = self.own(self._texture3d(self.raw.values[..., None]))
        self._sdf_smooth = self.own(self._texture3d(self.smooth.values[..., None], linear=True))
        sph = np.zeros((max(len(model.spheres), 1), 4), np.float32)
        if len(model.spheres):
            sph[:, :3] = model.spheres.centers
            sph[:, 3] = model.spheres.radii
        self._spheres = self.own(ctx.buffer(sph.tobytes()))
        self._share_tex = (None, None)
        self._tables = (None, None)
        #: (L, L, L, 6) float32 visible shares (S_A rgb, S_B rgb) of the last share pass.
        self.share_volume = None
        self.capture = self._lighting(capture_env, "capture", self._capture_sg)
        self.new = self._lighting(new_env, "new")
        #: The strands' field and fitted colours (None with config.strands False), the lightings (A, B) of
        #: the strand transfer.
        self.strands = None
        self.hair = (None, None)
        self._strand_tex: tuple = ()
        if self.config.strands:
            self.hair = (self.capture, self.new)
            self._build_strands()
        self._upload_tables()
        self._build_volume()

    @classmethod
    def from_model(cls, ctx, model, new_env: EnvMap, config: RelightConfig | None = None) -> Relighter:
        """The relighter of ``model`` from its stored capture lighting (and up) to ``new_env``."""
        env, up = capture_envmap_of(model)
        return cls(ctx, model, env, new_env, config, up)

    # ------------------------------------------------------------------ inputs
    def _texture3d(self, data: np.ndarray, linear: bool = False):
        """A float32 3-D texture of an (L, L, L, C) [i, j, k] array (x fastest in memory), clamped."""
        import moderngl

        L, C = data.shape[0], data.shape[-1]
        tex = self.ctx.texture3d((L, L, L), C, np.ascontiguousarray(np.transpose(data, (2, 1, 0, 3)), np.float32)
                                 .tobytes(), dtype="f4")
        f = moderngl.LINEAR if linear else moderngl.NEAREST
        tex.filter = (f, f)
        tex.repeat_x = tex.repeat_y = tex.repeat_z = False
        return tex

    def _lighting(self, env: EnvMap, label: str, fit=None) -> rl.RelightLighting:
        t0 = time.perf_counter()
        lt = rl.relight_lighting(env, self.up, self.config.kernel, self.config.sg_lobes, fit=fit)
        self.setup_seconds[label] = time.perf_counter() - t0
        return lt

    def _build_programs(self) -> None:
        """The two passes' programs for the config's transfer (its kernel and phase are compiled in)."""
        from render.gl import program

        ctx, kernel = self.ctx, self.config.kernel
        defines = {"MAX_SG": MAX_RELIGHT_SG, "RELIGHT_MIN_GRADIENT": f"{rl.MIN_GRADIENT:.9e}",
                   "RELIGHT_KERNEL": list(rl.KERNELS).index(kernel) if kernel in rl.KERNELS else len(rl.KERNELS),
                   "RELIGHT_KERNEL_W": "vec4({})".format(", ".join(
                       f"{w:.9e}" for w in (rl.mix_weights(kernel) if kernel not in rl.KERNELS else np.zeros(4)))),
                   "RELIGHT_FORWARD_G": f"{self.config.forward_g:.9e}",
                   "RELIGHT_LIFT_VOXELS": f"{VISIBILITY_LIFT_VOXELS:.9e}",
                   "RELIGHT_BAND_VOXELS": f"{VISIBILITY_BAND_VOXELS:.9e}", "SG_FH_TABLE": 1,
                   "HAIR_FORWARD": f"{ht.HAIR_FORWARD:.9e}", "HAIR_BETA_R": f"{ht.HAIR_BETA_R:.9e}",
                   "HAIR_BETA_D": f"{ht.HAIR_BETA_D:.9e}", "HAIR_FLOOR": f"{ht.HAIR_FLOOR:.9e}",
                   "STRAND_POWER_STEPS": POWER_STEPS, "RELIGHT_STRANDS": int(bool(self.config.strands))}
        self.free(*self._programs)
        self._vol_prog = self.own(program(ctx, "composite_vert.glsl", "relight_volume_frag.glsl", defines=defines))
        self._app_prog = self.own(program(ctx, "composite_vert.glsl", "relight_apply_frag.glsl", defines=defines))
        self._vol_vao = self.own(ctx.vertex_array(self._vol_prog, []))
        self._app_vao = self.own(ctx.vertex_array(self._app_prog, []))
        self._programs = (self._vol_vao, self._app_vao, self._vol_prog, self._app_prog)

    def _choose(self, new_env: EnvMap) -> None:
        """Kernel "auto": the transfer for ``new_env`` (``render.relight.trust.choose_transfer``: the fitted
        one, or the default transfer or the single gain where the fit cannot be trusted for that map)."""
        from render.relight.trust import choose_transfer

        t0 = time.perf_counter()
        self.choice = choose_transfer(self.fit, self._fit_samples, self._capture_env, new_env, self.up,
                                      self._capture_sg, regularise=self.config.regularise)
        self.config = replace(self.config, kernel=self.choice.kernel, forward=self.choice.forward,
                              forward_g=self.choice.forward_g)
        self.setup_seconds["choice"] = time.perf_counter() - t0

    def _calibrate(self, capture_env: EnvMap) -> None:
        """Kernel "auto": the transfer that best explains the model's capture views under the capture
        lighting (``render.relight.calibrate``) replaces the config's kernel, forward weight and phase."""
        from render.relight.calibrate import capture_samples, fit_transfer
        from render.shading.sg_fit import fit_env_sg

        t0 = time.perf_counter()
        self._capture_sg = fit_env_sg(capture_env, self.config.sg_lobes)
        try:
            samples = capture_samples(self.model.rgbz, lambda x: unit_normals(sdf_gradient(self.smooth, x)))
            self._fit_samples = samples
            self.fit = fit_transfer(samples, capture_env, self.up, self.raw.origin,
                                    self.raw.voxel * self.raw.resolution, fit=self._capture_sg,
                                    regularise=self.config.regularise)
        except ValueError as e:  # too few capture pixels to tell: the fixed default transfer
            self.fit_note = f"{e}; relighting with the fixed {rl.DEFAULT_KERNEL} transfer"
            self.config = replace(self.config, kernel=rl.DEFAULT_KERNEL)
        else:
            self.config = replace(self.config, kernel=self.fit.kernel, forward=self.fit.forward,
                                  forward_g=self.fit.forward_g)
        self.setup_seconds["fit"] = time.perf_counter() - t0

    def _build_strands(self) -> None:
        """Strand tangents and fibre colours from the model's capture views (numpy, once per model)."""
        t0 = time.perf_counter()
        rz, L = self.model.rgbz, int(self.config.strand_res)
        voxel = self.raw.voxel * self.raw.resolution / L
        field = strand_field(rz.rgb, rz.depth, rz.cameras, self.raw.origin, voxel, L, rz.alpha)
        normals = lambda x: unit_normals(sdf_gradient(self.smooth, x))
        self.set_strands(strand_colour(field, rz.rgb, rz.depth, rz.cameras, self.capture, normals, rz.alpha))
        self.setup_seconds["strands"] = time.perf_counter() - t0

    def set_strands(self, strands) -> None:
        """Use these strands (``render.relight.strands.StrandColour``) from now on: upload their volumes."""
        self.check_alive()
        if not self.config.strands:
            raise ValueError("set_strands: this relighter was configured without strands")
        self.strands = strands
        tv = tensor_volume(strands.field)
        t1 = np.concatenate([tv[..., 4:6], np.zeros(tv.shape[:3] + (2,), np.float32)], -1)
        self.free(*self._strand_tex)
        self._strand_tex = tuple(self.own(self._texture3d(v, linear=True)) for v in (tv[..., :4], t1, strands.fit))

    def set_new_env(self, env: EnvMap) -> None:
        """Relight to another map from now on (the viewer's switch): its lighting and the gain volume."""
        self.check_alive()
        if self.fit is not None:   # kernel "auto": is the fit to be trusted for this map?
            before = (self.config.kernel, self.config.forward, self.config.forward_g)
            self._choose(env)
            if (self.config.kernel, self.config.forward, self.config.forward_g) != before:
                self._build_programs()
                self.capture = self._lighting(self._capture_env, "capture", self._capture_sg)
        self.new = self._lighting(env, "new")
        if self.config.strands:
            self.hair = (self.capture, self.new)
        self._upload_tables()
        self._build_volume()

    @property
    def global_gain(self) -> np.ndarray:
        """(3,) mean radiance of the new map over the capture's (the single-gain baseline)."""
        return rl.global_gain(self.capture, self.new)

    def _upload_tables(self) -> None:
        from render.shading.irradiance import irradiance_texture

        self.free(*self._tables)
        self._tables = tuple(self.own(irradiance_texture(self.ctx, lt.table)) for lt in (self.capture, self.new))

    def _bind(self, p, units) -> None:
        from render.gl import set_uniform

        for unit, (name, tex) in enumerate(units):
            tex.use(unit)
            set_uniform(p, name, unit)

    # ------------------------------------------------------------------ passes
    def _set_lighting_uniforms(self, p) -> None:
        from render.gl import set_uniform
        from render.shading.sg import fh_glsl_params

        for tag, lt in (("a", self.capture), ("b", self.new)):
            for name, arr, width in (("axis", lt.axes, 3), ("lambda", lt.lams, 1), ("mu", lt.mus, 3)):
                if f"u_sg_{name}_{tag}" in p:
                    p[f"u_sg_{name}_{tag}"].write(_padded(arr, width))
            set_uniform(p, f"u_sg_count_{tag}", len(lt.lams))
            set_uniform(p, f"u_ref_{tag}", tuple(float(v) for v in lt.reference))
        set_uniform(p, "u_to_env", tuple(np.asarray(self.capture.to_env, np.float64).T.reshape(-1)))
        set_uniform(p, "u_global_gain", tuple(float(v) for v in self.global_gain))
        set_uniform(p, "u_regularise", float(self.config.regularise))
        set_uniform(p, "u_forward", float(self.config.forward))
        set_uniform(p, "u_max_gain", float(self.config.max_gain))
        set_uniform(p, "u_fh_params", fh_glsl_params())
        set_uniform(p, "u_ssdf_count", len(self.model.spheres) if self.config.visibility else 0)

    def _build_volume(self) -> None:
        """Pass 1: the share volume (module doc), read back into ``share_volume``, kept as textures."""
        import moderngl

        from render.gl import set_uniform

        t0 = time.perf_counter()
        ctx, p, L = self.ctx, self._vol_prog, self.raw.resolution
        tgt = self.target(L * L, L, colours=(4, 4), depth=False)
        self._set_lighting_uniforms(p)
        self._spheres.bind_to_storage_buffer(5)
        self._bind(p, (("u_fh_table", self._fh), ("u_table_a", self._tables[0]), ("u_table_b", self._tables[1]),
                       ("u_sdf_raw", self._sdf_raw), ("u_sdf_smooth", self._sdf_smooth)))
        set_uniform(p, "u_origin", tuple(float(v) for v in self.raw.origin))
        set_uniform(p, "u_voxel", float(self.raw.voxel))
        set_uniform(p, "u_res", L)
        tgt.fbo.use()
        ctx.viewport = (0, 0, L * L, L)
        ctx.disable(moderngl.BLEND | moderngl.DEPTH_TEST)
        self._vol_vao.render(moderngl.TRIANGLES, vertices=3)
        # atlas rows j, columns i + L k -> [j, k, i] -> [i, j, k]
        vols = [tgt.read_colour(c)[..., :3].reshape(L, L, L, 3).transpose(2, 0, 1, 3) for c in (0, 1)]
        self.share_volume = np.ascontiguousarray(np.concatenate(vols, -1), np.float32)
        self.free(*self._share_tex)
        self._share_tex = tuple(self.own(self._texture3d(v, linear=True)) for v in vols)
        self.setup_seconds["volume"] = time.perf_counter() - t0

    def _set_strand_uniforms(self, p) -> None:
        from render.gl import set_uniform

        if self.strands is None:  # RELIGHT_STRANDS 0: the strand branch is compiled out
            return
        f = self.strands.field
        for tag, lt in (("a", self.hair[0]), ("b", self.hair[1])):
            set_uniform(p, f"u_hair_ref_{tag}", tuple(float(v) for v in ht.hair_reference(lt)))
        set_uniform(p, "u_strand_origin", tuple(float(v) for v in f.origin))
        set_uniform(p, "u_strand_voxel", float(f.voxel))
        set_uniform(p, "u_strand_res", f.resolution)
        set_uniform(p, "u_strand_weight", float(self.config.strand_weight))

    def apply(self, frame: Frame, camera: Camera) -> Frame:
        """Pass 2: the frame relit (module doc); coverage, depth and stats are the frame's
        (the pass's own cost: :attr:`last_ms`, :attr:`last_cpu_ms`)."""
        import moderngl

        from render.gl import set_uniform

        self.check_alive()
        W, H = frame.size
        if (camera.width, camera.height) != (W, H):
            raise ValueError(f"Relighter.apply: camera {camera.width}x{camera.height} does not match the frame {W}x{H}")
        ctx, p = self.ctx, self._app_prog
        t_rgb = ctx.texture((W, H), 3, np.ascontiguousarray(frame.rgb).tobytes(), dtype="f4")
        t_dep = ctx.texture((W, H), 1, np.ascontiguousarray(frame.depth).tobytes(), dtype="f4")
        tgt = self.target(W, H, colours=(4,), depth=False)
        try:
            with FrameTimer(ctx) as t:
                self._set_lighting_uniforms(p)
                units = [("u_rgb", t_rgb), ("u_depth", t_dep), ("u_table_a", self._tables[0]),
                         ("u_table_b", self._tables[1]), ("u_sdf_smooth", self._sdf_smooth),
                         ("u_share_a", self._share_tex[0]), ("u_share_b", self._share_tex[1])]
                if self.strands is not None:
                    units += [("u_strand_t0", self._strand_tex[0]), ("u_strand_t1", self._strand_tex[1]),
                              ("u_strand_fit", self._strand_tex[2])]
                self._bind(p, units)
                self._set_strand_uniforms(p)
                ray = camera.cam_from_world[:3, :3].T @ np.linalg.inv(camera.K)
                set_uniform(p, "u_ray", tuple(ray.T.reshape(-1)))
                set_uniform(p, "u_eye", tuple(float(v) for v in camera.center))
                set_uniform(p, "u_origin", tuple(float(v) for v in self.raw.origin))
                set_uniform(p, "u_voxel", float(self.raw.voxel))
                set_uniform(p, "u_res", self.raw.resolution)
                set_uniform(p, "u_height", H)
                tgt.fbo.use()
                ctx.viewport = (0, 0, W, H)
                ctx.disable(moderngl.BLEND | moderngl.DEPTH_TEST)
                self._app_vao.render(moderngl.TRIANGLES, vertices=3)
            rgb = gl_rows_to_image(tgt.read_colour(0))[..., :3]
        finally:
            t_rgb.release()
            t_dep.release()
        self.last_ms, self.last_cpu_ms = t.ms, t.cpu_ms
        return replace(frame, rgb=rgb)

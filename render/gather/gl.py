"""The ``gather`` rendering method on the GPU: splatted depth, colours gathered from the two
nearest kept views with soft visibility (the algorithm and its numpy twin:
``render/gather/reference.py``).

Uploaded view by view from the model's crops (render/crops.py, issue 24), each view when a frame
first reads it (``load``; the first frame of a 200-view capture uploads a handful): its RGB-D points
(a vertex buffer per view) and its layer of the RGBz (+ matte) texture arrays of the crops only,
layers the size of the largest crop, a pixel outside its view's rectangle empty; at most
``render.crops.RESIDENT_VIEWS`` views are resident, the least recently used replaced.  Otherwise per
frame only uniforms change:

1. ``gather_depth_*.glsl``: the points of the ``k_depth`` nearest cameras drawn as GL points of
   side ``splat_px`` into an R32F target with MIN blending: the nearest z-depth per pixel
   (exactly the z-buffer of the twin; no depth buffer is involved); with a second layer also
   minus the z into a second R32F target (MIN: the farthest z, in the same draw);
2. ``gather_frag.glsl`` over a full-screen triangle: per pixel with a depth, the point is
   projected into the ``k_blend`` nearest cameras, their colours resampled (bilinear, or
   Catmull-Rom bicubic: 4 or 16 texel fetches, no hardware filtering, so the twin is exact) and
   blended with (1 / angle) x soft visibility (``gather_blend.glsl``).

With a matte and ``GatherConfig.back_gap_m`` > 0, the second layer (the twin's step 3) runs between
them: ``gather_mark_frag.glsl`` (1b) writes a depth where the farthest splat lies more than the gap
behind the front, and ``gather_under_frag.glsl`` (2a) gathers that point behind an early depth test
that passes only there (llvmpipe then skips the pixels without one: 3-6 ms at 960x720 against 40-41
without the test, and about 32 with a discard instead); pass 2 composites it under the front.  About
1.3 x the frame time of one layer at 960x720 (docs/novel_views.md); a draft frame
(``RenderOptions.draft``: the viewer's moving frames) leaves it out.

One sample per pixel whatever ``RenderOptions.supersample`` says (it reads no option): the
colours are interpolated from the photos, whose own area sampling already anti-aliases strand
fringes and silhouettes; a 2 x 2 box on top blurs (sharpness 0.65 on the fur ball, docs/novel_views.md).
GL clips a point whose centre lies outside the eye's frustum, so splats reaching into the
image from beyond its border or from outside the near / far planes of the object box are
dropped (the twin keeps their inside pixels); nothing else differs.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from capture.camera import Camera, gl_rows_to_image
from render.crops import RESIDENT_VIEWS, CropTextures
from render.frame import Frame, FrameStats
from render.gather import alpha_mass as am
from render.gather import fine_depth as fd
from render.gather import reference as gr
from render.gl import program
from render.methods import Renderer, RenderOptions
from render.owner import FrameTimer, mat4_bytes, near_far
from render.points import reference as pr

#: Cleared value of the depth target: "no splat here" (metres; any real depth is far below).
Z_EMPTY = 1e30


def shader_defines(cfg: gr.GatherConfig, has_alpha: bool = False) -> dict:
    """Constants of gather_frag.glsl, one source with the numpy twin."""
    return {"K_BLEND": cfg.k_blend, "VIS_SIGMA": f"{cfg.vis_sigma_m:.9e}", "VIS_FLOOR": f"{cfg.vis_floor:.9e}",
            "Z_EMPTY": f"{0.1 * Z_EMPTY:.3e}", "RESAMPLE_CUBIC": int(cfg.resample == "cubic"),
            "CUBIC_A": f"{gr.CUBIC_A:.9e}", "HAS_ALPHA": int(has_alpha),
            "PINHOLE_FILL": int(cfg.pinhole_spread_m > 0), "PINHOLE_SPREAD": f"{cfg.pinhole_spread_m:.9e}",
            "BACK_LAYER": int(has_alpha and cfg.back_gap_m > 0), "BACK_SOLID": f"{cfg.back_solid:.9e}"}


#: Depth pass 1b writes where a pixel has a second layer (the full-screen triangles lie at 0.5).
MARK_DEPTH = 0.25


def mark_defines(cfg: gr.GatherConfig) -> dict:
    """Constants of gather_mark_frag.glsl."""
    return {"BACK_GAP": f"{cfg.back_gap_m:.9e}", "Z_EMPTY": f"{0.1 * Z_EMPTY:.3e}", "MARK_DEPTH": MARK_DEPTH}


def unoffset(z: np.ndarray, offset: float) -> np.ndarray:
    """Pass 1's z (H, W) with its class's offset (a multiple of ``offset``, :meth:`GatherRenderer._depth_pass`) taken
    off; Z_EMPTY stays (the shaders' unoffset)."""
    z = np.asarray(z, np.float32)
    k = np.floor(z / np.float32(offset)) if offset > 0 else np.zeros_like(z)
    return np.where(z < 0.1 * Z_EMPTY, z - np.float32(offset) * k, z)


def fill_offset(far: float) -> float:
    """Metres added to the fill's z in pass 1 (module docstring): beyond any z of the frame (its
    far plane), small enough that float32 keeps the z to ~1e-7 of it."""
    return 2.0 * float(far) + 1.0


class GatherRenderer(Renderer):
    """Owns the GPU buffers and programs of the gather method for one model.

    Args:
        ctx: moderngl context.
        rgbz: the kept views (volume.model.RgbzImages), read through ``rgbz.crop(n)`` one at a
            time; with a matte (RgbzImages.has_alpha) the colours are blended premultiplied and
            the frame gets the blended alpha (without one: opaque where depth > 0).
        bounds: (2, 3) object box: the centre where viewing angles are measured, near / far.
        options: default per-frame options (none is read).
        config: the method's constants (gather_reference.GatherConfig).
        resident: views held on the GPU at once (render.crops.RESIDENT_VIEWS; >= k_depth + k_blend).
        backdrop: every kept view was matted against a backdrop (render.gather.alpha_mass.backdrop_matted; the
            coverage pull's "auto").
    """

    name = "gather"

    def __init__(self, ctx, rgbz, bounds, options: RenderOptions | None = None,
                 config: gr.GatherConfig | None = None, resident: int = RESIDENT_VIEWS, backdrop: bool = False):
        super().__init__(ctx, options)
        self.cfg = config or gr.GatherConfig()
        #: the coverage pull runs (render.gather.alpha_mass): "on", or "auto" with every view matted on a backdrop
        self.pulls = self.cfg.alpha_mass == "on" or (self.cfg.alpha_mass == "auto" and backdrop)
        self.cameras = tuple(rgbz.cameras)
        if not self.cameras:
            raise ValueError("gather renderer: the model has no input camera")
        self.bounds = np.asarray(bounds, np.float64)
        self.centre = self.bounds.mean(axis=0)
        self.image_size = rgbz.size
        self.crops = self.own(CropTextures(ctx, rgbz, resident))
        self.rgbz = rgbz
        #: per view: points in its vertex buffer, -1 while the view is not resident (:meth:`load`)
        self.counts = np.full(len(self.cameras), -1, int)
        #: per view: of those, the measured ones (first in the buffer; the rest is the fill)
        self.measured_counts = np.zeros(len(self.cameras), int)
        #: per view: the sum of its matte (render.gather.alpha_mass), NaN until the view is first loaded
        self.masses = np.full(len(self.cameras), np.nan)
        #: the model's alpha excess f (render.gather.alpha_mass.excess), measured on the first still frame read
        self.excess: float | None = None
        self._point_vaos: dict[int, object] = {}
        self.point_bytes = 0
        has_alpha = self.crops.matte is not None
        #: 1-pixel splats first (GatherConfig.fine_depth; "auto" from the sampled views' mattes)
        fine, self.partial_share = fd.decide(self.cfg.fine_depth, (lambda k: rgbz.crop(k)[3]) if has_alpha else None,
                                             len(self.cameras))
        self.fine = fine and self.cfg.splat_px > 1
        self.depth_prog = self.own(program(ctx, "gather_depth_vert.glsl", "gather_depth_frag.glsl"))
        #: passes 1b and 2a (the second layer) where the model has a matte and the config asks for it
        self.layered = has_alpha and self.cfg.back_gap_m > 0
        self._fill_offset = 0.0
        #: pass 2 by whether it composites a second layer (a draft frame does not: RenderOptions.draft)
        self.progs, self.vaos = {}, {}
        for under in {False, self.layered}:
            d = dict(shader_defines(self.cfg, has_alpha), BACK_LAYER=int(under))
            self.progs[under] = self.own(program(ctx, "resolve_vert.glsl", "gather_frag.glsl", defines=d))
            self.vaos[under] = self.own(ctx.vertex_array(self.progs[under], []))
        if self.layered:
            self.mark_prog = self.own(program(ctx, "resolve_vert.glsl", "gather_mark_frag.glsl",
                                              defines=mark_defines(self.cfg)))
            self.under_prog = self.own(program(ctx, "resolve_vert.glsl", "gather_under_frag.glsl",
                                               defines=shader_defines(self.cfg, has_alpha)))
            self.mark_vao = self.own(ctx.vertex_array(self.mark_prog, []))
            self.under_vao = self.own(ctx.vertex_array(self.under_prog, []))

    def load(self, views=None) -> None:
        """Make the given views (default: as many as are resident at once) resident: the crop's
        texture layer (render.crops.CropTextures, least recently used replaced) and the view's RGB-D
        points (its own vertex buffer, freed with the layer).  A frame loads the views it reads."""
        todo = range(self.crops.capacity) if views is None else views
        self.crops.load(todo, on_load=self._load_points, on_evict=self._drop_points)

    def _load_points(self, i, rect, rgb, depth, alpha) -> None:
        if self.pulls and alpha is not None:  # render.gather.alpha_mass: the view's own matte mass, for the excess
            self.masses[i] = am.matte_mass(alpha)
        m = self.rgbz.measured_mask(i) if self.cfg.measured_first else None
        if m is None:
            pts = pr.back_project_crop(self.cameras[i], rect, rgb, depth).points
            self.measured_counts[i] = len(pts)
        else:
            d = np.asarray(depth)
            meas = pr.back_project_crop(self.cameras[i], rect, rgb, np.where(m, d, 0)).points
            fill = pr.back_project_crop(self.cameras[i], rect, rgb, np.where(m, 0, d)).points
            self.measured_counts[i] = len(meas)
            pts = np.concatenate([meas, fill])
        pts = np.ascontiguousarray(pts, np.float32)
        self.counts[i] = len(pts)
        if len(pts):
            vbo = self.own(self.ctx.buffer(pts.tobytes()))
            self._point_vaos[i] = (vbo, self.own(self.ctx.vertex_array(self.depth_prog, [(vbo, "3f", "in_pos")])))
            self.point_bytes += pts.nbytes

    def _drop_points(self, i) -> None:
        self.counts[i] = -1
        vbo, vao = self._point_vaos.pop(i, (None, None))
        self.free(vao, vbo)

    @property
    def uploaded_bytes(self) -> int:
        """Bytes uploaded so far: the loaded crops' texels and points."""
        return self.crops.bytes + self.point_bytes

    @property
    def tex(self):
        """The RGBz crop texture array (render.crops.CropTextures.rgbz)."""
        return self.crops.rgbz

    @property
    def alpha_tex(self):
        """The matte crop texture array, or None without a matte."""
        return self.crops.matte

    @classmethod
    def from_model(cls, ctx, model, options: RenderOptions | None = None,
                   config: gr.GatherConfig | None = None) -> GatherRenderer:
        """Renderer of a volume.model.Model's RGBz images (its kept views and their depth), read
        crop by crop (render.crops): never the full stacks."""
        return cls(ctx, model.rgbz, model.bounds, options, config, backdrop=am.backdrop_matted(model.params))

    def views(self, eye: Camera, exclude: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(depth cameras, blend cameras, blend weights 1 / angle) of a frame: the nearest in
        viewing angle (render.points.reference.nearest_views), view ``exclude`` left out."""
        cfg = self.cfg
        k = max(cfg.k_depth, cfg.k_blend)
        idx, ang = pr.nearest_views(eye, self.cameras, self.centre, k + (exclude is not None))
        keep = idx != exclude
        idx, ang = idx[keep][:k], ang[keep][:k]
        return idx[: cfg.k_depth], idx[: cfg.k_blend], 1.0 / np.maximum(ang[: cfg.k_blend], pr.ANGLE_EPS)

    def _depth_pass(self, eye: Camera, cams, near: float, far: float, fill_offset: float):
        ctx = self.ctx
        tgt = self.target(eye.width, eye.height, colours=(1, 1) if self.layered else (1,), depth=False, name="front")
        tgt.fbo.use()
        ctx.viewport = (0, 0, eye.width, eye.height)
        tgt.fbo.clear(Z_EMPTY, Z_EMPTY, Z_EMPTY, Z_EMPTY)
        ctx.enable_only(ctx.BLEND)
        ctx.blend_func = ctx.ONE, ctx.ONE
        ctx.blend_equation = ctx.MIN
        prev_point_size = ctx.point_size
        p = self.depth_prog
        p["view_proj"].write(mat4_bytes(eye.gl_projection(near, far) @ eye.gl_view()))
        p["eye_z_row"].value = tuple(float(x) for x in eye.cam_from_world[2])
        # (point size, measured points' offset, fill's offset): MIN keeps the first class that lands in a pixel;
        # fine depth: measured 1 px, measured splats, fill 1 px, fill splats (the twin's measured_first_depth)
        rounds = (((1.0, 0.0, 2 * fill_offset), (float(self.cfg.splat_px), fill_offset, 3 * fill_offset))
                  if self.fine else ((float(self.cfg.splat_px), 0.0, fill_offset),))
        for size, z_measured, z_fill in rounds:
            ctx.point_size = size
            for i in cams:
                n, nm = int(self.counts[i]), int(self.measured_counts[i])
                if n > 0:
                    vao = self._point_vaos[int(i)][1]
                    p["z_offset"].value = z_measured
                    if nm:
                        vao.render(ctx.POINTS, vertices=nm)
                    p["z_offset"].value = z_fill
                    if n > nm:
                        vao.render(ctx.POINTS, vertices=n - nm, first=nm)
        # the context may be shared (tests, the viewer): leave its state as found
        ctx.point_size = prev_point_size
        ctx.blend_equation = ctx.FUNC_ADD
        ctx.disable(ctx.BLEND)
        return tgt

    def read_back_depth(self, eye: Camera) -> np.ndarray | None:
        """The second layer's z-depth (H, W; 0 = none) of the last frame drawn for ``eye``'s size
        (pass 1b's target, for tests and debugging), or None without a second layer."""
        if not self.layered:
            return None
        tgt = self.target(eye.width, eye.height, colours=(1, 1), depth=False, name="front")
        z = gl_rows_to_image(tgt.read_colour(0))
        far = -gl_rows_to_image(tgt.read_colour(1))
        front = unoffset(z, self._fill_offset)
        return np.where((z < 0.1 * Z_EMPTY) & (far > front + np.float32(self.cfg.back_gap_m)), far, 0.0)

    def _blend_uniforms(self, p, eye: Camera, blend, weights) -> None:
        """The eye's and the blend cameras' uniforms of gather_blend.glsl in program ``p``; the crops bound."""
        K = self.cfg.k_blend
        self.tex.use(1)
        p["rgbz"].value = 1
        if self.alpha_tex is not None:
            self.alpha_tex.use(2)
            p["matte"].value = 2
        p["height"].value = eye.height
        p["view_size"].value = tuple(int(v) for v in self.image_size)
        p["eye_intr"].value = (eye.K[0, 0], eye.K[1, 1], eye.K[0, 2], eye.K[1, 2])
        p["eye_skew"].value = float(eye.K[0, 1])
        p["eye_rot"].write(np.ascontiguousarray(eye.world_from_cam[:3, :3].T, np.float32).tobytes())
        p["eye_center"].value = tuple(float(x) for x in eye.center)
        cfw = np.zeros((K, 4, 4), np.float32)
        intr = np.zeros((K, 4), np.float32)
        skew, layer, w = np.zeros(K, np.float32), np.zeros(K, np.int32), np.zeros(K, np.float32)
        rect = np.zeros((K, 4), np.int32)
        for j, (i, wj) in enumerate(zip(blend, weights)):
            c = self.cameras[i]
            cfw[j] = c.cam_from_world.T  # column-major mat4
            intr[j] = (c.K[0, 0], c.K[1, 1], c.K[0, 2], c.K[1, 2])
            skew[j], layer[j], w[j], rect[j] = c.K[0, 1], self.crops.layer[i], wj, self.crops.rects[i]
        p["rect"].write(rect.tobytes())
        p["cfw"].write(cfw.tobytes())
        p["intr"].write(intr.tobytes())
        p["skew"].write(skew.tobytes())
        p["layer"].write(layer.tobytes())
        p["weight"].write(w.tobytes())

    def _full_screen(self, eye: Camera, name: str):
        """Bind and clear (0) an RGBA32F target of the eye's size for a full-screen pass."""
        ctx = self.ctx
        tgt = self.target(eye.width, eye.height, colours=(4,), depth=False, name=name)
        tgt.fbo.use()
        ctx.viewport = (0, 0, eye.width, eye.height)
        tgt.fbo.clear(0.0, 0.0, 0.0, 0.0)
        ctx.disable(ctx.DEPTH_TEST | ctx.BLEND)
        return tgt

    def _under_pass(self, eye: Camera, zt, blend, weights, fill_offset: float, timed=None):
        """Passes 1b and 2a: depth MARK_DEPTH where the pixel has a second layer (gather_mark_frag.glsl),
        then behind a depth test that passes only there, its colour and how solid it is
        (gather_under_frag.glsl).  ``timed(name, draw)`` (scripts/gather_layers.py) runs each draw: "mark",
        "under" and, with the depth test off, "under, test off"; default: draws mark and under."""
        ctx = self.ctx
        run = timed or (lambda name, draw: None if name.endswith("test off") else draw())
        tgt = self.target(eye.width, eye.height, colours=(4,), depth=True, name="under")
        tgt.fbo.use()
        ctx.viewport = (0, 0, eye.width, eye.height)
        tgt.fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        ctx.enable_only(ctx.DEPTH_TEST)
        ctx.depth_func = "1"
        zt.colours[0].use(0)
        zt.colours[1].use(4)
        self.mark_prog["front_z"].value = 0
        self.mark_prog["far_z"].value = 4
        self.mark_prog["fill_offset"].value = fill_offset
        run("mark", lambda: self.mark_vao.render(ctx.TRIANGLES, vertices=3))
        tgt.fbo.depth_mask = False
        ctx.depth_func = ">"
        self.under_prog["far_z"].value = 4
        self._blend_uniforms(self.under_prog, eye, blend, weights)
        run("under", lambda: self.under_vao.render(ctx.TRIANGLES, vertices=3))
        ctx.disable(ctx.DEPTH_TEST)
        run("under, test off", lambda: self.under_vao.render(ctx.TRIANGLES, vertices=3))
        tgt.fbo.depth_mask = True
        ctx.depth_func = "<"
        return tgt

    def _gather_pass(self, eye: Camera, zt, blend, weights, fill_offset: float, ut=None):
        tgt = self._full_screen(eye, "")
        p = self.progs[ut is not None]
        zt.colours[0].use(0)
        p["front_z"].value = 0
        p["fill_offset"].value = fill_offset
        if ut is not None:
            ut.colours[0].use(3)
            p["under"].value = 3
        self._blend_uniforms(p, eye, blend, weights)
        self.vaos[ut is not None].render(self.ctx.TRIANGLES, vertices=3)
        return tgt

    def _render(self, eye: Camera, options: RenderOptions, read: bool) -> Frame:
        fr = self._drawn(eye, options, read)
        if not read or self.crops.matte is None or not self.pulls or options.draft:
            return fr
        if self.excess is None:
            self.excess = self._measure_excess(options)
        rgb, alpha, d = am.pull(fr.rgb, fr.alpha, self.excess)  # render.gather.alpha_mass (the reference's step)
        return Frame(rgb, alpha, fr.depth, replace(fr.stats, alpha_pull=d))

    def _measure_excess(self, options: RenderOptions) -> float:
        """render.gather.alpha_mass.excess of this model: alpha_mass.loo_views's kept views drawn from the others."""
        drawn, own = [], []
        for k in am.loo_views(len(self.cameras)):
            drawn.append(am.matte_mass(self._drawn(self.cameras[k], options, True, exclude=k).alpha))
            own.append(float(self.masses[k]) if np.isfinite(self.masses[k]) else am.matte_mass(self.rgbz.crop(k)[3]))
        return am.excess(drawn, own)

    def _drawn(self, eye: Camera, options: RenderOptions, read: bool, exclude: int | None = None) -> Frame:
        """The frame as drawn (without render.gather.alpha_mass), view ``exclude`` left out."""
        depth_cams, blend, weights = self.views(eye, exclude)
        self.load(np.concatenate([depth_cams, blend]))
        near, far = near_far(eye, self.bounds)
        off = fill_offset(far)
        with FrameTimer(self.ctx) as t:
            zt = self._depth_pass(eye, depth_cams, near, far, off)
            self._fill_offset = off
            ut = self._under_pass(eye, zt, blend, weights, off) if self.layered and not options.draft else None
            ct = self._gather_pass(eye, zt, blend, weights, off, ut)
        stats = FrameStats(t.ms, t.cpu_ms, supersample=1, facets=int(self.counts[depth_cams].sum()),
                           fine_depth=float(self.fine), partial_share=self.partial_share)
        if not read:
            return Frame.empty(eye.width, eye.height, stats)
        rgba = gl_rows_to_image(ct.read_colour(0))
        z = gl_rows_to_image(zt.read_colour(0))
        z = unoffset(z, off)
        drawn = rgba[..., 3] > 0
        depth = np.where(drawn, z, 0.0)
        filled = drawn & ~(z < 0.1 * Z_EMPTY)   # pixels the shader's pinhole fill drew (a few)
        if filled.any():
            ys, xs = np.nonzero(filled)
            depth[ys, xs] = gr.pinhole_mean(z, ys, xs)
        return Frame(rgba[..., :3], rgba[..., 3], depth, stats)

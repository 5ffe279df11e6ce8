"""View-dependent microfacet billboards on the GPU (docs/methods.md §1.2-§1.7).

All surface voxel centres of every pyramid level (each in 6 axis-sorted orders), the input
cameras and the RGBz texture array are uploaded once; per frame only uniforms change (plus
the 16-byte reset of the indirect draw command).  Two interchangeable paths, chosen per frame
(``MicrofacetOptions.mode``, render/microfacet/spec.py; this is the ``"microfacet"`` method of render.methods):

* ``"instanced"`` (default): a compute pass selects the cameras per voxel and appends one
  record per slice (atomic counter -> indirect draw command); an instanced 4-vertex strip
  draws one square per record.  The record count is the facet count.
* ``"geometry"``: one point per voxel; a geometry shader selects the cameras and emits the
  slices (counted with a primitives-generated query).

The vertex stage projects each slice corner into the candidate cameras (homogeneous, so the
fragment gets exact projections by interpolation); the fragment shader applies Eq. 2 with the
RGBz array, lets the blend cameras vote with unstructured-lumigraph weights and falls back per
fragment to the next camera (microfacet_geometry.shade_fragments); alpha is binary (discard)
and the depth buffer resolves visibility, so nothing is sorted for correctness (the voxel
order along the view's dominant axis only helps llvmpipe's early depth test).  The numpy twin
of every step is ``render/microfacet/geometry.py`` (the level of detail: ``render/microfacet/lod.py``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from capture.camera import Camera, image_axes
from capture.sampling import voxel_centres
from render.frame import Frame, FrameStats
from render.gl import load_shader, program
from render.methods import Renderer, RenderOptions
from render.microfacet import cull as mcull
from render.microfacet import geometry as mg
from render.microfacet import lod as mlod
from render.microfacet.rgbz_textures import RGBZ_DTYPE, layer_textures
from render.microfacet.spec import MicrofacetOptions
from render.owner import FrameTimer, mat4_bytes, near_far

#: Compute work-group size of microfacet_select.glsl.
LOCAL_SIZE = 64
#: Bytes of one slice tile record (5 x vec4, microfacet_slice.glsl).
SLICE_BYTES = 80
#: Most levels of the depth-bounds pyramid (a 2^15 pixel image).
MAX_PYR_LEVELS = 16
#: Cull slice tiles on which no camera can pass Eq. 2 (render/microfacet/cull.py; exact).
CULL = True
#: Instanced path in two passes: a visibility pre-pass (Eq. 2 and the vote on the depths alone)
#: leaves per sample the nearest drawn slice, then one colour pass shades each drawn sample once
#: (on llvmpipe every rasterised fragment costs the whole shader; most are discarded).
PREPASS = True

#: RGBZ_DTYPE (render.microfacet.rgbz_textures): half floats (8 bytes per texel; the fetches are
#: the fragment cost on llvmpipe).  Depth in half float: 0.24 mm steps at 0.5 m.


def shader_defines(rule: str = "vote", n_fallback: int | None = None, refine: int | None = None,
                   debug: str | None = None, has_alpha: bool = False) -> dict:
    """Constants shared by the GLSL and the numpy twin (one source: microfacet_geometry)."""
    if rule not in mg.FALLBACK_RULES:
        raise ValueError(f"unknown fallback rule {rule!r}; use one of {mg.FALLBACK_RULES}")
    if debug not in mg.DEBUG_OUTPUTS:
        raise ValueError(f"unknown debug output {debug!r}; use one of {mg.DEBUG_OUTPUTS[1:]}")
    return {
        "DEBUG_VIEW": mg.DEBUG_OUTPUTS.index(debug),
        "DEBUG_BACK_DEPTH": f"{mg.DEBUG_BACK_DEPTH:.9f}",
        "FALLBACK_RULE": mg.FALLBACK_RULES.index(rule),
        "N_FALLBACK": mg.N_FALLBACK if n_fallback is None else int(n_fallback),
        "ALPHA_VOTE": f"{mg.ALPHA_VOTE:.6f}",
        "K_BLEND": mg.K_BLEND,
        "K_CAND": mg.K_CAND,
        "N_PROJ": mg.K_BLEND + (mg.N_FALLBACK if n_fallback is None else int(n_fallback)),
        "MAX_SLICES": mg.MAX_SLICES,
        "MAX_VERTS": 4 * mg.MAX_SLICES,
        "PHI_EPS": f"{mg.PHI_EPS:.9e}",
        "WEIGHT_EPS": f"{mg.WEIGHT_EPS:.9e}",
        "ULR_THRESHOLD_FACTOR": f"{mg.ULR_THRESHOLD_FACTOR:.6f}",
        "SLICE_SIDE": f"{mg.SLICE_SIDE_FACTOR:.9f}",
        "FOOTPRINT_SCALE": f"{mg.FOOTPRINT_SCALE:.6f}",
        "SLAB_COVER": f"{mg.SLAB_COVER:.6f}",
        "TIGHT_RECT": int(mg.TIGHT_RECT),
        "RECT_CLAMP": f"{mg.RECT_CLAMP:.6f}",
        "FREE_FACTOR": f"{mg.FREE_FACTOR:.6f}",
        "UNSURE_WEIGHT": f"{mg.UNSURE_WEIGHT:.6f}",
        "DEPTH_REFINE": mg.DEPTH_REFINE if refine is None else int(refine),
        "REFINE_RANGE": f"{mg.REFINE_RANGE:.6f}",
        "REFINE_ACCEPT": f"{mg.REFINE_ACCEPT:.6f}",
        "PIX_MARGIN": f"{mcull.PIX_MARGIN:.6f}",
        "VOTE_MARGIN": f"{mcull.VOTE_MARGIN:.9e}",
        "BOUND_BLOCKS": mcull.BOUND_BLOCKS,
        "EMPTY_MIN": f"{mcull.EMPTY_MIN:.1f}",
        "TOL_MARGIN_REL": f"{mcull.TOL_MARGIN_REL:.9e}",
        "TOL_MARGIN_ABS": f"{mcull.TOL_MARGIN_ABS:.9e}",
        "MAX_TILES": mcull.MAX_TILES,
        "MAX_PYR_LEVELS": MAX_PYR_LEVELS,
        "HAS_ALPHA": int(has_alpha),
    }


def camera_block(cameras) -> bytes:
    """std430 array of ``Cam`` structs (microfacet_common.glsl) for the input cameras."""
    out = np.zeros((max(len(cameras), 1), 40), np.float32)
    for i, c in enumerate(cameras):
        out[i, :16] = c.cam_from_world.T.reshape(-1)  # column-major mat4
        out[i, 16:20] = [c.K[0, 0], c.K[1, 1], c.K[0, 2], c.K[1, 2]]
        out[i, 20:24] = [c.width, c.height, c.K[0, 1], 0.0]
        out[i, 24:27] = c.center
        out[i, 28:40] = (c.K @ c.cam_from_world[:3]).reshape(-1)  # rows of K [R | t]
    return out.tobytes()


def eye_projections(cameras, eye_pos: np.ndarray) -> bytes:
    """std430 ``vec4`` per camera: the homogeneous projection (u z, v z, z) of the eye centre
    (cam_project_h; microfacet_common.glsl ``eye_h``), computed once per frame in float64."""
    out = np.zeros((max(len(cameras), 1), 4), np.float32)
    for i, c in enumerate(cameras):
        out[i, :3] = mg.project_h(c, np.asarray(eye_pos, np.float64)[None])[0]
    return out.tobytes()


@dataclass(frozen=True, kw_only=True)
class MicrofacetStats(FrameStats):
    """FrameStats plus the level of detail of the frame.

    Attributes:
        level: pyramid level index drawn (-1: nothing to draw).
        resolution: that level's L.
        tiles: slice tiles drawn (instanced path: the slices split into tiles, those on which
            no camera can pass Eq. 2 culled, render/microfacet/cull.py; else = facets).
        passes: when the renderer's ``profile`` is on, {pass: (wall ms, CPU ms)} of the frame's
            passes, each synchronised: "select" (compute pass and its count read back), "prepass"
            and "colour" (two-pass path) or "draw" / "fill" / "geometry", "resolve", "read"
            (read-back to numpy); else empty.
        spacing: slice spacing l (m).
        lod: the automatic level-of-detail choice (Eq. 10-11) for this eye.
    """

    level: int = -1
    resolution: int = 0
    spacing: float = 0.0
    lod: mlod.Lod | None = field(default=None, repr=False, compare=False)
    tiles: int = 0
    passes: dict = field(default_factory=dict, compare=False)

    def record(self) -> dict:
        """FrameStats.record plus ``level`` (the resolution L, as furrow eval has always written
        it) and ``spacing_m``."""
        out = {**super().record(), "level": int(self.resolution), "spacing_m": float(self.spacing),
               "tiles": int(self.tiles)}
        if self.passes:
            out["passes"] = {k: {"ms": float(v[0]), "cpu_ms": float(v[1])} for k, v in self.passes.items()}
        return out


class MicrofacetRenderer(Renderer):
    """Owns the GPU buffers and programs of the microfacet renderer for one model.

    Args:
        ctx: a moderngl context (render.gl.create_context()).
        levels: the pyramid levels (volume.model.SdfLevel, coarse -> fine).
        rgbz: the RGBz images (volume.model.RgbzImages, with its matte when it has one), uploaded
            view by view (render.microfacet.rgbz_textures.layer_textures), never as full stacks.
        bounds: (2, 3) object box (near/far planes, LOD centre).
        options: default per-frame options (render.methods.RenderOptions: ``supersample`` and this
            method's own, render.microfacet.spec.MicrofacetOptions).
        rule: per-fragment fallback rule, "vote" or "any" (microfacet_geometry.shade_fragments).
        n_fallback: fallback candidates tried after the blend cameras (default N_FALLBACK).
        cull: split the instanced path's slices into tiles and drop those on which no camera
            can pass Eq. 2 (render/microfacet/cull.py; the frame is unchanged); an attribute,
            may change between frames.
        tile_px: target tile side in drawn pixels (supersampled; attribute ``tile_px``).
        prepass: draw the instanced path as a visibility pre-pass and a colour pass (PREPASS;
            attribute ``prepass``); False = one pass with the whole shader per fragment.

    The programs are compiled on first use per parallax-refinement setting (the only option
    that is a shader constant), so options change per frame without re-uploading anything.
    """

    name = "microfacet"

    def __init__(self, ctx, levels, rgbz, bounds, options: RenderOptions | None = None,
                 rule: str = "vote", n_fallback: int | None = None, cull: bool = CULL,
                 tile_px: float = mcull.TILE_PX, prepass: bool = PREPASS):
        super().__init__(ctx, options)
        self.levels = tuple(levels)
        self.surfaces = mlod.covering_surfaces(self.levels)
        self.cameras = tuple(rgbz.cameras)
        self.bounds = np.asarray(bounds, dtype=np.float64)
        self.voxel_sizes = [lv.voxel_size for lv in self.levels]
        self.counts = [len(x) for x in self.surfaces]
        if len(self.cameras) == 0:
            raise ValueError("microfacet renderer: the model has no input camera")
        shader_defines(rule, n_fallback)  # validates the rule
        self.n_fallback = mg.N_FALLBACK if n_fallback is None else int(n_fallback)
        self.rule = rule
        # Per level, the voxel centres in 6 orders (front to back along +-x, +-y, +-z): the
        # frame uses the one closest to its view direction, so that llvmpipe's early depth
        # test rejects more fragments before shading (measured ~20-25 % per frame vs back to front).
        self.voxel_bufs = []
        self.orders = []
        for lv, surf in zip(self.levels, self.surfaces):
            cen = voxel_centres(surf, lv.origin, lv.voxel_size)
            bufs, ords = [], []
            for axis in range(6):
                direction = np.zeros(3)
                direction[axis // 2] = 1.0 if axis % 2 == 0 else -1.0
                o = np.argsort(cen @ direction, kind="stable") if len(cen) else np.zeros(0, np.int64)
                c = np.zeros((max(len(cen), 1), 4), np.float32)
                c[: len(cen), :3] = cen[o]
                bufs.append(self.own(ctx.buffer(c.tobytes())))
                ords.append(o)
            self.voxel_bufs.append(bufs)
            self.orders.append(ords)
        self._last_order = None
        self.cam_buf = self.own(ctx.buffer(camera_block(self.cameras)))
        self.eye_buf = self.own(ctx.buffer(reserve=16 * max(len(self.cameras), 1)))
        W, H = self.tex_size = rgbz.size
        n = len(self.cameras)
        self.ztex = self.own(ctx.texture_array((W, H, n), 1, None, dtype="f2"))
        self.ztex.filter = (ctx.NEAREST, ctx.NEAREST)
        self.ztex.repeat_x = self.ztex.repeat_y = False
        pyrs = []  # per view, the min / max pyramid of its depths as the texture holds them (microfacet_cull)

        def on_view(i, texels):
            z = np.ascontiguousarray(texels[..., 3].astype(RGBZ_DTYPE))
            self.ztex.write(z.tobytes(), viewport=(0, 0, i, W, H, 1))
            pyrs.append(mcull.depth_bounds_pyramid(z.astype(np.float32)[None]))

        tex, matte = layer_textures(ctx, rgbz, on_view=on_view)
        self.tex, self.matte = self.own(tex), None if matte is None else self.own(matte)
        pyr = [np.concatenate(lv) for lv in zip(*pyrs)]
        pyrs.clear()
        if len(pyr) > MAX_PYR_LEVELS:
            raise ValueError(f"microfacet renderer: RGBz images of {W}x{H} need {len(pyr)} pyramid levels "
                             f"(at most {MAX_PYR_LEVELS})")
        words, self.pyr_offsets = mcull.pack_pyramid(pyr)
        self.pyr_buf = self.own(ctx.buffer(words.tobytes()))
        self.prepass = bool(prepass)
        self.cull = bool(cull)
        #: Time every pass of the next frames (MicrofacetStats.passes; synchronises between passes).
        self.profile = False
        self._timer = FrameTimer(ctx)
        self.tile_px = float(tile_px)
        self.max_records = max(max(self.counts), 1) * mg.MAX_SLICES
        self.slice_buf = self.own(ctx.buffer(reserve=self.max_records * SLICE_BYTES))
        self.indirect = self.own(ctx.buffer(reserve=20))  # draw command + slice count
        self.query = ctx.query(primitives=True)  # moderngl queries have no release()
        self._programs: dict[tuple, tuple] = {}

    @classmethod
    def from_model(cls, ctx, model, options: RenderOptions | None = None, rule: str = "vote",
                   n_fallback: int | None = None) -> MicrofacetRenderer:
        """Renderer for a volume.model.Model (with its matte, RgbzImages.alpha, when it has one)."""
        return cls(ctx, model.pyramid.levels, model.rgbz, model.bounds, options, rule, n_fallback)

    def level_centers(self, level: int) -> np.ndarray:
        """(N, 3) world centres of the voxels drawn on ``level`` (see render.microfacet.lod.covering_surfaces)."""
        lv = self.levels[level]
        return voxel_centres(self.surfaces[level], lv.origin, lv.voxel_size)

    def _program(self, kind: str, refine: int, debug: str | None = None):
        """(program, vertex array) of ``kind`` ("select" (tiles, culled), "select_all" (one record
        per slice), "draw", "fill", "geometry", "prepass", "colour") for ``refine``
        parallax-correction steps and the ``debug`` output, compiled on first use."""
        refines = kind in ("draw", "geometry", "colour")  # the others never refine ...
        key = (kind, refine if refines else 0, debug if kind in ("draw", "geometry") else None)  # ... or debug
        if key not in self._programs:
            ctx = self.ctx
            d = shader_defines(self.rule, self.n_fallback, key[1], key[2], self.matte is not None)
            if kind in ("select", "select_all"):
                d = {**d, "CULL": int(kind == "select")}
                self._programs[key] = (self.own(ctx.compute_shader(load_shader("microfacet_select.glsl", d))), None)
            elif kind == "prepass":
                d = {**shader_defines(self.rule, self.n_fallback, 0), "DEPTH_ONLY": 1}
                prog = self.own(program(ctx, "microfacet_vert.glsl", "microfacet_prepass_frag.glsl", defines=d))
                self._programs[key] = (prog, self.own(ctx.vertex_array(prog, [])))
            elif kind == "colour":
                prog = self.own(program(ctx, "microfacet_colour_vert.glsl", "microfacet_colour_frag.glsl", defines=d))
                self._programs[key] = (prog, self.own(ctx.vertex_array(prog, [])))
            else:
                frag = "microfacet_quad_frag.glsl" if kind == "fill" else "microfacet_frag.glsl"
                vert = "microfacet_points_vert.glsl" if kind == "geometry" else "microfacet_vert.glsl"
                if kind == "fill":
                    d = {**d, "FILL_ONLY": 1}  # positions only: the bare fill
                geom = "microfacet_geom.glsl" if kind == "geometry" else None
                prog = self.own(program(ctx, vert, frag, geometry=geom, defines=d))
                self._programs[key] = (prog, self.own(ctx.vertex_array(prog, [])))
        return self._programs[key]

    # ------------------------------------------------------------------ frame
    def choose_lod(self, eye: Camera, tolerance_px: float) -> mlod.Lod:
        """Level and spacing for this eye (Eq. 10-11, microfacet_lod.choose_lod)."""
        center = self.bounds.mean(axis=0)
        return mlod.choose_lod(eye, center, self.cameras, self.voxel_sizes, self.counts, tolerance_px)

    def level_index(self, resolution: int) -> int:
        """Index of the pyramid level of resolution L (MicrofacetOptions.level)."""
        res = [lv.resolution for lv in self.levels]
        if resolution not in res:
            raise ValueError(f"level {resolution}: the model has levels {res}")
        return res.index(resolution)

    def frame_lod(self, eye: Camera, options: MicrofacetOptions) -> tuple[int, float, mlod.Lod]:
        """(level index, slice spacing l, automatic choice) of a frame: Eq. 10-11, or the
        options' forced level (spacing by Eq. 10 on it) and spacing."""
        lod = self.choose_lod(eye, options.tolerance_px)
        lev = lod.level if options.level is None else self.level_index(options.level)
        w = self.voxel_sizes[lev]
        spacing = options.spacing
        if spacing is None:
            spacing = lod.spacing if options.level is None else max(mlod.eq10_spacing(lod.e_world, lod.phi, w),
                                                                    mlod.min_spacing(w))
        return lev, max(float(spacing), mlod.min_spacing(w)), lod

    def _uniforms(self, prog, eye: Camera, level: int, spacing: float, near: float, view_proj: np.ndarray):
        right, up = image_axes(eye)
        w = self.voxel_sizes[level]
        vals = {"n_cams": len(self.cameras), "eye_pos": tuple(eye.center), "eye_right": tuple(right),
                "eye_up": tuple(up), "spacing": spacing, "voxel_size": w, "near_plane": near}
        for k, v in vals.items():
            if k in prog:
                prog[k].value = v
        if "view_proj" in prog:
            prog["view_proj"].write(mat4_bytes(view_proj))
        for name, unit in (("rgbz", 0), ("zdepth", 1), ("records", 2), ("matte", 3)):
            if name in prog:
                prog[name].value = unit
        for name, value in (("tex_size", self.tex_size), ("depth_size", self.tex_size)):
            if name in prog:
                prog[name].value = value

    def _draw(self, eye: Camera, options: MicrofacetOptions, f: int, lev: int, spacing: float, near: float,
              view_proj: np.ndarray) -> tuple[int, int]:
        """Select and draw the slices of level ``lev`` into the bound target; returns the counts of
        slices (facets) and of tiles drawn."""
        ctx = self.ctx
        n_vox = self.counts[lev]
        self.cam_buf.bind_to_storage_buffer(0)
        self.eye_buf.write(eye_projections(self.cameras, eye.center))
        self.eye_buf.bind_to_storage_buffer(5)
        axis = view_axis(eye)
        self.voxel_bufs[lev][axis].bind_to_storage_buffer(1)
        self._last_order = self.orders[lev][axis]
        self.tex.use(0)
        if self.matte is not None:
            self.matte.use(3)
        if options.mode == "geometry" and not options.fill_only:
            prog, vao = self._program("geometry", options.refine_steps, options.debug)
            self._uniforms(prog, eye, lev, spacing, near, view_proj)
            with self.query:
                vao.render(mode=ctx.POINTS, vertices=n_vox)
            ctx.finish()
            self._timer.lap("geometry")
            facets = int(self.query.primitives) // 2  # two triangles per square
            return facets, facets
        while True:
            records = self._select(eye, options, f, lev, spacing, near, view_proj)
            if records <= self.max_records:
                break
            # more tiles than the buffer holds: grow it and select again (rare: first frames)
            self.max_records = int(2 ** np.ceil(np.log2(records)))
            self.free(self.slice_buf)
            self.slice_buf = self.own(ctx.buffer(reserve=self.max_records * SLICE_BYTES))
        self._timer.lap("select")
        if self._two_pass(options):
            self._two_passes(eye, options, lev, spacing, near, view_proj)
        else:
            prog, vao = self._program("fill" if options.fill_only else "draw", options.refine_steps, options.debug)
            self._uniforms(prog, eye, lev, spacing, near, view_proj)
            vao.render_indirect(self.indirect, mode=ctx.TRIANGLE_STRIP, count=1)
            self._timer.lap("fill" if options.fill_only else "draw")
        ctx.finish()
        return self._slices, records

    def _two_pass(self, options: MicrofacetOptions) -> bool:
        """Whether a frame with ``options`` is drawn as pre-pass + colour pass (the instanced path's
        colour frames; fills and debug views take the one-pass path, which sees every fragment)."""
        return self.prepass and options.mode == "instanced" and not options.fill_only and options.debug is None

    def _two_passes(self, eye: Camera, options: MicrofacetOptions, lev: int, spacing: float, near: float,
                    view_proj: np.ndarray) -> None:
        """The visibility pre-pass (depth + record index per sample) and the colour pass (each
        drawn sample shaded once) into the frame's target (colour 0, record index 1)."""
        ctx = self.ctx
        tgt = self._frame[3]
        colour, records = tgt.colours[0], tgt.colours[1]
        pre_fbo = ctx.framebuffer([records], tgt.depth)
        col_fbo = ctx.framebuffer([colour], tgt.depth)
        try:
            pre_fbo.use()
            self.ztex.use(1)
            prog, vao = self._program("prepass", options.refine_steps)
            self._uniforms(prog, eye, lev, spacing, near, view_proj)
            vao.render_indirect(self.indirect, mode=ctx.TRIANGLE_STRIP, count=1)
            self._timer.lap("prepass")
            col_fbo.use()
            col_fbo.depth_mask = False
            ctx.depth_func = ">"
            records.use(2)
            prog, vao = self._program("colour", options.refine_steps)
            self._uniforms(prog, eye, lev, spacing, near, view_proj)
            prog["target_size"].value = tuple(float(x) for x in tgt.size)
            vao.render(ctx.TRIANGLES, vertices=3)
            self._timer.lap("colour")
            ctx.depth_func = "<"
            tgt.fbo.use()
        finally:
            pre_fbo.release()
            col_fbo.release()

    def _select(self, eye: Camera, options: MicrofacetOptions, f: int, lev: int, spacing: float, near: float,
                view_proj: np.ndarray) -> int:
        """Run the compute pass (slice tiles of level ``lev`` into the slice buffer, their count
        into the indirect draw command); returns the number of tiles it wanted to write."""
        ctx = self.ctx
        n_vox = self.counts[lev]
        self.indirect.write(np.array([4, 0, 0, 0, 0], np.uint32).tobytes())
        self.slice_buf.bind_to_storage_buffer(2)
        self.indirect.bind_to_storage_buffer(3)
        self.pyr_buf.bind_to_storage_buffer(4)
        cull = self.cull and options.debug is None  # debug views show every slice fragment
        select, _ = self._program("select" if cull else "select_all", options.refine_steps)
        self._uniforms(select, eye, lev, spacing, near, view_proj)
        select["n_voxels"].value = n_vox
        select["max_records"].value = self.max_records
        if cull:
            select["tile_px"].value = self.tile_px
            select["eye_focal"].value = float(eye.K[0, 0]) * f  # drawn pixels
            select["pyr_levels"].value = len(self.pyr_offsets)
            select["pyr_offset"].value = tuple(self.pyr_offsets) + (0,) * (MAX_PYR_LEVELS - len(self.pyr_offsets))
        select.run(group_x=(n_vox + LOCAL_SIZE - 1) // LOCAL_SIZE)
        ctx.memory_barrier()
        _, records, _, _, self._slices = (int(x) for x in np.frombuffer(self.indirect.read(), np.uint32))
        if records > self.max_records:  # the draw command must not read past the buffer
            self.indirect.write(np.array([4, self.max_records, 0, 0], np.uint32).tobytes())
        return records

    def _render(self, eye: Camera, options: RenderOptions, read: bool) -> Frame:
        """One frame (Renderer.render).  ``options.supersample`` samples per pixel and axis: the
        frame is drawn at that multiple of the eye's size (E stays in output pixels) and
        box-resolved on the GPU; the method's own options (MicrofacetOptions): ``fill_only`` draws the
        same squares untextured (instanced), a ``debug`` output needs one sample per pixel."""
        f = options.supersample
        options = options.of(self.name)
        if options.debug is not None and f != 1:
            raise ValueError("debug outputs are codes per pixel: they need supersample 1")
        lev, spacing, lod = self.frame_lod(eye, options)
        near, far = near_far(eye, self.bounds)
        draw_eye = eye if f == 1 else eye.scaled(f)
        view_proj = draw_eye.gl_projection(near, far) @ draw_eye.gl_view()
        two_pass = self._two_pass(options)
        self.begin_frame(eye.width, eye.height, f, colours=(4, 1) if two_pass else (4,))
        n_vox = self.counts[lev]
        with FrameTimer(self.ctx, laps=self.profile) as t:
            self._timer = t
            facets, tiles = self._draw(eye, options, f, lev, spacing, near, view_proj) if n_vox > 0 else (0, 0)
            self.resolve_frame()
            t.lap("resolve")
        self._timer = FrameTimer(self.ctx)
        stats = MicrofacetStats(t.ms, t.cpu_ms, supersample=f, facets=facets, level=lev if n_vox > 0 else -1,
                                resolution=self.levels[lev].resolution, spacing=float(spacing), lod=lod, tiles=tiles,
                                passes=t.laps)
        if not read:
            return Frame.empty(eye.width, eye.height, stats)
        with FrameTimer(self.ctx, laps=self.profile) as r:
            back = self.read_frame()
            r.lap("read")
        t.laps.update(r.laps)
        return Frame.from_gl(*back, near, far, stats)

    def read_slices(self, count: int) -> dict:
        """The slice tile records of the last instanced frame (for tests): centres, s, weights,
        candidates, voxel index, slice number, tile rectangle (x0, x1, y0, y1 along the slice axes)."""
        raw = np.frombuffer(self.slice_buf.read(size=count * SLICE_BYTES), np.float32).reshape(count, SLICE_BYTES // 4)
        ints = raw.view(np.int32)
        return {"center": raw[:, 0:3].astype(np.float64), "s": raw[:, 3].astype(np.float64),
                "weights": raw[:, 4:7].astype(np.float64), "cand": np.concatenate([ints[:, 8:12], ints[:, 12:14]], 1),
                "voxel": self._last_order[ints[:, 14]], "n": ints[:, 15].copy(),
                "rect": raw[:, 16:20].astype(np.float64)}


def view_axis(eye: Camera) -> int:
    """Index (2 * axis + (0 if +, 1 if -)) of the world axis direction closest to the eye's
    viewing direction: sorting voxels by their coordinate along it is front to back."""
    f = eye.forward
    a = int(np.argmax(np.abs(f)))
    return 2 * a + (0 if f[a] >= 0 else 1)


"""View-dependent microfacet billboards on the GPU (METHODS §1.2-§1.7).

All surface voxel centres of every pyramid level (each in 6 axis-sorted orders), the input
cameras and the RGBz texture array are uploaded once; per frame only uniforms change (plus
the 16-byte reset of the indirect draw command).  Two interchangeable paths:

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
of every step is ``render/microfacet_geometry.py``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from capture.camera import Camera, gl_ndc_depth_to_z, gl_rows_to_image
from render import microfacet_geometry as mg
from render.antialias import Supersampler, check_factor, split_rgba
from render.gl import program

#: Compute work-group size of microfacet_select.glsl.
LOCAL_SIZE = 64
#: Bytes of one slice record (4 x vec4, microfacet_slice.glsl).
SLICE_BYTES = 64
MODES = ("instanced", "geometry")
#: Most parallax-correction steps accepted (render quality saturates after 2: bench/render.py).
MAX_REFINE = 4


#: Draw, on every coarse level, the ancestors of the finest level's surface voxels too
#: (covering_surfaces): the plant's top vanished from a fused 8^3 level (volume.build), whose
#: surface voxels ended 7.6 cm below the plant's tip.
COARSE_COVERS_FINE = True
#: Storage of the RGBz texture array: half floats (8 bytes per texel; the fetches are the
#: fragment cost on llvmpipe).  Depth in half float: 0.24 mm steps at 0.5 m.
RGBZ_DTYPE = np.float16


def shader_defines(rule: str = "vote", n_fallback: int | None = None, refine: int | None = None) -> dict:
    """Constants shared by the GLSL and the numpy twin (one source: microfacet_geometry)."""
    if rule not in mg.FALLBACK_RULES:
        raise ValueError(f"unknown fallback rule {rule!r}; use one of {mg.FALLBACK_RULES}")
    return {
        "FALLBACK_RULE": mg.FALLBACK_RULES.index(rule),
        "N_FALLBACK": mg.N_FALLBACK if n_fallback is None else int(n_fallback),
        "ALPHA_VOTE": f"{mg.ALPHA_VOTE:.6f}",
        "K_BLEND": mg.K_BLEND,
        "K_CAND": mg.K_CAND,
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
    }


def camera_block(cameras) -> bytes:
    """std430 array of ``Cam`` structs (microfacet_common.glsl) for the input cameras."""
    out = np.zeros((max(len(cameras), 1), 28), np.float32)
    for i, c in enumerate(cameras):
        out[i, :16] = c.cam_from_world.T.reshape(-1)  # column-major mat4
        out[i, 16:20] = [c.K[0, 0], c.K[1, 1], c.K[0, 2], c.K[1, 2]]
        out[i, 20:24] = [c.width, c.height, c.K[0, 1], 0.0]
        out[i, 24:27] = c.center
    return out.tobytes()


def rgbz_array(rgb: np.ndarray, depth: np.ndarray) -> np.ndarray:
    """(N, H, W, 4) float32 RGBz texels: linear rgb + z-depth in metres (0 = none)."""
    return np.concatenate([np.asarray(rgb, np.float32), np.asarray(depth, np.float32)[..., None]], axis=-1)


def _mat(m: np.ndarray) -> bytes:
    return np.asarray(m, dtype=np.float32).T.tobytes()


@dataclass
class Frame:
    """One rendered frame.

    Attributes:
        rgb: (H, W, 3) float32 linear colour, black where nothing was drawn.
        alpha: (H, W) bool foreground.
        level: pyramid level index used (-1: nothing to draw).
        resolution: that level's L.
        spacing: slice spacing l (m).
        facets: number of slices drawn.
        ms: GPU frame time in milliseconds (selection + draw, synchronised; no read-back).
        lod: the level-of-detail choice.
        cpu_ms: process CPU time over the same interval (llvmpipe threads included): the cost
            independent of other load on the machine.
        depth: (H, W) float32 z-depth (metres) of the drawn slices (the nearest sample when
            supersampled), 0 where nothing was drawn.
        coverage: (H, W) float32 share of the pixel's samples drawn (1 or 0 without supersampling).
        supersample: samples per pixel and axis the frame was drawn with.
    """

    rgb: np.ndarray
    alpha: np.ndarray
    level: int
    resolution: int
    spacing: float
    facets: int
    ms: float
    lod: mg.Lod | None = field(default=None, repr=False)
    cpu_ms: float = 0.0
    depth: np.ndarray | None = field(default=None, repr=False)
    coverage: np.ndarray | None = field(default=None, repr=False)
    supersample: int = 1


class MicrofacetRenderer:
    """Owns the GPU buffers and programs of the microfacet renderer for one model.

    Args:
        ctx: a moderngl context (render.gl.create_context()).
        levels: the pyramid levels (volume.model.SdfLevel, coarse -> fine).
        rgb, depth, cameras: the RGBz images (volume.model.RgbzImages fields).
        bounds: (2, 3) object box (near/far planes, LOD centre).
        mode: "instanced" or "geometry".
        rule: per-fragment fallback rule, "vote" or "any" (microfacet_geometry.shade_fragments).
        n_fallback: fallback candidates tried after the blend cameras (default N_FALLBACK).
        refine: parallax-correction steps of passing colours (default DEPTH_REFINE; 0 = the
            paper's colour at the slice point; microfacet_geometry.refine_colours).
    """

    def __init__(self, ctx, levels, rgb, depth, cameras, bounds, mode: str = "instanced", rule: str = "vote",
                 n_fallback: int | None = None, refine: int | None = None):
        if mode not in MODES:
            raise ValueError(f"unknown microfacet mode {mode!r}; use one of {MODES}")
        self.ctx = ctx
        self.mode = mode
        self.levels = tuple(levels)
        self.surfaces = covering_surfaces(self.levels)
        self.cameras = tuple(cameras)
        self.bounds = np.asarray(bounds, dtype=np.float64)
        self.voxel_sizes = [lv.voxel_size for lv in self.levels]
        self.counts = [len(x) for x in self.surfaces]
        if len(self.cameras) == 0:
            raise ValueError("microfacet renderer: the model has no input camera")
        if refine is not None and not 0 <= int(refine) <= MAX_REFINE:
            raise ValueError(f"refine must be 0..{MAX_REFINE} steps, got {refine}")
        d = shader_defines(rule, n_fallback, refine)
        self.refine = mg.DEPTH_REFINE if refine is None else int(refine)
        self.n_fallback = mg.N_FALLBACK if n_fallback is None else int(n_fallback)
        self.rule = rule
        # Per level, the voxel centres in 6 orders (front to back along +-x, +-y, +-z): the
        # frame uses the one closest to its view direction, so that llvmpipe's early depth
        # test rejects more fragments before shading (measured ~20-25 % per frame vs back to front).
        self.voxel_bufs = []
        self.orders = []
        for lv, surf in zip(self.levels, self.surfaces):
            cen = lv.origin + (surf.astype(np.float64) + 0.5) * lv.voxel_size
            bufs, ords = [], []
            for axis in range(6):
                direction = np.zeros(3)
                direction[axis // 2] = 1.0 if axis % 2 == 0 else -1.0
                o = np.argsort(cen @ direction, kind="stable") if len(cen) else np.zeros(0, np.int64)
                c = np.zeros((max(len(cen), 1), 4), np.float32)
                c[: len(cen), :3] = cen[o]
                bufs.append(ctx.buffer(c.tobytes()))
                ords.append(o)
            self.voxel_bufs.append(bufs)
            self.orders.append(ords)
        self._last_order = None
        self.cam_buf = ctx.buffer(camera_block(self.cameras))
        texels = rgbz_array(rgb, depth)
        n, H, W = texels.shape[:3]
        self.tex_size = (W, H)
        self.tex = ctx.texture_array((W, H, n), 4, texels.astype(RGBZ_DTYPE).tobytes(), dtype="f2")
        self.tex.filter = (ctx.NEAREST, ctx.NEAREST)
        self.tex.repeat_x = self.tex.repeat_y = False
        self.max_records = max(max(self.counts), 1) * mg.MAX_SLICES
        self.slice_buf = ctx.buffer(reserve=self.max_records * SLICE_BYTES)
        self.indirect = ctx.buffer(reserve=16)
        self.select = ctx.compute_shader(_src("microfacet_select.glsl", d))
        self.draw_prog = program(ctx, "microfacet_vert.glsl", "microfacet_frag.glsl", defines=d)
        self.fill_prog = program(ctx, "microfacet_vert.glsl", "microfacet_quad_frag.glsl", defines=d)
        self.geom_prog = program(ctx, "microfacet_points_vert.glsl", "microfacet_frag.glsl",
                                 geometry="microfacet_geom.glsl", defines=d)
        self.vao_inst = ctx.vertex_array(self.draw_prog, [])
        self.vao_fill = ctx.vertex_array(self.fill_prog, [])
        self.vao_geom = ctx.vertex_array(self.geom_prog, [])
        self.query = ctx.query(primitives=True)
        self._fbo = None
        self._fbo_size = None
        self._ss = None

    def level_centers(self, level: int) -> np.ndarray:
        """(N, 3) world centres of the voxels drawn on ``level`` (see covering_surfaces)."""
        lv = self.levels[level]
        return lv.origin + (self.surfaces[level].astype(np.float64) + 0.5) * lv.voxel_size

    @classmethod
    def from_model(cls, ctx, model, mode: str = "instanced", rule: str = "vote",
                   n_fallback: int | None = None, refine: int | None = None) -> "MicrofacetRenderer":
        """Renderer for a volume.model.Model."""
        return cls(ctx, model.pyramid.levels, model.rgbz.rgb, model.rgbz.depth, model.rgbz.cameras,
                   model.bounds, mode, rule, n_fallback, refine)

    def release(self) -> None:
        for o in [*(b for bufs in self.voxel_bufs for b in bufs), self.cam_buf, self.tex, self.slice_buf, self.indirect, self.select,
                  self.draw_prog, self.fill_prog, self.geom_prog, self.vao_inst, self.vao_fill, self.vao_geom]:
            o.release()
        if self._fbo is not None:
            for o in self._fbo:
                o.release()
        if self._ss is not None:
            self._ss.release()

    # ------------------------------------------------------------------ frame
    def _target(self, W: int, H: int):
        if self._fbo_size != (W, H):
            if self._fbo is not None:
                for o in self._fbo:
                    o.release()
            col = self.ctx.renderbuffer((W, H), 4, dtype="f4")
            dep = self.ctx.depth_renderbuffer((W, H))
            self._fbo = (self.ctx.framebuffer([col], dep), col, dep)
            self._fbo_size = (W, H)
        return self._fbo[0]

    def choose_lod(self, eye: Camera, tolerance_px: float) -> mg.Lod:
        """Level and spacing for this eye (Eq. 10-11, microfacet_geometry.choose_lod)."""
        center = self.bounds.mean(axis=0)
        return mg.choose_lod(eye, center, self.cameras, self.voxel_sizes, self.counts, tolerance_px)

    def _uniforms(self, prog, eye: Camera, level: int, spacing: float, near: float, view_proj: np.ndarray):
        right, up = mg.eye_axes(eye)
        w = self.voxel_sizes[level]
        vals = {"n_cams": len(self.cameras), "eye_pos": tuple(eye.center), "eye_right": tuple(right),
                "eye_up": tuple(up), "spacing": spacing, "voxel_size": w, "near_plane": near}
        for k, v in vals.items():
            if k in prog:
                prog[k].value = v
        if "view_proj" in prog:
            prog["view_proj"].write(_mat(view_proj))
        if "rgbz" in prog:
            prog["rgbz"].value = 0
        if "tex_size" in prog:
            prog["tex_size"].value = self.tex_size

    def render(self, eye: Camera, tolerance_px: float = mg.DEFAULT_TOLERANCE_PX, level: int | None = None,
               spacing: float | None = None, fill_only: bool = False, read: bool = True,
               supersample: int = 1) -> Frame:
        """Render one frame from ``eye``.

        Args:
            eye: the viewing camera (its size is the image size).
            tolerance_px: E in pixels for the automatic level/spacing (Eq. 10-11).
            level: force this pyramid level index (spacing then from Eq. 10 on it).
            spacing: force the slice spacing l (m).
            fill_only: draw the same squares untextured (the bare fill-cost reference;
                instanced mode only).
            read: read the image back (False for timing only).
            supersample: samples per pixel and axis (render.antialias): the frame is drawn at
                that multiple of the eye's size (E stays in output pixels) and box-resolved on
                the GPU; rgb is then the mean over the samples (over black) and ``coverage``
                the drawn share.
        """
        ctx = self.ctx
        lod = self.choose_lod(eye, tolerance_px)
        lev = lod.level if level is None else int(level)
        w = self.voxel_sizes[lev]
        if spacing is None:
            spacing = lod.spacing if level is None else max(mg.eq10_spacing(lod.e_world, lod.phi, w), mg.min_spacing(w))
        spacing = max(float(spacing), mg.min_spacing(w))
        near, far = mg.near_far(eye, self.bounds)
        f = check_factor(supersample)
        draw_eye = eye if f == 1 else eye.scaled(f)
        view_proj = draw_eye.gl_projection(near, far) @ draw_eye.gl_view()
        W, H = eye.width, eye.height
        if f == 1:
            fbo = self._target(W, H)
        else:
            if self._ss is None:
                self._ss = Supersampler(ctx)
            fbo = self._ss.target(W, H, f)
        fbo.use()
        ctx.viewport = (0, 0, W * f, H * f)
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        ctx.enable_only(ctx.DEPTH_TEST)
        ctx.depth_func = "<"
        n_vox = self.counts[lev]
        facets = 0
        ctx.finish()
        t0 = time.perf_counter()
        c0 = time.process_time()
        if n_vox > 0:
            self.cam_buf.bind_to_storage_buffer(0)
            axis = view_axis(eye)
            self.voxel_bufs[lev][axis].bind_to_storage_buffer(1)
            self._last_order = self.orders[lev][axis]
            self.tex.use(0)
            if self.mode == "instanced" or fill_only:
                self.indirect.write(np.array([4, 0, 0, 0], np.uint32).tobytes())
                self.slice_buf.bind_to_storage_buffer(2)
                self.indirect.bind_to_storage_buffer(3)
                self._uniforms(self.select, eye, lev, spacing, near, view_proj)
                self.select["n_voxels"].value = n_vox
                self.select["max_records"].value = self.max_records
                self.select.run(group_x=(n_vox + LOCAL_SIZE - 1) // LOCAL_SIZE)
                ctx.memory_barrier()
                prog, vao = (self.fill_prog, self.vao_fill) if fill_only else (self.draw_prog, self.vao_inst)
                self._uniforms(prog, eye, lev, spacing, near, view_proj)
                vao.render_indirect(self.indirect, mode=ctx.TRIANGLE_STRIP, count=1)
                ctx.finish()
                facets = int(np.frombuffer(self.indirect.read(), np.uint32)[1])
            else:
                self._uniforms(self.geom_prog, eye, lev, spacing, near, view_proj)
                with self.query:
                    self.vao_geom.render(mode=ctx.POINTS, vertices=n_vox)
                ctx.finish()
                facets = int(self.query.primitives) // 2  # two triangles per square
        if f > 1:
            self._ss.resolve()
            ctx.finish()
        ms = (time.perf_counter() - t0) * 1e3
        cpu_ms = (time.process_time() - c0) * 1e3
        rgb = np.zeros((H, W, 3), np.float32)
        alpha = np.zeros((H, W), bool)
        depth = coverage = None
        if read:
            if f == 1:
                raw = np.frombuffer(fbo.read(components=4, dtype="f4"), np.float32).reshape(H, W, 4)
                d01 = np.frombuffer(fbo.read(components=1, attachment=-1, dtype="f4"), np.float32).reshape(H, W)
            else:
                raw, d01 = self._ss.read()
            rgb, coverage, alpha = split_rgba(gl_rows_to_image(raw), f)
            depth = gl_ndc_depth_to_z(gl_rows_to_image(d01), near, far).astype(np.float32)
            depth[~alpha] = 0.0
        return Frame(rgb, alpha, lev if n_vox > 0 else -1, self.levels[lev].resolution, float(spacing), facets,
                     ms, lod, cpu_ms, depth, coverage, f)

    def read_slices(self, count: int) -> dict:
        """The slice records of the last instanced frame (for tests): centres, s, weights,
        candidates, voxel index, slice number."""
        raw = np.frombuffer(self.slice_buf.read(size=count * SLICE_BYTES), np.float32).reshape(count, 16)
        ints = raw.view(np.int32)
        return {"center": raw[:, 0:3].astype(np.float64), "s": raw[:, 3].astype(np.float64),
                "weights": raw[:, 4:7].astype(np.float64), "cand": np.concatenate([ints[:, 8:12], ints[:, 12:14]], 1),
                "voxel": self._last_order[ints[:, 14]], "n": ints[:, 15].copy()}


def covering_surfaces(levels) -> list[np.ndarray]:
    """Surface voxel indices drawn per level: the level's own surface voxels plus the ancestors
    of the finest level's surface voxels (COARSE_COVERS_FINE).

    A fused pyramid's coarse levels can lose thin parts (plant tips, needles) that its finest
    level keeps; the slices are carved by Eq. 2 anyway, so a coarse voxel that contains finer
    surface must be drawn.  With an exact distance field the union adds nothing (a parent of a
    surface voxel is a surface voxel when |d| <= half the diagonal)."""
    out = [np.asarray(lv.surface, np.int64) for lv in levels]
    if not COARSE_COVERS_FINE or not levels:
        return [o.astype(np.int32) for o in out]
    fine = levels[-1]
    for i, lv in enumerate(levels[:-1]):
        ratio = fine.resolution // lv.resolution
        if ratio < 1 or fine.resolution % lv.resolution or len(fine.surface) == 0:
            continue
        anc = np.asarray(fine.surface, np.int64) // ratio
        out[i] = np.unique(np.concatenate([out[i], anc]), axis=0) if len(out[i]) else np.unique(anc, axis=0)
    return [o.astype(np.int32) for o in out]


def view_axis(eye: Camera) -> int:
    """Index (2 * axis + (0 if +, 1 if -)) of the world axis direction closest to the eye's
    viewing direction: sorting voxels by their coordinate along it is front to back."""
    f = eye.forward
    a = int(np.argmax(np.abs(f)))
    return 2 * a + (0 if f[a] >= 0 else 1)


def _src(name: str, defines: dict) -> str:
    from render.gl import load_shader

    return load_shader(name, defines)

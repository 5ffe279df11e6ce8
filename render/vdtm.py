"""Fixed-mesh baselines: view-dependent texture mapping (VDTM) and a per-vertex colour floor.

The VDTM renderer draws the model's extracted mesh and textures every fragment from the input
RGBz images with the *same* camera selection and unstructured-lumigraph weights as the
microfacet renderer (``microfacet_common.glsl``), so the two differ only in geometry (the
paper's "conventional method", METHODS §1.8 Fig. 11).  A camera textures a fragment when it
sees it: |d - D| < ``vis_tol`` (default: the finest voxel size).  Fragments no candidate sees
keep the mesh's vertex colour (black when the model has none).

The floor is the plain mesh with per-vertex colour, drawn with ``render.raster.MeshRasterizer``.
:func:`vdtm_reference` is the numpy twin of the fragment shader.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from capture.camera import Camera, gl_rows_to_image
from render import microfacet_geometry as mg
from render.antialias import Supersampler, check_factor, split_rgba
from render.gl import program
from render.microfacet import camera_block, rgbz_array, shader_defines

#: Visibility tolerance of a camera for a mesh fragment, in finest-level voxel sizes.
VIS_TOL_VOXELS = 1.0


@dataclass
class MeshFrame:
    """One baseline frame: linear rgb (H, W, 3), alpha (H, W) bool, ms (draw, synchronised), facets
    (triangles), cpu_ms (process CPU time of the draw, llvmpipe threads included), coverage (H, W)
    share of drawn samples (supersampled frames; render.antialias)."""

    rgb: np.ndarray
    alpha: np.ndarray
    ms: float
    facets: int
    cpu_ms: float = 0.0
    coverage: np.ndarray | None = None


def _mat(m) -> bytes:
    return np.asarray(m, np.float32).T.tobytes()


class VdtmRenderer:
    """Owns the GL objects of the VDTM baseline for one model.

    Args:
        ctx: moderngl context.
        vertices, faces, colors: the mesh ((V,3) float32 m, (F,3) int32, (V,3) linear or None).
        rgb, depth, cameras: RGBz images of the input cameras.
        bounds: (2, 3) object box (near/far).
        vis_tol: visibility tolerance |d - D| in metres.
    """

    def __init__(self, ctx, vertices, faces, colors, rgb, depth, cameras, bounds, vis_tol: float):
        self.ctx = ctx
        self.cameras = tuple(cameras)
        self.bounds = np.asarray(bounds, np.float64)
        self.vis_tol = float(vis_tol)
        self.vis_depth = np.asarray(depth, np.float32)  # (N, H, W) z-depth the visibility test uses
        v = np.asarray(vertices, np.float32)
        col = np.zeros_like(v) if colors is None else np.asarray(colors, np.float32)
        self.n_faces = int(len(faces))
        self.vbo = ctx.buffer(np.concatenate([v, col], 1).astype(np.float32).tobytes())
        self.ibo = ctx.buffer(np.asarray(faces, np.int32).tobytes())
        self.prog = program(ctx, "vdtm_vert.glsl", "vdtm_frag.glsl", defines=shader_defines())
        self.vao = ctx.vertex_array(self.prog, [(self.vbo, "3f 3f", "in_pos", "in_color")], index_buffer=self.ibo,
                                    index_element_size=4)
        self.cam_buf = ctx.buffer(camera_block(self.cameras))
        texels = rgbz_array(rgb, depth)
        n, H, W = texels.shape[:3]
        self.tex_size = (W, H)
        self.tex = ctx.texture_array((W, H, n), 4, texels.tobytes(), dtype="f4")
        self.tex.filter = (ctx.NEAREST, ctx.NEAREST)
        self._fbo = None
        self._size = None
        self._ss = None

    @classmethod
    def from_model(cls, ctx, model) -> "VdtmRenderer":
        """Baseline from a Model.  Visibility is tested against the mesh's own depth in every
        camera (a fixed-mesh VDTM knows only its mesh): the model's RGBz depth keeps every
        measured sample for the microfacets (volume.rgbz), fur fringe included, which would
        reject mesh texels the baseline has always used (measured: -0.2 to -0.3 dB)."""
        from volume.rgbz import raycast_depth

        w = model.pyramid.levels[-1].voxel_size
        depth = raycast_depth(model.mesh_vertices, model.mesh_faces, model.rgbz.cameras)
        return cls(ctx, model.mesh_vertices, model.mesh_faces, model.mesh_colors, model.rgbz.rgb, depth,
                   model.rgbz.cameras, model.bounds, VIS_TOL_VOXELS * w)

    def release(self) -> None:
        for o in (self.vbo, self.ibo, self.prog, self.vao, self.cam_buf, self.tex):
            o.release()
        if self._fbo is not None:
            for o in self._fbo:
                o.release()
        if self._ss is not None:
            self._ss.release()

    def render(self, eye: Camera, read: bool = True, supersample: int = 1) -> MeshFrame:
        """Render one frame; ``supersample`` samples per pixel and axis as MicrofacetRenderer.render."""
        ctx = self.ctx
        W, H = eye.width, eye.height
        f = check_factor(supersample)
        if f > 1:
            if self._ss is None:
                self._ss = Supersampler(ctx)
            fbo = self._ss.target(W, H, f)
        elif self._size != (W, H):
            if self._fbo is not None:
                for o in self._fbo:
                    o.release()
            c = ctx.renderbuffer((W, H), 4, dtype="f4")
            d = ctx.depth_renderbuffer((W, H))
            self._fbo = (ctx.framebuffer([c], d), c, d)
            self._size = (W, H)
        if f == 1:
            fbo = self._fbo[0]
        fbo.use()
        ctx.viewport = (0, 0, W * f, H * f)
        draw_eye = eye if f == 1 else eye.scaled(f)
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        ctx.enable_only(ctx.DEPTH_TEST)
        near, far = mg.near_far(eye, self.bounds)
        p = self.prog
        right, up = mg.eye_axes(eye)
        p["view_proj"].write(_mat(draw_eye.gl_projection(near, far) @ draw_eye.gl_view()))
        for k, val in {"n_cams": len(self.cameras), "eye_pos": tuple(eye.center), "vis_tol": self.vis_tol}.items():
            if k in p:
                p[k].value = val
        if "rgbz" in p:
            p["rgbz"].value = 0
        if "tex_size" in p:
            p["tex_size"].value = self.tex_size
        self.cam_buf.bind_to_storage_buffer(0)
        self.tex.use(0)
        ctx.finish()
        t0 = time.perf_counter()
        c0 = time.process_time()
        if self.n_faces:
            self.vao.render(ctx.TRIANGLES)
        if f > 1:
            self._ss.resolve()
        ctx.finish()
        ms = (time.perf_counter() - t0) * 1e3
        cpu_ms = (time.process_time() - c0) * 1e3
        rgb = np.zeros((H, W, 3), np.float32)
        alpha = np.zeros((H, W), bool)
        coverage = None
        if read:
            raw = np.frombuffer(fbo.read(components=4, dtype="f4"), np.float32) if f == 1 else self._ss.read()[0]
            rgb, coverage, alpha = split_rgba(gl_rows_to_image(raw.reshape(H, W, 4)), f)
        return MeshFrame(rgb, alpha, ms, self.n_faces, cpu_ms, coverage)


def vdtm_reference(eye: Camera, depth: np.ndarray, vertex_colour: np.ndarray, cameras, rgb: np.ndarray,
                   rgbz_depth: np.ndarray, vis_tol: float) -> np.ndarray:
    """Numpy twin of vdtm_frag.glsl for the pixels where ``depth`` (H, W, z-depth of the mesh
    in ``eye``, e.g. from render.raster.rasterize_reference) is > 0; ``vertex_colour`` (H, W, 3)
    is the interpolated vertex colour there.  Returns (H, W, 3) linear colour."""
    mask = depth > 0
    pts = eye.unproject(eye.pixel_grid()[mask], depth[mask])
    idx, w = mg.select_cameras(pts, 0.0, eye.center, cameras)
    N = len(pts)
    vis = np.zeros((N, mg.K_CAND), bool)
    cols = np.zeros((N, mg.K_CAND, 3))
    for k in range(mg.K_CAND):
        for c in np.unique(idx[:, k][idx[:, k] >= 0]):
            m = idx[:, k] == c
            col, d, D, inside = mg.sample_rgbz(cameras[c], rgb[c], rgbz_depth[c], pts[m])
            vis[m, k] = inside & (d > 0) & (np.abs(d - D) < vis_tol)
            cols[m, k] = col
    wb = w * vis[:, : mg.K_BLEND]
    wsum = wb.sum(1)
    blend = (wb[:, :, None] * cols[:, : mg.K_BLEND]).sum(1) / np.where(wsum > 0, wsum, 1)[:, None]
    first = np.argmax(vis, axis=1)
    fcol = cols[np.arange(N), first]
    out = np.where((wsum > mg.WEIGHT_EPS)[:, None], blend, np.where(vis.any(1)[:, None], fcol, vertex_colour[mask]))
    img = np.zeros(depth.shape + (3,))
    img[mask] = out
    return img


def render_vertex_colour(ctx, model, eye: Camera, supersample: int = 1) -> MeshFrame:
    """The floor: the mesh with its per-vertex colour (black when the model has none)."""
    from render.raster import MeshRasterizer, RasterMesh

    cols = model.mesh_colors if model.mesh_colors is not None else np.zeros_like(model.mesh_vertices)
    with MeshRasterizer(ctx, supersample=check_factor(supersample)) as r:
        r.set_mesh(RasterMesh(model.mesh_vertices, model.mesh_faces, cols))
        t0 = time.perf_counter()
        c0 = time.process_time()
        res = r.render(eye)
        ms = (time.perf_counter() - t0) * 1e3
        cpu_ms = (time.process_time() - c0) * 1e3
    return MeshFrame(res.color, res.alpha > 0, ms, int(len(model.mesh_faces)), cpu_ms, res.alpha)

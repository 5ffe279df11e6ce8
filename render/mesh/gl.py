"""Fixed-mesh baselines: view-dependent texture mapping (VDTM) and a per-vertex colour floor.

The VDTM renderer draws the model's extracted mesh and textures every fragment from the input
RGBz images with the *same* camera selection and unstructured-lumigraph weights as the
microfacet renderer (``microfacet_common.glsl``), so the two differ only in geometry (the
paper's "conventional method", docs/methods.md §1.8 Fig. 11).  A camera textures a fragment when it
sees it: |d - D| < ``vis_tol`` (default: the finest voxel size).  Fragments no candidate sees
keep the mesh's vertex colour (black when the model has none).

The floor (:class:`MeshColourRenderer`) is the plain mesh with per-vertex colour, drawn with
``render.mesh.raster.gl.MeshRasterizer``.
:func:`render.mesh.reference.vdtm_reference` is the numpy twin of the fragment shader.
"""

from __future__ import annotations

import numpy as np

from capture.camera import Camera
from render.frame import Frame, FrameStats
from render.gl import program
from render.methods import Renderer, RenderOptions
from render.microfacet.gl import camera_block, shader_defines
from render.microfacet.rgbz_textures import layer_textures
from render.owner import FrameTimer, mat4_bytes, near_far

#: Visibility tolerance of a camera for a mesh fragment, in finest-level voxel sizes.
VIS_TOL_VOXELS = 1.0


class VdtmRenderer(Renderer):
    """Owns the GL objects of the VDTM baseline for one model.

    Args:
        ctx: moderngl context.
        vertices, faces, colors: the mesh ((V,3) float32 m, (F,3) int32, (V,3) linear or None).
        rgbz: RGBz images of the input cameras (volume.model.RgbzImages, with its matte when it has
            one: then the blend carries premultiplied colour + alpha, render.microfacet.rgbz_textures,
            and the frame its alpha), uploaded view by view (rgbz_textures.layer_textures).
        depth: (N, H, W) z-depth (metres) the visibility test uses in place of the RGBz depth.
        bounds: (2, 3) object box (near/far).
        vis_tol: visibility tolerance |d - D| in metres.
        options: default per-frame options (this method reads ``supersample``).
    """

    name = "mesh-vdtm"

    def __init__(self, ctx, vertices, faces, colors, rgbz, depth, bounds, vis_tol: float,
                 options: RenderOptions | None = None):
        super().__init__(ctx, options)
        self.cameras = tuple(rgbz.cameras)
        self.bounds = np.asarray(bounds, np.float64)
        self.vis_tol = float(vis_tol)
        self.vis_depth = np.asarray(depth, np.float32)  # (N, H, W) z-depth the visibility test uses
        v = np.asarray(vertices, np.float32)
        col = np.zeros_like(v) if colors is None else np.asarray(colors, np.float32)
        self.n_faces = int(len(faces))
        self.vbo = self.own(ctx.buffer(np.concatenate([v, col], 1).astype(np.float32).tobytes()))
        self.ibo = self.own(ctx.buffer(np.asarray(faces, np.int32).tobytes()))
        self.prog = self.own(program(ctx, "vdtm_vert.glsl", "vdtm_frag.glsl",
                                     defines=shader_defines(has_alpha=rgbz.has_alpha)))
        self.vao = self.own(ctx.vertex_array(self.prog, [(self.vbo, "3f 3f", "in_pos", "in_color")],
                                             index_buffer=self.ibo, index_element_size=4))
        self.cam_buf = self.own(ctx.buffer(camera_block(self.cameras)))
        self.tex_size = rgbz.size
        tex, matte = layer_textures(ctx, rgbz, depth=self.vis_depth, dtype="f4")
        self.tex, self.matte = self.own(tex), None if matte is None else self.own(matte)

    @classmethod
    def from_model(cls, ctx, model, options: RenderOptions | None = None) -> VdtmRenderer:
        """Baseline from a Model.  Visibility is tested against the mesh's own depth in every
        camera (a fixed-mesh VDTM knows only its mesh): the model's RGBz depth keeps every
        measured sample for the microfacets (volume.rgbz), fur fringe included, which would
        reject mesh texels the baseline has always used (measured: -0.2 to -0.3 dB)."""
        from capture.raycast import raycast_depth

        w = model.pyramid.levels[-1].voxel_size
        depth = raycast_depth(model.mesh_vertices, model.mesh_faces, model.rgbz.cameras)
        return cls(ctx, model.mesh_vertices, model.mesh_faces, model.mesh_colors, model.rgbz, depth,
                   model.bounds, VIS_TOL_VOXELS * w, options)

    def _render(self, eye: Camera, options: RenderOptions, read: bool) -> Frame:
        """One frame (Renderer.render) with ``options.supersample`` samples per pixel and axis."""
        f = options.supersample
        self.begin_frame(eye.width, eye.height, f)
        draw_eye = eye if f == 1 else eye.scaled(f)
        near, far = near_far(eye, self.bounds)
        p = self.prog
        p["view_proj"].write(mat4_bytes(draw_eye.gl_projection(near, far) @ draw_eye.gl_view()))
        for k, val in {"n_cams": len(self.cameras), "eye_pos": tuple(eye.center), "vis_tol": self.vis_tol}.items():
            if k in p:
                p[k].value = val
        if "rgbz" in p:
            p["rgbz"].value = 0
        if self.matte is not None:
            p["matte"].value = 3
            self.matte.use(3)
        if "tex_size" in p:
            p["tex_size"].value = self.tex_size
        self.cam_buf.bind_to_storage_buffer(0)
        self.tex.use(0)
        with FrameTimer(self.ctx) as t:
            if self.n_faces:
                self.vao.render(self.ctx.TRIANGLES)
            self.resolve_frame()
        stats = FrameStats(t.ms, t.cpu_ms, supersample=f, facets=self.n_faces)
        if not read:
            return Frame.empty(eye.width, eye.height, stats)
        return Frame.from_gl(*self.read_frame(), near, far, stats)


class MeshColourRenderer(Renderer):
    """The floor: the model's mesh with its per-vertex colour (black when the model has none),
    drawn by the mesh rasteriser (render.mesh.raster.gl.MeshRasterizer); reads ``supersample``."""

    name = "mesh-colour"

    def __init__(self, ctx, vertices, faces, colors, options: RenderOptions | None = None):
        from render.mesh.raster.gl import MeshRasterizer, RasterMesh

        super().__init__(ctx, options)
        cols = colors if colors is not None else np.zeros_like(vertices)
        self.rasterizer = self.own(MeshRasterizer(ctx))
        self.rasterizer.set_mesh(RasterMesh(vertices, faces, cols))

    @classmethod
    def from_model(cls, ctx, model, options: RenderOptions | None = None) -> MeshColourRenderer:
        return cls(ctx, model.mesh_vertices, model.mesh_faces, model.mesh_colors, options)

    def _render(self, eye: Camera, options: RenderOptions, read: bool) -> Frame:
        r = self.rasterizer
        f = options.supersample
        near, far = r.planes(eye)
        with FrameTimer(self.ctx) as t:
            r.draw(eye, f, near, far)
            r.resolve_frame()
        stats = FrameStats(t.ms, t.cpu_ms, supersample=f, facets=len(r.mesh.faces))
        if not read:
            return Frame.empty(eye.width, eye.height, stats)
        return Frame.from_gl(*r.read_frame(), near, far, stats)

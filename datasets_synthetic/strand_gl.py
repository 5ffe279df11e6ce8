"""The GL synthetic renderer: strands as camera-facing ribbons shaded on the GPU.

Same images as the numpy renderer (``--synth-renderer numpy``: ``render.mesh.raster.gl.MeshRasterizer``
drawing every strand as its tube of triangles, the hair lobes of ``datasets_synthetic.hair_shading``
evaluated in numpy per strand point and view) to within the tolerances of
tests/datasets_synthetic/test_strand_gl.py, many times faster on llvmpipe:

* **Strands** (``datasets_synthetic.strands``): per segment between two tube rings, the strip of
  the tube's facets that face the viewer, made in a geometry shader from the rings (centre, radius,
  frame; ``strand_ribbon.glsl``): the tube's own vertices, triangulation, depth and interpolated
  normals, its silhouette, and 2 or 4 triangles where the tube has 6 (3 sides), no back faces.
  Coverage comes from the rasteriser's supersamples, as the tube's does.  A strip wholly behind
  the surfaces already drawn is not emitted (the farthest surface depth per 16 x 16 tile,
  ``strand_hiz_comp.glsl``): the depth test would have rejected all of it.
* **Surfaces** (skin, pot, stems, leaves) are drawn by the mesh rasteriser itself (this class is
  one), shaded as before, with the dominant lights' visibility from shadow maps that hold the
  strands too.  (This overrides ``MeshRasterizer._build_shadows``, which would make the maps of the
  surfaces alone.)
* **Shadow maps**: for every hair light (the map's dominant lights at SHADOW_MAP_SIZE, the
  median-cut lights at ENV_SHADOW_MAP_SIZE, as today) the surfaces and the strands' facets facing
  the light; the visibility of every strand point (the dominant lights at the ring's first vertex,
  the cut lights at its centre, as ``hair_shading.prepare_hair`` looks them up) and of every
  surface vertex by ``strand_visibility_comp.glsl``, the twin of
  ``render.mesh.raster.shadow_maps.shadow_map_visibility``.
* **Lobes** (chiang), deferred: the strand pass writes each covered sample's segment and its
  position along it; the points of the segments left on the frame are listed
  (``strand_deferred_comp.glsl``), ``strand_lobes_comp.glsl`` (the twin of
  ``hair_shading.strand_radiance``) shades those only (a fifth of the fur ball's points in a view),
  and every strand sample gets its two points' radiance mixed at its position (what the
  rasteriser does with per-vertex emission).  Kajiya-Kay: the rasteriser's strand shading per
  fragment, in ``strand_ribbon_frag.glsl``, with the dominant lights' visibility at every ring
  vertex.

The GL context is passed in; every GL object is owned here and released by :meth:`release`
(``render.owner.GLOwner``).
"""

from __future__ import annotations

import numpy as np

from datasets_synthetic.hair_shading import (
    ENV_SHADOW_MAP_SIZE,
    HAIR_MODELS,
    WIDTH_NODES_SYNTH,
    hair_info,
    hair_lights,
)
from datasets_synthetic.strand_shaders import (
    DEFERRED_DEFINES,
    HIZ_DEFINES,
    HIZ_TILE,
    LIGHT_FLOATS,
    LOCAL_SIZE,
    MAX_SEGMENTS,
    MAX_SIDES,
    POINT_FLOATS,
    light_records,
    load_synth_shader,
    lobe_defines,
    point_records,
)
from datasets_synthetic.strands import StrandGeometry, split_strands
from render.mesh.raster.gl import (
    MAX_LIGHTS,
    SHADOW_BIAS_TEXELS,
    SHADOW_BOX_MARGIN,
    SHADOW_MAP_SIZE,
    Lighting,
    MeshRasterizer,
    RasterError,
    RasterMesh,
)
from render.mesh.raster.shadow_maps import light_view_projection
from render.owner import mat4_bytes, near_far
from render.shading.envmap import EnvMap
from render.shading.hair import HairParams

#: Texture unit of the shadow map read by the visibility pass and of the Kajiya-Kay irradiance table.
TEXTURE_UNIT = 1
#: Skip the strand strips wholly behind the surfaces (False draws every strip; same images).
HIZ_CULL = True


class StrandRasterizer(MeshRasterizer):
    """The mesh rasteriser with the strands drawn as ribbons and shaded on the GPU (module docstring).

    Usage::

        with StrandRasterizer(ctx, supersample=3) as r:
            hair_info = r.set_scene(mesh, lighting, residual, "chiang", env_lights=32)
            res = r.render(camera)          # render.mesh.raster.gl.RasterResult
    """

    released_error = RasterError

    def __init__(self, ctx, supersample: int = 1) -> None:
        super().__init__(ctx, supersample)
        self._geo: StrandGeometry | None = None
        self._scene_bounds = None
        self._surface_vis = None
        self._buf: dict = {}
        self._progs: dict = {}
        self._strand_vaos: dict = {}
        self._hair_model = "chiang"
        self._n_lights = 0
        #: Strand points the lobe pass shaded in the last view (chiang).
        self.visible_points = 0

    # ------------------------------------------------------------------ programs and buffers
    def _program(self, key: str, build):
        """The program ``key``, made by ``build()`` (a compute shader's source, or the keyword
        arguments of ``ctx.program``) the first time."""
        if key not in self._progs:
            src = build()
            prog = self.ctx.compute_shader(src) if isinstance(src, str) else self.ctx.program(**src)
            self._progs[key] = self.own(prog)
        return self._progs[key]

    def _ribbon_program(self, kind: str):
        """kind: 'camera' (chiang), 'camera_kk' or 'shadow' (depth only)."""
        frag = "raster_shadow_frag.glsl" if kind == "shadow" else "strand_ribbon_frag.glsl"
        d = {"HAIR_KK": int(kind == "camera_kk"), "MAX_LIGHTS": MAX_LIGHTS,
             "MAX_STRIP_VERTICES": 2 * (MAX_SIDES + 1), **DEFERRED_DEFINES, **HIZ_DEFINES}
        return self._program(kind, lambda: {"vertex_shader": load_synth_shader("strand_ribbon_vert.glsl", d),
                                            "geometry_shader": load_synth_shader("strand_ribbon_geom.glsl", d),
                                            "fragment_shader": load_synth_shader(frag, d)})

    def _buffer(self, name: str, data: np.ndarray | None = None, reserve: int = 0):
        self.free(self._buf.pop(name, None))
        b = self.ctx.buffer(np.ascontiguousarray(data).tobytes()) if data is not None else self.ctx.buffer(
            reserve=max(int(reserve), 4))
        self._buf[name] = self.own(b)
        return b

    def _strand_vao(self, kind: str):
        if kind not in self._strand_vaos:
            prog = self._ribbon_program(kind)
            self._strand_vaos[kind] = self.own(self.ctx.vertex_array(prog, [], index_buffer=self._buf["segments"],
                                                                     index_element_size=4))
        return self._strand_vaos[kind]

    # ------------------------------------------------------------------ scene
    def set_scene(self, mesh: RasterMesh, lighting: Lighting, residual: EnvMap | None = None,
                  hair_model: str = "chiang", env_lights: int = 32, shadows: bool = True) -> dict:
        """Split ``mesh`` into strands and surfaces, upload them, build the hair lights (chiang:
        ``lighting``'s dominant lights + ``residual`` cut into ``env_lights``; kajiya-kay: the
        dominant lights) and their shadow-map visibility (all 1 without ``shadows``), and give the
        surfaces to the rasteriser.  Returns the gt/scene.json record of the hair shading."""
        self.check_alive()
        if hair_model not in HAIR_MODELS:
            raise ValueError(f"hair model must be one of {', '.join(HAIR_MODELS)}, got {hair_model!r}")
        if hair_model == "kajiya-kay" and lighting.ambient != "table":
            raise RasterError("the GL strands' Kajiya-Kay shading needs the lighting's irradiance table")
        for v in self._strand_vaos.values():
            self.free(v)
        self._strand_vaos.clear()
        geo = split_strands(mesh)
        if geo.count and (int(geo.sides.max()) > MAX_SIDES or len(geo.segments) > MAX_SEGMENTS):
            raise RasterError(f"the GL renderer draws strands of at most {MAX_SIDES} sides and {MAX_SEGMENTS} "
                              "segments: use --synth-renderer numpy")
        self._geo, self._hair_model, self._scene_bounds = geo, hair_model, mesh.bounds
        self.visible_points = 0
        K = len(lighting.light_dirs)
        if hair_model == "chiang" and geo.count:
            dirs, power, spread = hair_lights(lighting, residual, env_lights)
        else:
            dirs, power, spread = (np.asarray(lighting.light_dirs, np.float64).reshape(-1, 3),
                                   np.asarray(lighting.light_colors, np.float64).reshape(-1, 3), np.zeros(K))
        self._n_lights = len(dirs)
        self._upload(geo, mesh, dirs, power, spread)
        vis = self._visibility(geo, mesh, dirs, K, shadows and lighting.shadows)
        surf = geo.surfaces if geo.surfaces is not None else _dummy_mesh(mesh.bounds)
        self._surface_vis = vis[geo.count:geo.count + len(surf.vertices), :K] if geo.surfaces is not None else None
        super().set_lighting(lighting)
        super().set_mesh(surf)
        self.shadow_info = self._shadow_info(geo, vis, K, lighting, shadows)
        if hair_model == "kajiya-kay" or geo.count == 0:  # (as the numpy renderer records a scene without strands)
            return {"model": "kajiya-kay", "renderer": "gl"}
        info = hair_info(geo.count, dirs, power, vis[:geo.count].mean(0), HairParams(), WIDTH_NODES_SYNTH)
        return {**info, "renderer": "gl"}

    def _upload(self, geo: StrandGeometry, mesh: RasterMesh, dirs, power, spread) -> None:
        P = geo.count
        surf_v = geo.surfaces.vertices if geo.surfaces is not None else np.zeros((0, 3), np.float32)
        first = np.nonzero(np.r_[True, np.diff(geo.points.group) != 0] & (geo.points.group >= 0))[0]
        ring_v = mesh.vertices[geo.points.group >= 0] if self._hair_model == "kajiya-kay" else np.zeros((0, 3))
        lookup = np.concatenate([geo.points.centres, mesh.vertices[first], surf_v, ring_v]).astype(np.float64)
        lookup4 = np.concatenate([lookup, np.ones((len(lookup), 1))], 1).astype(np.float32)
        self._buffer("points", point_records(geo, mesh) if P else np.zeros((1, POINT_FLOATS), np.float32))
        self._buffer("segments", geo.segments.astype(np.uint32) if len(geo.segments) else np.zeros(2, np.uint32))
        self._buffer("lookup", lookup4 if len(lookup4) else np.zeros((1, 4), np.float32))
        rows = P + len(surf_v)
        self._buffer("visibility", np.ones((max(rows, 1), max(len(dirs), 1)), np.float32))
        self._buffer("lights", light_records(dirs, power, spread) if len(dirs) else np.zeros((1, LIGHT_FLOATS),
                                                                                             np.float32))
        # Kajiya-Kay: the dominant lights' visibility at every ring vertex, interpolated as the rasteriser does
        self._buffer("ring_visibility", np.ones((max(len(ring_v), 1), MAX_LIGHTS), np.float32))
        start = np.r_[0, np.cumsum(geo.sides)[:-1]] if P else np.zeros(1)
        self._buffer("ring_start", start.astype(np.uint32))
        self._buffer("radiance", reserve=16 * max(P, 1))
        self._buffer("flags", reserve=4 * max(P, 1))
        self._buffer("list", reserve=4 * max(P, 1))
        self._buffer("count", reserve=4)
        if geo.surfaces is not None:
            self._buffer("surface_pos", geo.surfaces.vertices.astype(np.float32))
            self._buffer("surface_idx", geo.surfaces.faces.astype(np.uint32))

    # ------------------------------------------------------------------ shadows
    def _visibility(self, geo: StrandGeometry, mesh: RasterMesh, dirs, K: int, shadows: bool) -> np.ndarray:
        """(P + Vs, L) float32 visibility: strand points (dominant lights at the ring's first vertex,
        the others at the centre), then the surface vertices (dominant lights)."""
        P = geo.count
        Vs = len(geo.surfaces.vertices) if geo.surfaces is not None else 0
        L = len(dirs)
        if not shadows or L == 0:
            return np.ones((P + Vs, L), np.float32)
        b = mesh.bounds
        centre = 0.5 * (b[0] + b[1])
        radius = 0.5 * float(np.linalg.norm(b[1] - b[0])) * (1 + SHADOW_BOX_MARGIN)
        cs = self._program("visibility", lambda: load_synth_shader("strand_visibility_comp.glsl",
                                                                   {"LOCAL_SIZE": LOCAL_SIZE}))
        self._buf["lookup"].bind_to_storage_buffer(5)
        self._buf["visibility"].bind_to_storage_buffer(2)
        for i, d in enumerate(dirs):
            size = SHADOW_MAP_SIZE if i < K else ENV_SHADOW_MAP_SIZE
            vp = light_view_projection(d, centre, radius)
            tgt = self._shadow_map(vp, d, size)
            tgt.depth.compare_func = ""
            tgt.depth.use(location=TEXTURE_UNIT)
            cs["u_depth"].value = TEXTURE_UNIT
            cs["u_light_vp"].write(mat4_bytes(vp))
            cs["u_dir"].value = tuple(float(x) for x in d)
            cs["u_bias"].value = SHADOW_BIAS_TEXELS * 2 * radius / size
            # dominant: ring first vertices (lookup rows P..2P) then the surface vertices; cut lights: centres
            count, offset = (P + Vs, P) if i < K else (P, 0)
            self._lookup(cs, count, offset, L, i)
            if i < K and self._hair_model == "kajiya-kay":  # every ring vertex, into ring_visibility
                self._buf["ring_visibility"].bind_to_storage_buffer(2)
                self._lookup(cs, int(geo.sides.sum()), 2 * P + Vs, MAX_LIGHTS, i)
                self._buf["visibility"].bind_to_storage_buffer(2)
        return np.frombuffer(self._buf["visibility"].read(), np.float32).reshape(-1, L)[:P + Vs].copy()

    def _lookup(self, cs, count: int, offset: int, stride: int, column: int) -> None:
        """vis[r * stride + column] for r < count from lookup[offset + r] (strand_visibility_comp.glsl)."""
        cs["u_count"].value, cs["u_offset"].value = count, offset
        cs["u_stride"].value, cs["u_column"].value = stride, column
        if count:
            cs.run(group_x=(count + LOCAL_SIZE - 1) // LOCAL_SIZE)
        self.ctx.memory_barrier()

    def _shadow_map(self, vp: np.ndarray, d, size: int):
        """The depth map of the surfaces and the ribbons seen from a directional light."""
        ctx = self.ctx
        tgt = self.target(size, size, colours=())
        tgt.fbo.use()
        tgt.fbo.clear(depth=1.0)
        ctx.enable_only(ctx.DEPTH_TEST)
        ctx.depth_func = "<"
        if self._geo.surfaces is not None:
            sprog, vao = self._surface_shadow()
            sprog["u_mvp"].write(mat4_bytes(vp))
            vao.render()
        if self._geo.count:
            prog = self._ribbon_program("shadow")
            self._hiz(prog, tgt.depth)
            self._bind_strand_buffers()
            prog["u_view"].write(mat4_bytes(np.eye(4)))
            prog["u_proj"].write(mat4_bytes(vp))
            prog["u_ortho"].value = 1
            prog["u_light_dir"].value = tuple(float(x) for x in d)
            self._strand_vao("shadow").render(mode=ctx.LINES)
        return tgt

    def _surface_shadow(self):
        """(program, vertex array) of the surfaces' shadow-map pass (the rasteriser's shadow shaders)."""
        prog = self._program("surface_shadow", lambda: {
            "vertex_shader": load_synth_shader("raster_shadow_vert.glsl"),
            "fragment_shader": load_synth_shader("raster_shadow_frag.glsl")})
        if "surface_shadow" not in self._strand_vaos:
            self._strand_vaos["surface_shadow"] = self.own(self.ctx.vertex_array(
                prog, [(self._buf["surface_pos"], "3f", "in_pos")], index_buffer=self._buf["surface_idx"],
                index_element_size=4))
        return prog, self._strand_vaos["surface_shadow"]

    def _shadow_info(self, geo, vis, K, lighting, shadows) -> dict:
        if not (shadows and lighting.shadows and K):
            return {}
        b = self._scene_bounds
        radius = 0.5 * float(np.linalg.norm(b[1] - b[0])) * (1 + SHADOW_BOX_MARGIN)
        # every ring vertex counted with its ring's first-vertex visibility, as the mean over the mesh's vertices
        w = np.concatenate([geo.sides.astype(np.float64), np.ones(len(vis) - geo.count)])
        mean = (vis[:, :K] * w[:, None]).sum(0) / max(w.sum(), 1.0)
        return {"map_size": SHADOW_MAP_SIZE, "texel_m": 2 * radius / SHADOW_MAP_SIZE, "mean_visibility": mean.tolist()}

    def _build_shadows(self) -> None:
        """The rasteriser's per-vertex light visibility of the surfaces: the one computed by
        set_scene from shadow maps that hold the strands too (not from the surfaces alone)."""
        V = len(self._mesh.vertices)
        vis = np.ones((V, MAX_LIGHTS), np.float32)
        k = len(self._lighting.light_dirs) if self._lighting is not None else 0
        if self._surface_vis is not None and len(self._surface_vis) == V:
            vis[:, :k] = self._surface_vis
        self._vis_vbo.write(vis.tobytes())
        self.vertex_visibility = vis[:, :k].copy()

    # ------------------------------------------------------------------ per view
    def planes(self, camera) -> tuple[float, float]:
        """Near / far planes of the whole scene (strands included)."""
        self._check()
        return near_far(camera, self._scene_bounds)

    def draw(self, camera, factor: int, near: float, far: float):
        """The rasteriser's surfaces, then the strands into the same frame target."""
        tgt = super().draw(camera, factor, near, far)
        if self._geo is not None and self._geo.count:
            self._draw_strands(camera if factor == 1 else camera.scaled(factor), near, far, tgt)
        return tgt

    def _hiz(self, prog, depth) -> None:
        """Give ``prog`` the farthest depth of every tile of ``depth`` (the surfaces drawn so far) so
        that its geometry shader skips the strips behind them (off when there are no surfaces)."""
        if self._geo.surfaces is None or not HIZ_CULL:
            prog["u_hiz"].value = 0
            return
        W, H = depth.size
        tiles = ((W + HIZ_TILE - 1) // HIZ_TILE, (H + HIZ_TILE - 1) // HIZ_TILE)
        if self._buf.get("tiles") is None or self._buf["tiles"].size < 4 * tiles[0] * tiles[1]:
            self._buffer("tiles", reserve=4 * tiles[0] * tiles[1])
        cs = self._program("hiz", lambda: load_synth_shader("strand_hiz_comp.glsl", HIZ_DEFINES))
        depth.compare_func = ""
        depth.use(location=TEXTURE_UNIT)
        self._buf["tiles"].bind_to_storage_buffer(11)
        cs["u_depth"].value = TEXTURE_UNIT
        cs["u_tiles"].value = tiles
        cs.run((tiles[0] + 7) // 8, (tiles[1] + 7) // 8)
        self.ctx.memory_barrier()
        prog["u_hiz"].value = 1
        prog["u_tiles"].value = tiles
        prog["u_viewport"].value = (float(W), float(H))

    def _bind_strand_buffers(self) -> None:
        for name, binding in (("points", 0), ("lights", 1), ("visibility", 2), ("radiance", 3), ("flags", 4),
                              ("list", 6), ("count", 7), ("segments", 8), ("ring_visibility", 9), ("ring_start", 10)):
            self._buf[name].bind_to_storage_buffer(binding)

    def _draw_strands(self, cam, near: float, far: float, tgt) -> None:
        ctx = self.ctx
        kk = self._hair_model == "kajiya-kay"
        kind = "camera_kk" if kk else "camera"
        prog = self._ribbon_program(kind)
        prog["u_view"].write(mat4_bytes(cam.gl_view()))
        prog["u_proj"].write(mat4_bytes(cam.gl_projection(near, far)))
        prog["u_eye"].value = tuple(float(x) for x in cam.center)
        prog["u_ortho"].value = 0
        self._hiz(prog, tgt.depth)
        self._bind_strand_buffers()
        if kk:
            prog["u_exposure"].value = float(self._lighting.exposure)
            self._kk_uniforms(prog)
        self._strand_vao(kind).render(mode=ctx.LINES)
        if not kk:
            ctx.memory_barrier()
            self._deferred(cam.center, tgt.colours[0])

    def _deferred(self, eye, colour) -> None:
        """Flag the points of the segments the strand pass left on the frame's samples, list them,
        shade them (lobe pass) and put their radiance on the samples (strand_deferred_comp.glsl)."""
        ctx = self.ctx
        cs = self._program("deferred", lambda: load_synth_shader("strand_deferred_comp.glsl", DEFERRED_DEFINES))
        self._bind_strand_buffers()
        colour.bind_to_image(0, read=True, write=True)
        W, H = colour.size
        groups = ((W + 7) // 8, (H + 7) // 8)
        P = self._geo.count
        self._buf["flags"].clear()
        self._buf["count"].clear()
        cs["u_points"].value = P
        cs["u_exposure"].value = float(self._lighting.exposure)
        cs["u_stage"].value = 0
        cs.run(*groups)
        ctx.memory_barrier()
        cs["u_stage"].value = 1
        cs.run((P + 63) // 64, 1)
        ctx.memory_barrier()
        n = int(np.frombuffer(self._buf["count"].read(), np.uint32)[0])
        self.visible_points = n
        if n:
            self._lobes(eye, n, use_list=True)
        cs["u_stage"].value = 2
        cs.run(*groups)
        ctx.memory_barrier()

    def _lobes(self, eye, count: int, use_list: bool) -> None:
        n = self._n_lights
        cs = self._program(f"lobes{n}", lambda: load_synth_shader("strand_lobes_comp.glsl", lobe_defines(n)))
        cs["u_eye"].value = tuple(float(x) for x in eye)
        cs["u_count"].value = int(count)
        cs["u_use_list"].value = int(use_list)
        self._bind_strand_buffers()
        cs.run(group_x=(int(count) + LOCAL_SIZE - 1) // LOCAL_SIZE)
        self.ctx.memory_barrier()

    def _kk_uniforms(self, prog) -> None:
        lt = self._lighting
        self._irr_tex.use(location=TEXTURE_UNIT)
        prog["u_irradiance"].value = TEXTURE_UNIT
        k = len(lt.light_dirs)
        dirs = np.zeros((MAX_LIGHTS, 3), np.float32)
        cols = np.zeros((MAX_LIGHTS, 3), np.float32)
        dirs[:k], cols[:k] = lt.light_dirs, lt.light_colors
        prog["u_light_dir_kk"].write(dirs.tobytes())
        prog["u_light_col"].write(cols.tobytes())
        prog["u_nlights"].value = k
        prog["u_hair_shininess"].value = float(lt.hair_shininess)

    def strand_radiance(self, eye) -> np.ndarray:
        """(P, 3) float32 radiance of every strand point towards ``eye`` from the lobe pass (the twin
        of ``hair_shading.strand_radiance``)."""
        self._check()
        self._lobes(eye, self._geo.count, use_list=False)
        return np.frombuffer(self._buf["radiance"].read(), np.float32).reshape(-1, 4)[:self._geo.count, :3].copy()

    def strand_visibility(self) -> np.ndarray:
        """(P, L) float32 visibility of the hair lights at the strand points (set_scene's shadow maps)."""
        self._check()
        L = max(self._n_lights, 1)
        return np.frombuffer(self._buf["visibility"].read(), np.float32).reshape(-1, L)[:self._geo.count].copy()


def _dummy_mesh(bounds: np.ndarray) -> RasterMesh:
    """A single degenerate triangle (draws nothing) for a scene of strands only."""
    c = 0.5 * (np.asarray(bounds[0]) + np.asarray(bounds[1]))
    return RasterMesh(np.tile(c, (3, 1)), np.array([[0, 1, 2]]), np.zeros((3, 3)))

"""Triangle-mesh rasteriser: colour, z-depth (metres), world normals and coverage.

Used by ``datasets_synthetic`` to render exact ground truth and later as the fixed-mesh
baseline renderer (docs/design.md "render/").  The GL path (:class:`MeshRasterizer`) has a slow,
obviously-correct numpy twin (``render.mesh.raster.reference``: per-pixel barycentric
rasterisation and the same shading in numpy through ``render.shading``) and tests comparing them
(tests/render/mesh/raster/test_raster.py).

Conventions: cameras are :class:`capture.camera.Camera` (OpenCV); the GL matrices come from
``camera.gl_view()`` / ``camera.gl_projection()`` and read-back rows are flipped by
``gl_rows_to_image`` only.  Depth is the eye-space z-depth (metres along the optical axis)
written to a float32 target, 0 = background.  Colour is linear float32.  Supersampling:
colour (and the coverage ``alpha``) come from a pass at ``supersample`` x the resolution with
the camera scaled exactly (``Camera.scaled``), averaged over s x s blocks on the GPU (the one
supersampling path: ``render.owner.GLOwner.begin_frame`` / ``resolve_frame``,
``render.antialias``); depth, normals and the mask are single samples at the pixel centres (no
mixed depths at edges): for odd ``s`` the centre sub-sample of each block (exactly the pixel
centre), for even ``s`` a native pass.

Shaded mode (``lighting=``): ambient irradiance of the environment minus its dominant lights x
per-vertex ambient occlusion -- from the exact irradiance table (``render.shading.irradiance``,
``env_irradiance`` of ``render/shaders/shading_envmap.glsl``, within ~1% of the brute-force integral)
or, when the Lighting has only SH9 coefficients, from SH9 (``render/shaders/sh9.glsl``) -- plus K
directional lights with shadow-map visibility baked per vertex, Lambert diffuse and an
energy-preserving Blinn-Phong lobe (``render/shaders/shading_brdf.glsl``, docs/methods.md §4 Eq. 4); strands (vertices
with a tangent) use Kajiya-Kay: the lobe is evaluated on sin(T, H) and diffuse on sin(T, L).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from capture.camera import Camera, gl_rows_to_image
from capture.sampling import points_box
from render.gl import program
from render.mesh.raster.shadow_maps import light_view_projection, shadow_map_visibility
from render.owner import GLOwner, mat4_bytes, near_far, vertex_format
from render.shading.irradiance import irradiance_texture
from render.shading.sh import sh9_glsl_uniform

#: Near plane of the numpy reference rasteriser (metres; render.mesh.raster.reference).
MIN_NEAR = 1e-3
#: Shadow-map resolution (texels per side) and the ortho box margin (fraction of the radius).
SHADOW_MAP_SIZE = 2048
SHADOW_BOX_MARGIN = 0.02
#: Shadow bias along the light direction, in shadow-map texels (thin strands need it small).
SHADOW_BIAS_TEXELS = 3.0
#: Most directional lights the shaded program supports.
MAX_LIGHTS = 4
#: A vertex belongs to a strand (Kajiya-Kay shading) when its tangent's squared length exceeds this.
HAIR_TANGENT_SQ = 0.25
#: Texture unit of the ambient irradiance table in the shaded program.
IRRADIANCE_TEXTURE_UNIT = 0


#: Colour attachments of the rasteriser's target (components): colour + coverage, z-depth, normal.
RASTER_COLOURS = (4, 1, 4)
#: Interleaved vertex layout: (attribute name, float count).
_ATTRIBUTES = (("in_pos", 3), ("in_color", 3), ("in_normal", 3), ("in_tangent", 3), ("in_occl", 1), ("in_spec", 1))


class RasterError(ValueError):
    """Invalid mesh or render request."""


def triangle_arrays(vertices, faces, what: str = "mesh") -> tuple[np.ndarray, np.ndarray]:
    """(V, 3) float32 vertices and (F, 3) int32 faces, validated: at least one of each, finite
    vertices, faces indexing them (RasterError naming ``what`` otherwise)."""
    v = np.ascontiguousarray(vertices, dtype=np.float32)
    f = np.ascontiguousarray(faces, dtype=np.int32)
    if v.ndim != 2 or v.shape[1] != 3 or len(v) == 0:
        raise RasterError(f"{what} vertices must be (V, 3), got {v.shape}")
    if f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
        raise RasterError(f"{what} faces must be (F, 3), got {f.shape}")
    if f.min() < 0 or f.max() >= len(v):
        raise RasterError(f"{what} faces index vertices out of range [0, {len(v)})")
    if not np.all(np.isfinite(v)):
        raise RasterError(f"{what} vertices contain NaN or inf")
    return v, f


@dataclass(frozen=True)
class RasterMesh:
    """A triangle mesh with per-vertex attributes (world metres, linear colour).

    Attributes:
        vertices: (V, 3) float32 world positions in metres.
        faces: (F, 3) int32 vertex indices (winding is irrelevant: no culling).
        colors: (V, 3) float32 linear albedo / colour in [0, 1].
        normals: (V, 3) float32 unit world normals, or None (flat face normals are used).
        tangents: (V, 3) float32 unit strand directions (zero rows = not a strand), or None.
        occlusion: (V,) float32 ambient visibility in [0, 1] (1 = unoccluded), or None (= 1).
        specular: (V,) float32 specular strength in [0, 1], or None (= 0).
    """

    vertices: np.ndarray
    faces: np.ndarray
    colors: np.ndarray
    normals: np.ndarray | None = None
    tangents: np.ndarray | None = None
    occlusion: np.ndarray | None = None
    specular: np.ndarray | None = None

    def __post_init__(self) -> None:
        v, f = triangle_arrays(self.vertices, self.faces)
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "faces", f)
        for name, cols in (("colors", 3), ("normals", 3), ("tangents", 3), ("occlusion", 0), ("specular", 0)):
            a = getattr(self, name)
            if a is None:
                if name == "colors":
                    raise RasterError("mesh colors are required")
                continue
            a = np.ascontiguousarray(a, dtype=np.float32)
            want = (len(v), cols) if cols else (len(v),)
            if a.shape != want:
                raise RasterError(f"mesh {name} must be {want}, got {a.shape}")
            if not np.all(np.isfinite(a)):
                raise RasterError(f"mesh {name} contain NaN or inf")
            object.__setattr__(self, name, a)

    @property
    def bounds(self) -> np.ndarray:
        """(2, 3) float64 axis-aligned [min, max] of the vertices."""
        return points_box(self.vertices)


@dataclass(frozen=True)
class RasterResult:
    """What one render returns (all (H, W[, 3]) float32, image rows top first).

    Attributes:
        color: linear colour (background 0), supersampled box average.
        depth: z-depth in metres along the optical axis, 0 = background (single sample).
        normal: unit world normals facing the camera, 0 on background (single sample).
        mask: bool coverage of the single-sample pass (depth > 0).
        alpha: fraction of supersamples covered (equals ``mask`` when supersample == 1).
    """

    color: np.ndarray
    depth: np.ndarray
    normal: np.ndarray
    mask: np.ndarray
    alpha: np.ndarray


@dataclass(frozen=True)
class Lighting:
    """Environment lighting for the shaded mode (world frame).

    The ambient part (usually the environment minus the directional lights) is given either as an
    exact irradiance table (``irradiance``, preferred) or as SH9 coefficients (``sh9``); when both
    are given the table is used.

    Attributes:
        sh9: (9, 3) radiance SH coefficients (``render.shading.sh.sh9_project``) of the ambient
            part, or None; irradiance from them is ``sh9_irradiance`` (numpy) / sh9.glsl (GLSL,
            via ``sh9_glsl_uniform``).  Up to ~44% off on real HDR maps: prefer ``irradiance``.
        light_dirs: (K, 3) unit directions *towards* the lights, K <= MAX_LIGHTS.
        light_colors: (K, 3) irradiance of each light on a surface facing it.
        exposure: scale applied to the final radiance.
        shininess: Blinn-Phong exponent of surfaces.
        hair_shininess: exponent of the Kajiya-Kay lobe of strands.
        shadows: whether the lights cast shadow maps.
        irradiance: (h, 2h, 3) irradiance table E(n) of the ambient part
            (``render.shading.irradiance.irradiance_table``: equirect grid of normals, world +z
            up), looked up bilinearly (``irradiance_lookup`` / ``env_irradiance``), or None.
    """

    sh9: np.ndarray | None
    light_dirs: np.ndarray
    light_colors: np.ndarray
    exposure: float = 1.0
    shininess: float = 40.0
    hair_shininess: float = 80.0
    shadows: bool = True
    irradiance: np.ndarray | None = None

    @property
    def ambient(self) -> str:
        """'table' (irradiance table) or 'sh9': the ambient term the shaded mode evaluates."""
        return "table" if self.irradiance is not None else "sh9"

    def __post_init__(self) -> None:
        d = np.asarray(self.light_dirs, dtype=np.float64).reshape(-1, 3)
        c = np.asarray(self.light_colors, dtype=np.float32).reshape(-1, 3)
        if self.sh9 is None and self.irradiance is None:
            raise RasterError("lighting needs an ambient term: sh9 or an irradiance table")
        if self.sh9 is not None:
            sh = np.asarray(self.sh9, dtype=np.float32)
            if sh.shape != (9, 3) or not np.all(np.isfinite(sh)):
                raise RasterError(f"lighting sh9 must be finite (9, 3), got {sh.shape}")
            object.__setattr__(self, "sh9", sh)
        if self.irradiance is not None:
            t = np.ascontiguousarray(self.irradiance, dtype=np.float32)
            if t.ndim != 3 or t.shape[2] != 3 or t.shape[1] != 2 * t.shape[0] or not np.all(np.isfinite(t)):
                raise RasterError(f"lighting irradiance table must be finite (h, 2h, 3), got {t.shape}")
            object.__setattr__(self, "irradiance", t)
        if len(d) != len(c) or len(d) > MAX_LIGHTS:
            raise RasterError(f"lighting needs as many light colours as directions, at most {MAX_LIGHTS}")
        n = np.linalg.norm(d, axis=1, keepdims=True)
        if np.any(n < 1e-9):
            raise RasterError("lighting: zero light direction")
        object.__setattr__(self, "light_dirs", (d / n).astype(np.float32))
        object.__setattr__(self, "light_colors", c)


class MeshRasterizer(GLOwner):
    """Owns the GL programs, buffers and framebuffers of the mesh rasteriser.

    ``ctx`` is an explicit moderngl context (``render.gl.create_context``); it is not released
    here.  Usage::

        with MeshRasterizer(ctx, supersample=3) as r:
            r.set_mesh(mesh)
            r.set_lighting(lighting)      # optional: shaded mode
            res = r.render(camera)
    """

    released_error = RasterError

    def __init__(self, ctx, supersample: int = 1) -> None:
        if int(supersample) < 1:
            raise RasterError(f"supersample must be >= 1, got {supersample}")
        super().__init__(ctx)
        self.supersample = int(supersample)
        self._prog_flat = self.own(program(ctx, "raster_mesh_vert.glsl", "raster_mesh_frag.glsl"))
        self._prog_shaded_by_mode: dict[str, object] = {}
        self._prog_shaded = None
        self._prog_shadow = None
        self._irr_tex = None
        self._vbo = self._ibo = self._vis_vbo = self._emit_vbo = None
        self._vaos: dict[str, object] = {}
        self._mesh: RasterMesh | None = None
        self._lighting: Lighting | None = None
        self.shadow_info: dict = {}
        #: (V, K) float32 per-vertex visibility of the K lights from the last shadow build.
        self.vertex_visibility = np.zeros((0, 0), np.float32)

    @property
    def mesh(self) -> RasterMesh | None:
        """The mesh last given to set_mesh()."""
        return self._mesh

    def _free_mesh(self) -> None:
        self.free(*self._vaos.values(), self._vbo, self._ibo, self._vis_vbo, self._emit_vbo)
        self._vaos.clear()
        self._vbo = self._ibo = self._vis_vbo = self._emit_vbo = None

    def _check(self) -> None:
        self.check_alive()
        if self._mesh is None:
            raise RasterError("MeshRasterizer: call set_mesh() before rendering")

    # ------------------------------------------------------------------ mesh
    def set_mesh(self, mesh: RasterMesh) -> None:
        """Upload ``mesh`` (replaces the previous one; invalidates shadow maps)."""
        self.check_alive()
        self._free_mesh()
        V = len(mesh.vertices)
        normals = mesh.normals if mesh.normals is not None else np.zeros((V, 3), np.float32)
        tangents = mesh.tangents if mesh.tangents is not None else np.zeros((V, 3), np.float32)
        occl = mesh.occlusion if mesh.occlusion is not None else np.ones(V, np.float32)
        spec = mesh.specular if mesh.specular is not None else np.zeros(V, np.float32)
        data = np.concatenate([mesh.vertices, mesh.colors, normals, tangents, occl[:, None], spec[:, None]], axis=1)
        self._vbo = self.own(self.ctx.buffer(np.ascontiguousarray(data, dtype=np.float32).tobytes()))
        self._ibo = self.own(self.ctx.buffer(mesh.faces.tobytes()))
        self._vis_vbo = self.own(self.ctx.buffer(np.ones((V, MAX_LIGHTS), np.float32).tobytes()))
        self._emit_vbo = self.own(self.ctx.buffer(np.zeros((V, 3), np.float32).tobytes()))
        self._mesh = mesh
        self._has_normals = mesh.normals is not None
        if self._lighting is not None:
            self._build_shadows()

    def _vao(self, kind: str):
        if kind not in self._vaos:
            progs = {"flat": self._prog_flat, "shadow": self._prog_shadow}
            progs.update({f"shaded_{m}": p for m, p in self._prog_shaded_by_mode.items()})
            prog = progs[kind]
            fmt, names = vertex_format(prog, _ATTRIBUTES)
            content = [(self._vbo, fmt, *names)]
            if "in_vis" in prog:
                content.append((self._vis_vbo, "4f", "in_vis"))
            if "in_emit" in prog:
                content.append((self._emit_vbo, "3f", "in_emit"))
            self._vaos[kind] = self.own(self.ctx.vertex_array(prog, content, index_buffer=self._ibo,
                                                              index_element_size=4))
        return self._vaos[kind]

    # ------------------------------------------------------------------ lighting
    def set_lighting(self, lighting: Lighting | None) -> None:
        """Switch to shaded mode with ``lighting`` (None = flat per-vertex colour)."""
        self.check_alive()
        self._lighting = lighting
        self.free(self._irr_tex)
        self._irr_tex = None
        if lighting is None:
            return
        mode = lighting.ambient
        if mode not in self._prog_shaded_by_mode:
            self._prog_shaded_by_mode[mode] = self.own(program(
                self.ctx, "raster_mesh_vert.glsl", "raster_shaded_frag.glsl", defines=shaded_defines(mode)))
        self._prog_shaded = self._prog_shaded_by_mode[mode]
        if mode == "table":
            self._irr_tex = self.own(irradiance_texture(self.ctx, lighting.irradiance))
        if self._prog_shadow is None:
            self._prog_shadow = self.own(program(self.ctx, "raster_shadow_vert.glsl", "raster_shadow_frag.glsl"))
        if self._mesh is not None:
            self._build_shadows()

    def _build_shadows(self) -> None:
        """Per-vertex visibility of the lighting's lights (:meth:`light_visibility`).  The lights
        are fixed in the world, so this is done once per mesh and lighting, not per view."""
        lt = self._lighting
        V = len(self._mesh.vertices)
        vis = np.ones((V, MAX_LIGHTS), np.float32)
        self.shadow_info = {}
        if lt is not None and lt.shadows and len(lt.light_dirs):
            k = len(lt.light_dirs)
            vis[:, :k] = self.light_visibility(lt.light_dirs)
            b = self._mesh.bounds
            radius = 0.5 * float(np.linalg.norm(b[1] - b[0])) * (1 + SHADOW_BOX_MARGIN)
            self.shadow_info = {"map_size": SHADOW_MAP_SIZE, "texel_m": 2 * radius / SHADOW_MAP_SIZE,
                                "mean_visibility": vis[:, :k].mean(0).tolist()}
        self._vis_vbo.write(vis.tobytes())
        self.vertex_visibility = vis[:, : len(lt.light_dirs)].copy() if lt is not None else vis[:, :0].copy()

    def light_visibility(self, dirs, points: np.ndarray | None = None, map_size: int = SHADOW_MAP_SIZE) -> np.ndarray:
        """(N, n) float32 visibility of n directional lights (``dirs`` (n, 3) towards the lights)
        at ``points`` (N, 3; default every vertex of the mesh): one orthographic depth map per
        light covering the mesh's bounding sphere, rendered here, read back and looked up for
        every point (:func:`shadow_map_visibility`)."""
        self._check()
        if self._prog_shadow is None:
            self._prog_shadow = self.own(program(self.ctx, "raster_shadow_vert.glsl", "raster_shadow_frag.glsl"))
        pts = self._mesh.vertices if points is None else np.asarray(points, np.float64)
        dirs = np.asarray(dirs, np.float64).reshape(-1, 3)
        vis = np.ones((len(pts), len(dirs)), np.float32)
        b = self._mesh.bounds
        centre = 0.5 * (b[0] + b[1])
        radius = 0.5 * float(np.linalg.norm(b[1] - b[0])) * (1 + SHADOW_BOX_MARGIN)
        ctx = self.ctx
        vao = self._vao("shadow")
        tgt = self.target(map_size, map_size, colours=())
        for i, d in enumerate(dirs):
            vp = light_view_projection(d, centre, radius)
            tgt.fbo.use()
            tgt.fbo.clear(depth=1.0)
            ctx.enable(ctx.DEPTH_TEST)
            ctx.disable(ctx.CULL_FACE)
            self._prog_shadow["u_mvp"].write(mat4_bytes(vp))
            vao.render()
            vis[:, i] = shadow_map_visibility(pts, tgt.read_depth(), vp, d, SHADOW_BIAS_TEXELS * 2 * radius / map_size)
        return vis

    def set_emission(self, emission: np.ndarray | None) -> None:
        """Per-vertex radiance (V, 3) added to the shaded colour before exposure (None = 0): for
        shading computed outside the rasteriser, e.g. the hair lobes of ``datasets_synthetic``."""
        self._check()
        V = len(self._mesh.vertices)
        e = np.zeros((V, 3), np.float32) if emission is None else np.ascontiguousarray(emission, np.float32)
        if e.shape != (V, 3) or not np.all(np.isfinite(e)):
            raise RasterError(f"emission must be finite ({V}, 3), got {e.shape}")
        self._emit_vbo.write(e.tobytes())

    # ------------------------------------------------------------------ render
    def planes(self, camera: Camera) -> tuple[float, float]:
        """Default near / far planes of ``camera``: those of the mesh bounds (render.owner.near_far)."""
        self._check()
        return near_far(camera, self._mesh.bounds)

    def draw(self, camera: Camera, factor: int, near: float, far: float):
        """Draw the mesh for ``camera`` with ``factor`` x ``factor`` samples per pixel into this
        owner's frame target (GLOwner.begin_frame; colour attachments: colour + coverage,
        z-depth, normal); returns the target.  resolve_frame() / read_frame() then give the
        box-resolved colour."""
        self._check()
        shaded = self._lighting is not None
        cam = camera if factor == 1 else camera.scaled(factor)
        tgt = self.begin_frame(camera.width, camera.height, factor, colours=RASTER_COLOURS)
        prog = self._prog_shaded if shaded else self._prog_flat
        prog["u_view"].write(mat4_bytes(cam.gl_view()))
        prog["u_proj"].write(mat4_bytes(cam.gl_projection(near, far)))
        prog["u_eye"].value = tuple(float(x) for x in cam.center)
        prog["u_has_normals"].value = int(self._has_normals)
        if shaded:
            self._set_shading_uniforms(prog)
        self._vao(f"shaded_{self._lighting.ambient}" if shaded else "flat").render()
        return tgt

    def _set_shading_uniforms(self, prog) -> None:
        lt = self._lighting
        if lt.ambient == "table":
            self._irr_tex.use(location=IRRADIANCE_TEXTURE_UNIT)
            prog["u_irradiance"].value = IRRADIANCE_TEXTURE_UNIT
        else:
            prog["u_sh9"].write(np.ascontiguousarray(sh9_glsl_uniform(lt.sh9), dtype=np.float32).tobytes())
        k = len(lt.light_dirs)
        dirs = np.zeros((MAX_LIGHTS, 3), np.float32)
        cols = np.zeros((MAX_LIGHTS, 3), np.float32)
        dirs[:k] = lt.light_dirs
        cols[:k] = lt.light_colors
        prog["u_light_dir"].write(dirs.tobytes())
        prog["u_light_col"].write(cols.tobytes())
        prog["u_exposure"].value = float(lt.exposure)
        prog["u_shininess"].value = float(lt.shininess)
        prog["u_hair_shininess"].value = float(lt.hair_shininess)
        prog["u_nlights"].value = k

    def render(self, camera: Camera, near: float | None = None, far: float | None = None) -> RasterResult:
        """Render the current mesh for ``camera``; see :class:`RasterResult`.

        ``near`` / ``far`` default to those of the mesh bounds (:meth:`planes`).
        """
        self._check()
        if near is None or far is None:
            n0, f0 = self.planes(camera)
            near = n0 if near is None else near
            far = f0 if far is None else far
        s = self.supersample
        tgt = self.draw(camera, s, near, far)
        self.resolve_frame()
        block, _ = self.read_frame()  # s x s blocks are the same set of samples in either row order
        if s % 2 == 1:
            # odd factor: the centre sub-sample of each s x s block sits exactly on the pixel centre
            # (Camera.scaled keeps centres exact), so one pass gives the single-sample depth too
            # (in bottom-first rows the centre sub-samples are rows c + s m as well, since the
            # block height s is odd and the image height is H s)
            c = s // 2
            dep, nor = tgt.read_colour(1)[c::s, c::s], tgt.read_colour(2)[c::s, c::s, :3]
        else:
            tgt = self.draw(camera, 1, near, far)
            dep, nor = tgt.read_colour(1), tgt.read_colour(2)[..., :3]
        # framebuffer row order (bottom first) until here
        color, alpha = gl_rows_to_image(block[..., :3]), gl_rows_to_image(block[..., 3])
        dep, nor = gl_rows_to_image(dep), gl_rows_to_image(nor)
        mask = dep > 0
        return RasterResult(color=np.ascontiguousarray(color, np.float32),
                            depth=np.where(mask, dep, 0).astype(np.float32),
                            normal=np.where(mask[..., None], nor, 0).astype(np.float32), mask=mask,
                            alpha=np.clip(alpha, 0, 1).astype(np.float32))


def shaded_defines(ambient: str) -> dict:
    """Constants of raster_shaded_frag.glsl, shared with its numpy twin (render.mesh.raster.reference)."""
    return {"MAX_LIGHTS": MAX_LIGHTS, "AMBIENT_TABLE": int(ambient == "table"),
            "HAIR_TANGENT_SQ": f"{HAIR_TANGENT_SQ:.9e}"}


# ---------------------------------------------------------------------------------- reference
def face_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(F, 3) float64 unit normals of the triangles (right-hand rule); zero for degenerate ones."""
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces)
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    ln = np.linalg.norm(n, axis=1, keepdims=True)
    return np.where(ln > 0, n / np.maximum(ln, 1e-300), 0.0)

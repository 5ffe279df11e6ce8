"""Glossy mesh renderer: Phong reflection with non-uniform roughness from the multi-scale
environment map (docs/methods.md §2, seed 000 §3.3; issue 6 item 2).

Per pixel: the reflection r of the view about the (interpolated, eye-facing) normal and the
smoothness lambda in [0, 1] (the thesis' per-vertex "roughness" coordinate: 1 = mirror, 0 = the
roughest lobe) give one trilinear 3-D texture fetch ``msem_radiance(msem, r, lambda)``
(``render/shaders/shading_msem.glsl``, the shading module's lookup; the map itself is built by
``render.shading.msem.msem_build``).  lambda comes either from the vertices (linearly interpolated
across each triangle, the thesis' per-vertex mode) or from a smoothness texture over the mesh's
uv coordinates (per texel, bilinear), which avoids the thesis' artefact of interpolating lambda
across a polygon where roughness changes abruptly.

The slow, obviously-correct twins are in ``render.mesh.glossy.reference``: the same lookup in numpy
(``msem_lookup``) at the numpy rasteriser's pixel centres, and the per-pixel brute-force Phong
integral over every environment pixel (with the horizon gate the MSEM drops) -- the thesis'
Table 5 reference.  Meshes: :func:`uv_sphere` and :func:`utah_teapot` (Newell's 32 Bezier patches,
``render/mesh/glossy/data/utah_teapot.txt``, public domain).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from capture.camera import Camera, gl_rows_to_image
from capture.sampling import points_box
from render.gl import program
from render.mesh.raster.gl import RasterError, triangle_arrays
from render.owner import GLOwner, mat4_bytes, near_far, vertex_format

#: Texture units of the MSEM (3-D) and the smoothness map.
MSEM_UNIT = 0
SMOOTH_MAP_UNIT = 1
#: Utah teapot control data (Newell 1975, public domain).
TEAPOT_FILE = Path(__file__).resolve().parent / "data" / "utah_teapot.txt"
#: Normals at degenerate patch corners (the lid knob top, the bottom centre) are taken this far
#: inside the patch in (u, v), where the derivatives do not vanish.
TEAPOT_DEGENERATE_EPS = 1e-3

_ATTRIBUTES = (("in_pos", 3), ("in_normal", 3), ("in_smooth", 1), ("in_uv", 2))


@dataclass(frozen=True)
class GlossyMesh:
    """A triangle mesh with per-vertex smoothness and optional per-texel smoothness map.

    Attributes:
        vertices: (V, 3) float32 world positions, metres.
        faces: (F, 3) int32 vertex indices.
        normals: (V, 3) float32 unit normals (their sign is irrelevant: they are turned to the eye).
        smoothness: (V,) float32 MSEM smoothness lambda in [0, 1] (1 = mirror).
        uv: (V, 2) float32 texture coordinates of ``smoothness_map``, or None.
        smoothness_map: (h, w) float32 per-texel smoothness in [0, 1] (row i at v = (i + 0.5) / h,
            column j at u = (j + 0.5) / w; LINEAR, wrap in u, clamp in v), or None; when given it
            replaces the per-vertex smoothness.
    """

    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray
    smoothness: np.ndarray
    uv: np.ndarray | None = None
    smoothness_map: np.ndarray | None = None

    def __post_init__(self) -> None:
        v, f = triangle_arrays(self.vertices, self.faces, "glossy mesh")
        n = np.ascontiguousarray(self.normals, np.float32)
        s = np.ascontiguousarray(self.smoothness, np.float32)
        if n.shape != v.shape or not np.all(np.isfinite(n)):
            raise RasterError(f"glossy mesh normals must be finite {v.shape}, got {n.shape}")
        if s.shape != (len(v),) or not np.all((s >= 0) & (s <= 1)):
            raise RasterError(f"glossy mesh smoothness must be ({len(v)},) in [0, 1]")
        for name, val in (("vertices", v), ("faces", f), ("normals", n), ("smoothness", s)):
            object.__setattr__(self, name, val)
        if (self.uv is None) != (self.smoothness_map is None):
            raise RasterError("glossy mesh: uv and smoothness_map go together")
        if self.uv is not None:
            uv = np.ascontiguousarray(self.uv, np.float32)
            m = np.ascontiguousarray(self.smoothness_map, np.float32)
            if uv.shape != (len(v), 2) or not np.all(np.isfinite(uv)):
                raise RasterError(f"glossy mesh uv must be finite ({len(v)}, 2), got {uv.shape}")
            if m.ndim != 2 or not np.all((m >= 0) & (m <= 1)):
                raise RasterError(f"glossy mesh smoothness_map must be (h, w) in [0, 1], got {m.shape}")
            object.__setattr__(self, "uv", uv)
            object.__setattr__(self, "smoothness_map", m)

    @property
    def bounds(self) -> np.ndarray:
        """(2, 3) float64 [min, max] of the vertices."""
        return points_box(self.vertices)


@dataclass(frozen=True)
class GlossyResult:
    """One render (all (H, W[, 3]) float32, rows top first; single sample at pixel centres).

    Attributes:
        color: linear radiance k_r F(r, lambda), 0 on background.
        smoothness: the smoothness used at each pixel (0 on background).
        depth: z-depth in metres, 0 on background.
        mask: bool coverage.
    """

    color: np.ndarray
    smoothness: np.ndarray
    depth: np.ndarray
    mask: np.ndarray


class GlossyRenderer(GLOwner):
    """Owns the program, MSEM 3-D texture, smoothness map, buffers and framebuffers.

    Usage::

        with GlossyRenderer(ctx) as g:
            g.set_msem(msem_build(env, 128).volume)
            g.set_mesh(utah_teapot(size=0.25, smoothness=...))
            res = g.render(camera)
    """

    released_error = RasterError

    def __init__(self, ctx, kr=(1.0, 1.0, 1.0)) -> None:
        super().__init__(ctx)
        self.kr = tuple(float(x) for x in np.broadcast_to(np.asarray(kr, float), (3,)))
        self._prog = self.own(program(ctx, "raster_glossy_vert.glsl", "raster_glossy_frag.glsl"))
        self._msem = self._map = self._vbo = self._ibo = self._vao = None
        self._mesh: GlossyMesh | None = None

    def set_msem(self, volume: np.ndarray) -> None:
        """Upload an (s, s, s, 3) MSEM (``render.shading.msem.msem_build(...).volume``)."""
        from render.shading.msem import msem_texture

        self.check_alive()
        vol = np.asarray(volume)
        if vol.ndim != 4 or vol.shape[3] != 3 or len(set(vol.shape[:3])) != 1:
            raise RasterError(f"MSEM volume must be (s, s, s, 3), got {vol.shape}")
        self.free(self._msem)
        self._msem = self.own(msem_texture(self.ctx, vol))

    def set_mesh(self, mesh: GlossyMesh) -> None:
        """Upload ``mesh`` (and its smoothness map) replacing the previous one."""
        import moderngl

        self.check_alive()
        self.free(self._vao, self._vbo, self._ibo, self._map)
        V = len(mesh.vertices)
        uv = mesh.uv if mesh.uv is not None else np.zeros((V, 2), np.float32)
        data = np.concatenate([mesh.vertices, mesh.normals, mesh.smoothness[:, None], uv], 1)
        self._vbo = self.own(self.ctx.buffer(np.ascontiguousarray(data, np.float32).tobytes()))
        self._ibo = self.own(self.ctx.buffer(mesh.faces.tobytes()))
        fmt, names = vertex_format(self._prog, _ATTRIBUTES)
        self._vao = self.own(self.ctx.vertex_array(self._prog, [(self._vbo, fmt, *names)],
                                                   index_buffer=self._ibo, index_element_size=4))
        m = mesh.smoothness_map if mesh.smoothness_map is not None else np.zeros((1, 1), np.float32)
        self._map = self.own(self.ctx.texture((m.shape[1], m.shape[0]), 1, np.ascontiguousarray(m).tobytes(),
                                              dtype="f4"))
        self._map.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self._map.repeat_x, self._map.repeat_y = True, False
        self._mesh = mesh

    def draw(self, camera: Camera, near: float | None = None, far: float | None = None):
        """Draw into the framebuffer for ``camera`` without reading back; returns the target
        (render.owner.Target; colour attachments: colour, aux). For timing; :meth:`render` reads back."""
        self.check_alive()
        if self._mesh is None or self._msem is None:
            raise RasterError("GlossyRenderer: call set_msem() and set_mesh() before rendering")
        if near is None or far is None:
            n0, f0 = near_far(camera, self._mesh.bounds)
            near, far = (n0 if near is None else near), (f0 if far is None else far)
        tgt = self.begin_frame(camera.width, camera.height, 1, colours=(4, 4))
        p = self._prog
        p["u_view"].write(mat4_bytes(camera.gl_view()))
        p["u_proj"].write(mat4_bytes(camera.gl_projection(near, far)))
        p["u_eye"].value = tuple(float(x) for x in camera.center)
        p["u_kr"].value = self.kr
        self._msem.use(location=MSEM_UNIT)
        p["u_msem"].value = MSEM_UNIT
        self._map.use(location=SMOOTH_MAP_UNIT)
        p["u_smooth_map"].value = SMOOTH_MAP_UNIT
        p["u_use_map"].value = int(self._mesh.smoothness_map is not None)
        self._vao.render()
        return tgt

    def render(self, camera: Camera, near: float | None = None, far: float | None = None) -> GlossyResult:
        """Render the current mesh for ``camera``; see :class:`GlossyResult`."""
        tgt = self.draw(camera, near, far)
        col = gl_rows_to_image(tgt.read_colour(0))
        aux = gl_rows_to_image(tgt.read_colour(1))
        mask = aux[..., 3] > 0.5
        return GlossyResult(color=np.ascontiguousarray(col[..., :3]),
                            smoothness=np.where(mask, aux[..., 0], 0).astype(np.float32),
                            depth=np.where(mask, aux[..., 1], 0).astype(np.float32), mask=mask)


# ------------------------------------------------------------------------------------ meshes
def uv_sphere(radius: float = 0.1, rows: int = 48, centre=(0.0, 0.0, 0.0)):
    """(vertices (V, 3), faces (F, 3), normals (V, 3), uv (V, 2)) of a latitude-longitude sphere
    (world +z pole; u = longitude / 2 pi with a duplicated seam column, v = colatitude / pi)."""
    cols = 2 * rows
    th = np.linspace(0, np.pi, rows + 1)
    ph = np.linspace(0, 2 * np.pi, cols + 1)
    T, P = np.meshgrid(th, ph, indexing="ij")
    n = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], -1).reshape(-1, 3)
    uv = np.stack([P / (2 * np.pi), T / np.pi], -1).reshape(-1, 2)
    idx = np.arange((rows + 1) * (cols + 1)).reshape(rows + 1, cols + 1)
    a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, 1:], idx[1:, :-1]
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    # drop the zero-area triangles at the poles
    v = radius * n + np.asarray(centre, float)
    area = np.linalg.norm(np.cross(v[faces[:, 1]] - v[faces[:, 0]], v[faces[:, 2]] - v[faces[:, 0]]), axis=1)
    return v, faces[area > 1e-12 * radius**2], n, uv


def load_teapot_patches(path: Path = TEAPOT_FILE) -> np.ndarray:
    """(32, 4, 4, 3) float64 Bezier control points of the Utah teapot (z up, data units)."""
    try:
        rows = [ln.strip() for ln in Path(path).read_text().splitlines() if ln.strip() and not ln.startswith("#")]
        npatch = int(rows[0])
        idx = np.array([[int(x) for x in r.split(",")] for r in rows[1 : 1 + npatch]]) - 1
        npts = int(rows[1 + npatch])
        pts = np.array([[float(x) for x in r.split(",")] for r in rows[2 + npatch : 2 + npatch + npts]])
    except (OSError, ValueError, IndexError) as e:
        raise RasterError(f"{path}: cannot read teapot patch data ({e})") from e
    if idx.shape != (npatch, 16) or pts.shape != (npts, 3) or idx.min() < 0 or idx.max() >= npts:
        raise RasterError(f"{path}: malformed teapot patch data")
    return pts[idx].reshape(npatch, 4, 4, 3)


def _bernstein(t):
    t = np.asarray(t, float)
    s = 1 - t
    b = np.stack([s**3, 3 * s * s * t, 3 * s * t * t, t**3], -1)
    db = np.stack([-3 * s * s, 3 * s * s - 6 * s * t, 6 * s * t - 3 * t * t, 3 * t * t], -1)
    return b, db


def utah_teapot(size: float = 0.25, n: int = 12, centre=(0.0, 0.0, 0.0)):
    """(vertices (V, 3), faces (F, 3), normals (V, 3), uv (V, 2)) of the Utah teapot tessellated
    into n x n quads per Bezier patch, scaled so its largest extent is ``size`` metres and its
    bounding box centred at ``centre`` (z up). uv = the patch parameters (u, v), with each patch's
    u squeezed into its own 1/32 strip so the per-texel map is continuous within a patch."""
    P = load_teapot_patches()
    t = np.linspace(0.0, 1.0, n + 1)
    te = np.clip(t, TEAPOT_DEGENERATE_EPS, 1 - TEAPOT_DEGENERATE_EPS)
    b, _ = _bernstein(t)
    be, dbe = _bernstein(te)
    pos = np.einsum("ui,vj,pijc->puvc", b, b, P)
    du = np.einsum("ui,vj,pijc->puvc", dbe, be, P)
    dv = np.einsum("ui,vj,pijc->puvc", be, dbe, P)
    nrm = np.cross(du, dv)
    nrm /= np.maximum(np.linalg.norm(nrm, axis=-1, keepdims=True), 1e-300)
    npatch = len(P)
    U, Vv = np.meshgrid(t, t, indexing="ij")
    uv = np.stack([(np.arange(npatch)[:, None, None] + 0.05 + 0.9 * U[None]) / npatch,
                   np.broadcast_to(Vv, (npatch, n + 1, n + 1))], -1)
    idx = np.arange(npatch * (n + 1) ** 2).reshape(npatch, n + 1, n + 1)
    a, bq, c, d = idx[:, :-1, :-1], idx[:, :-1, 1:], idx[:, 1:, 1:], idx[:, 1:, :-1]
    faces = np.concatenate([np.stack([a, bq, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    v = pos.reshape(-1, 3)
    area = np.linalg.norm(np.cross(v[faces[:, 1]] - v[faces[:, 0]], v[faces[:, 2]] - v[faces[:, 0]]), axis=1)
    faces = faces[area > 1e-10]
    lo, hi = points_box(v)
    scale = size / float((hi - lo).max())
    v = (v - 0.5 * (lo + hi)) * scale + np.asarray(centre, float)
    return v, faces, nrm.reshape(-1, 3), uv.reshape(-1, 2)

"""Procedural triangle-mesh building blocks for the synthetic scenes (world metres, +z up).

Every builder returns a :class:`render.mesh.raster.gl.RasterMesh` (vertices, faces, linear albedo,
unit normals, strand tangents, ambient occlusion, specular strength), so a scene is the
concatenation (:func:`merge`) of exact geometry that is both rendered and written as the
ground truth (``gt/mesh.ply``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from capture.atomic import atomic_write
from render.mesh.raster.gl import RasterMesh

#: Below this length a direction is treated as degenerate (metres or unitless).
EPS = 1e-12


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.maximum(n, EPS)


def _perpendicular(t: np.ndarray) -> np.ndarray:
    """(..., 3) unit vectors perpendicular to the unit vectors ``t``."""
    a = np.where(np.abs(t[..., :1]) < 0.9, np.array([1.0, 0, 0]), np.array([0, 1.0, 0]))
    return _unit(np.cross(t, a))


def tube_sweep(paths: np.ndarray, radii: np.ndarray, sides: int, colors: np.ndarray,
               occlusion: np.ndarray | None = None, specular: float | np.ndarray = 0.0,
               strand: bool = True) -> RasterMesh:
    """Sweep S polylines into open tubes with ``sides`` sides (parallel-transport frames).

    Args:
        paths: (S, P, 3) centre-line points in metres, P >= 2.
        radii: (S, P) tube radius at each point (metres), > 0.
        sides: polygon sides of the cross-section (>= 3).
        colors: (S, P, 3) or (S, 3) linear albedo.
        occlusion: (S, P) ambient visibility, or None (= 1).
        specular: scalar or (S, P) specular strength.
        strand: store the centre-line tangents (Kajiya-Kay shading) instead of zero tangents.
    Returns a mesh with S * P * sides vertices and S * (P-1) * sides * 2 triangles.
    """
    paths = np.asarray(paths, np.float64)
    S, P, _ = paths.shape
    if P < 2 or sides < 3:
        raise ValueError(f"tube_sweep: need P >= 2 points and >= 3 sides, got P={P}, sides={sides}")
    radii = np.broadcast_to(np.asarray(radii, np.float64), (S, P))
    d = np.gradient(paths, axis=1)
    T = _unit(d)
    N = np.empty_like(T)
    N[:, 0] = _perpendicular(T[:, 0])
    for p in range(1, P):  # parallel transport: project the previous normal onto the new plane
        n = N[:, p - 1] - np.sum(N[:, p - 1] * T[:, p], -1, keepdims=True) * T[:, p]
        bad = np.linalg.norm(n, axis=-1) < 1e-6
        n[bad] = _perpendicular(T[bad, p])
        N[:, p] = _unit(n)
    B = np.cross(T, N)
    ang = 2 * np.pi * np.arange(sides) / sides
    ring = np.cos(ang)[None, None, :, None] * N[:, :, None] + np.sin(ang)[None, None, :, None] * B[:, :, None]
    verts = paths[:, :, None] + radii[:, :, None, None] * ring  # (S, P, sides, 3)
    idx = np.arange(S * P * sides).reshape(S, P, sides)
    a = idx[:, :-1]
    b = np.roll(idx, -1, axis=2)[:, :-1]
    c = np.roll(idx, -1, axis=2)[:, 1:]
    dd = idx[:, 1:]
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, dd], -1).reshape(-1, 3)])
    colors = np.asarray(colors, np.float64)
    if colors.shape == (S, 3):
        colors = np.broadcast_to(colors[:, None], (S, P, 3))
    col = np.broadcast_to(colors[:, :, None], (S, P, sides, 3))
    occ = np.ones((S, P)) if occlusion is None else np.broadcast_to(occlusion, (S, P))
    spec = np.broadcast_to(np.asarray(specular, np.float64), (S, P))
    tang = np.broadcast_to(T[:, :, None], (S, P, sides, 3)) if strand else np.zeros((S, P, sides, 3))
    return RasterMesh(
        verts.reshape(-1, 3), faces, col.reshape(-1, 3), normals=ring.reshape(-1, 3),
        tangents=tang.reshape(-1, 3), occlusion=np.broadcast_to(occ[:, :, None], (S, P, sides)).reshape(-1),
        specular=np.broadcast_to(spec[:, :, None], (S, P, sides)).reshape(-1))


def grid_faces(rows: int, cols: int, wrap_cols: bool = False) -> np.ndarray:
    """Two triangles per cell of a rows x cols vertex grid (row-major), optionally wrapping columns."""
    idx = np.arange(rows * cols).reshape(rows, cols)
    right = np.roll(idx, -1, axis=1) if wrap_cols else idx[:, 1:]
    left = idx if wrap_cols else idx[:, :-1]
    a, b = left[:-1], right[:-1]
    c, d = right[1:], left[1:]
    return np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])


def ellipsoid(axes, n_theta: int, n_phi: int, color, occlusion: float = 1.0, specular: float = 0.0,
              color_fn=None) -> RasterMesh:
    """Closed UV ellipsoid centred at the origin with semi-axes ``axes`` (metres), exact normals.

    ``color_fn(points (N,3)) -> (N,3)`` overrides the constant ``color``.
    """
    a = np.asarray(axes, np.float64)
    th = np.linspace(0, np.pi, n_theta + 1)[1:-1]
    ph = np.linspace(0, 2 * np.pi, n_phi, endpoint=False)
    tt, pp = np.meshgrid(th, ph, indexing="ij")
    u = np.stack([np.sin(tt) * np.cos(pp), np.sin(tt) * np.sin(pp), np.cos(tt)], -1).reshape(-1, 3)
    verts = np.concatenate([[[0, 0, a[2]]], u * a, [[0, 0, -a[2]]]])
    normals = _unit(np.concatenate([[[0, 0, 1.0]], u / a, [[0, 0, -1.0]]]))
    rows = n_theta - 1
    body = grid_faces(rows, n_phi, wrap_cols=True) + 1
    j = np.arange(n_phi)
    top = np.stack([np.zeros(n_phi, int), 1 + (j + 1) % n_phi, 1 + j], -1)
    last = 1 + (rows - 1) * n_phi
    bot = np.stack([np.full(n_phi, len(verts) - 1), last + j, last + (j + 1) % n_phi], -1)
    faces = np.concatenate([top, body, bot])
    cols = color_fn(verts) if color_fn is not None else np.broadcast_to(np.asarray(color, float), verts.shape)
    V = len(verts)
    return RasterMesh(verts, faces, cols, normals=normals, occlusion=np.full(V, occlusion),
                      specular=np.full(V, specular))


def torus(major: float, minor: float, n_major: int, n_minor: int, color_fn, specular: float = 0.0) -> RasterMesh:
    """Torus around +z at the origin, exact normals; ``color_fn(u, v) -> (N, 3)`` with u, v the
    major / minor angles (radians)."""
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, n_major, endpoint=False),
                       np.linspace(0, 2 * np.pi, n_minor, endpoint=False), indexing="ij")
    u, v = u.reshape(-1), v.reshape(-1)
    n = np.stack([np.cos(v) * np.cos(u), np.cos(v) * np.sin(u), np.sin(v)], -1)
    c = np.stack([major * np.cos(u), major * np.sin(u), np.zeros_like(u)], -1)
    faces = grid_faces(n_major + 1, n_minor, wrap_cols=True)
    faces = np.where(faces >= n_major * n_minor, faces - n_major * n_minor, faces)  # wrap rows
    V = len(u)
    return RasterMesh(c + minor * n, faces, color_fn(u, v), normals=n, occlusion=np.ones(V),
                      specular=np.full(V, specular))


def lathe(profile_rz: np.ndarray, n_phi: int, colors: np.ndarray, occlusion=None, specular: float = 0.0) -> RasterMesh:
    """Surface of revolution around +z of the polyline ``profile_rz`` (M, 2) = (radius, z);
    ``colors`` (M, 3) per profile point.  Normals from the profile (perpendicular, outward when
    the profile runs bottom -> top on the outside)."""
    pr = np.asarray(profile_rz, np.float64)
    M = len(pr)
    ph = np.linspace(0, 2 * np.pi, n_phi, endpoint=False)
    d = np.gradient(pr, axis=0)
    n2 = _unit(np.stack([d[:, 1], -d[:, 0]], -1))  # (dr, dz) rotated by -90 degrees
    cp, sp = np.cos(ph)[None, :], np.sin(ph)[None, :]
    verts = np.stack([pr[:, :1] * cp, pr[:, :1] * sp, np.broadcast_to(pr[:, 1:], (M, n_phi))], -1)
    norms = np.stack([n2[:, :1] * cp, n2[:, :1] * sp, np.broadcast_to(n2[:, 1:], (M, n_phi))], -1)
    faces = grid_faces(M, n_phi, wrap_cols=True)
    col = np.broadcast_to(np.asarray(colors, float)[:, None], (M, n_phi, 3))
    occ = np.ones(M) if occlusion is None else np.asarray(occlusion, float)
    return RasterMesh(verts.reshape(-1, 3), faces, col.reshape(-1, 3), normals=norms.reshape(-1, 3),
                      occlusion=np.broadcast_to(occ[:, None], (M, n_phi)).reshape(-1),
                      specular=np.full(M * n_phi, specular))


def merge(meshes: list[RasterMesh]) -> RasterMesh:
    """Concatenate meshes (missing optional attributes become 0 normals/tangents, 1 occlusion, 0 specular)."""
    vs, fs, cs, ns, ts, os_, ss = [], [], [], [], [], [], []
    off = 0
    for m in meshes:
        V = len(m.vertices)
        vs.append(m.vertices)
        fs.append(m.faces + off)
        cs.append(m.colors)
        ns.append(m.normals if m.normals is not None else np.zeros((V, 3), np.float32))
        ts.append(m.tangents if m.tangents is not None else np.zeros((V, 3), np.float32))
        os_.append(m.occlusion if m.occlusion is not None else np.ones(V, np.float32))
        ss.append(m.specular if m.specular is not None else np.zeros(V, np.float32))
        off += V
    return RasterMesh(np.concatenate(vs), np.concatenate(fs), np.concatenate(cs), np.concatenate(ns),
                      np.concatenate(ts), np.concatenate(os_), np.concatenate(ss))


def transformed(mesh: RasterMesh, R: np.ndarray, t) -> RasterMesh:
    """Rigidly move a mesh: x -> R x + t (normals and tangents rotated)."""
    R = np.asarray(R, np.float64)
    rot = (lambda a: None if a is None else a @ R.T)
    return RasterMesh(mesh.vertices @ R.T + np.asarray(t, float), mesh.faces, mesh.colors, rot(mesh.normals),
                      rot(mesh.tangents), mesh.occlusion, mesh.specular)


def ply_bytes(mesh: RasterMesh) -> bytes:
    """Binary little-endian PLY: float xyz, float normals (0 when absent), uchar sRGB colour, int faces."""
    from capture.scan import to_uint8_srgb

    V, F = len(mesh.vertices), len(mesh.faces)
    vt = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("nx", "<f4"), ("ny", "<f4"), ("nz", "<f4"),
                   ("red", "u1"), ("green", "u1"), ("blue", "u1")])
    va = np.empty(V, vt)
    va["x"], va["y"], va["z"] = mesh.vertices.T
    n = mesh.normals if mesh.normals is not None else np.zeros((V, 3), np.float32)
    va["nx"], va["ny"], va["nz"] = n.T
    c = to_uint8_srgb(mesh.colors)
    va["red"], va["green"], va["blue"] = c.T
    ft = np.dtype([("n", "u1"), ("i", "<i4", (3,))])
    fa = np.empty(F, ft)
    fa["n"] = 3
    fa["i"] = mesh.faces
    header = ("ply\nformat binary_little_endian 1.0\ncomment furrow synthetic ground truth, metres, +z up\n"
              f"element vertex {V}\nproperty float x\nproperty float y\nproperty float z\n"
              "property float nx\nproperty float ny\nproperty float nz\n"
              "property uchar red\nproperty uchar green\nproperty uchar blue\n"
              f"element face {F}\nproperty list uchar int vertex_indices\nend_header\n")
    return header.encode("ascii") + va.tobytes() + fa.tobytes()


def write_ply(mesh: RasterMesh, path) -> Path:
    """Write :func:`ply_bytes` to ``path`` (atomically)."""
    with atomic_write(path) as tmp:
        tmp.write_bytes(ply_bytes(mesh))
    return Path(path)


"""Fur grown on any surface: strands from root points, combed, drooping and curled, kept outside
the body (used by the ``furrybunny`` scene; the same recipe as the fur ball's strands, written
for an arbitrary triangle mesh instead of an analytic ellipsoid).

:func:`grow_strands` turns roots, surface normals and a combing direction into (S, P, 3) strand
centre lines; :func:`push_outside` moves strand points that fall inside a closed mesh back out
along the nearest surface normal; :func:`strand_tubes` sweeps them into thin tapering tubes with
the strand tangents the hair shading needs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from datasets_synthetic.geometry import _perpendicular, _unit, tube_sweep
from render.mesh.raster.gl import RasterMesh

#: Strand points closer than this to the body surface (or inside it) are pushed out to it (metres).
SKIN_CLEARANCE_M = 3e-4
#: Rounds of :func:`push_outside` (each pushes the points found inside after the previous one).
PUSH_ROUNDS = 2


@dataclass(frozen=True)
class FurParams:
    """Strand shape of a pelt (lengths in metres)."""

    strands: int = 20000
    """Number of strands."""
    length: float = 0.014
    """Mean strand length."""
    length_jitter: float = 0.35
    """Relative uniform jitter of the strand length."""
    root_radius: float = 0.0004
    """Tube radius at the root."""
    tip_radius: float = 0.0001
    """Tube radius at the tip (linear taper)."""
    sides: int = 3
    """Sides of each tube's cross-section."""
    segments: int = 8
    """Segments along each strand."""
    comb: float = 1.3
    """Weight of the combing direction in the root direction (0 = along the normal)."""
    gravity: float = 0.6
    """Droop: weight of -z added to the direction at the tip (grows linearly from the root)."""
    curl: float = 0.25
    """Amplitude of the helical curl."""
    curl_turns: float = 0.7
    """Turns of the curl helix over a strand."""
    jitter: float = 0.3
    """Standard deviation of the random tilt of each root direction."""
    root_occlusion: float = 0.15
    """Ambient visibility at the root (1 at the tip)."""
    specular: float = 0.08
    """Specular strength of the strands."""

    def __post_init__(self) -> None:
        if self.strands < 1 or self.segments < 1 or self.sides < 3:
            raise ValueError(f"fur: need strands >= 1, segments >= 1, sides >= 3, got {self.strands}, "
                             f"{self.segments}, {self.sides}")
        if not 0 < self.tip_radius <= self.root_radius or self.length <= 0:
            raise ValueError("fur: need 0 < tip_radius <= root_radius and length > 0")


def sample_surface(rng: np.random.Generator, vertices: np.ndarray, faces: np.ndarray, normals: np.ndarray,
                   n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """n points uniformly by area on a triangle mesh: (points (n, 3), unit normals interpolated
    from the vertex ``normals`` (n, 3), face index (n,))."""
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces)
    area = 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)
    tri = rng.choice(len(f), size=n, p=area / area.sum())
    r1, r2 = rng.uniform(size=(2, n))
    s = np.sqrt(r1)
    w = np.stack([1 - s, s * (1 - r2), s * r2], -1)  # uniform barycentrics
    pts = np.einsum("nk,nkd->nd", w, v[f[tri]])
    nrm = _unit(np.einsum("nk,nkd->nd", w, np.asarray(normals, np.float64)[f[tri]]))
    return pts, nrm, tri


def grow_strands(rng: np.random.Generator, roots: np.ndarray, normals: np.ndarray, comb_dir: np.ndarray,
                 p: FurParams) -> tuple[np.ndarray, np.ndarray]:
    """(S, P, 3) strand centre lines and (S,) lengths: each leaves its root along the normal tilted
    towards ``comb_dir`` (weight ``p.comb``, plus random jitter), droops towards -z and curls."""
    S, P = len(roots), int(p.segments) + 1
    n = _unit(np.asarray(normals, np.float64))
    flow = np.asarray(comb_dir, np.float64)
    flow = flow - np.sum(flow * n, -1, keepdims=True) * n
    small = np.linalg.norm(flow, axis=1) < 1e-3
    flow[small] = _perpendicular(n[small])
    d0 = _unit(n + p.comb * _unit(flow) + p.jitter * rng.normal(size=(S, 3)))
    e1 = _perpendicular(d0)
    e2 = np.cross(d0, e1)
    length = p.length * (1 + p.length_jitter * rng.uniform(-1, 1, S))
    s = np.linspace(0, 1, P)
    ang = 2 * np.pi * p.curl_turns * s[None] + rng.uniform(0, 2 * np.pi, S)[:, None]
    curl = p.curl * (np.cos(ang)[..., None] * e1[:, None] + np.sin(ang)[..., None] * e2[:, None])
    down = np.array([0.0, 0.0, -1.0])
    dirs = _unit(d0[:, None] + p.gravity * s[None, :, None] * down + curl * s[None, :, None] ** 0.5)
    step = (length / (P - 1))[:, None, None]
    root = np.asarray(roots, np.float64) - 0.6 * p.root_radius * n  # start just below the skin
    paths = root[:, None] + np.concatenate([np.zeros((S, 1, 3)), np.cumsum(dirs[:, :-1] * step, axis=1)], axis=1)
    return paths, length


def push_outside(paths: np.ndarray, vertices: np.ndarray, faces: np.ndarray,
                 clearance: float = SKIN_CLEARANCE_M, rounds: int = PUSH_ROUNDS) -> tuple[np.ndarray, int]:
    """Strand points (all but the root) inside the closed mesh or nearer than ``clearance`` to it
    are moved to ``clearance`` outside the nearest surface point (open3d signed distance, so the
    mesh must be watertight).  Returns (paths, number of points moved in the first round)."""
    import open3d as o3d

    rc = o3d.t.geometry.RaycastingScene()
    rc.add_triangles(o3d.core.Tensor(np.asarray(vertices, np.float32)), o3d.core.Tensor(np.asarray(faces, np.uint32)))
    out = np.array(paths, np.float64)
    S, P, _ = out.shape
    moved0 = 0
    for r in range(rounds):
        q = out[:, 1:].reshape(-1, 3)
        sd = rc.compute_signed_distance(o3d.core.Tensor(q.astype(np.float32))).numpy().astype(np.float64)
        bad = sd < clearance
        if r == 0:
            moved0 = int(bad.sum())
        if not bad.any():
            break
        cp = rc.compute_closest_points(o3d.core.Tensor(q[bad].astype(np.float32)))
        closest = cp["points"].numpy().astype(np.float64)
        fn = np.asarray(vertices, np.float64)[np.asarray(faces)[cp["primitive_ids"].numpy()]]
        nrm = _unit(np.cross(fn[:, 1] - fn[:, 0], fn[:, 2] - fn[:, 0]))
        # orient the face normal outward: away from the point when it is inside, towards it outside
        towards = q[bad] - closest
        sign = np.where(sd[bad] < 0, -1.0, 1.0) * np.sign(np.sum(towards * nrm, -1) + 1e-30)
        q[bad] = closest + clearance * nrm * sign[:, None]
        out[:, 1:] = q.reshape(S, P - 1, 3)
    return out, moved0


def strand_tubes(paths: np.ndarray, colors: np.ndarray, p: FurParams) -> RasterMesh:
    """Tapering tubes (root ``p.root_radius`` to tip ``p.tip_radius``) along ``paths`` (S, P, 3)
    with per-point ``colors`` (S, P, 3), ambient visibility growing from ``p.root_occlusion`` at
    the root to 1 at the tip, and strand tangents."""
    S, P, _ = paths.shape
    s = np.linspace(0, 1, P)
    radii = np.broadcast_to(p.root_radius + (p.tip_radius - p.root_radius) * s, (S, P))
    occl = np.broadcast_to(p.root_occlusion + (1 - p.root_occlusion) * s ** 0.8, (S, P))
    return tube_sweep(paths, radii, p.sides, colors, occl, p.specular)

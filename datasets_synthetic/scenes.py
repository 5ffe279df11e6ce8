"""Seeded procedural scenes with exact ground-truth geometry (world metres, +z up, centred
at the origin, 0.15-0.3 m across).

* ``furball``: an ellipsoidal body covered by thousands of thin tapering strands (real tube
  geometry, 3-4 sides, radius ~0.45 mm at the root) with combing, gravity droop and curl, and a
  tabby coat pattern; ambient occlusion grows from root to tip (strand depth).
* ``plant``: a terracotta pot with soil, a stem, branches carrying many thin needles in whorls,
  and a few flat (two-sided) leaves on petioles.
* ``torus``: the smooth control object (tilted, painted with a smooth pattern).
* ``furrybunny``: fur grown on a real scanned surface (the Stanford Bunny from pymeshlab's test
  data; ``datasets_synthetic.scanned``, where its licence is noted).

A scene is a :class:`Scene`: the :class:`render.mesh.raster.gl.RasterMesh` that is both rendered and
written as ``gt/mesh.ply``, plus its parameters and statistics (``gt/scene.json``).  The same
name, parameters and seed always give the same mesh, bit for bit.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from capture.rotations import rotation
from datasets_synthetic.geometry import (
    _perpendicular,
    _unit,
    ellipsoid,
    grid_faces,
    lathe,
    merge,
    torus,
    transformed,
    tube_sweep,
)
from datasets_synthetic.scanned import FurryBunnyParams, build_furrybunny
from render.mesh.raster.gl import RasterMesh, face_normals

#: Golden angle (radians): azimuth step of branches and needle whorls.
GOLDEN = np.pi * (3 - np.sqrt(5))


@dataclass(frozen=True)
class Scene:
    """A synthetic object.

    Attributes:
        name: scene name (``furball``, ``plant``, ``torus``).
        seed: the random seed used.
        mesh: the exact geometry with shading attributes (metres, linear albedo).
        params: the generator parameters (JSON-able dict).
        stats: counts (vertices, triangles, strands, needles, ...).
    """

    name: str
    seed: int
    mesh: RasterMesh
    params: dict = field(default_factory=dict)
    stats: dict = field(default_factory=dict)

    @property
    def bounds(self) -> np.ndarray:
        """(2, 3) float64 tight axis-aligned bounds of the geometry."""
        return self.mesh.bounds


# ------------------------------------------------------------------------------------ furball
@dataclass(frozen=True)
class FurballParams:
    """Parameters of the fur ball (lengths in metres)."""

    body_axes: tuple[float, float, float] = (0.075, 0.062, 0.052)
    """Semi-axes of the ellipsoidal body."""
    strands: int = 20000
    """Number of strands (thin tubes); 20,000 like the path-traced evaluation fur ball (issue 11)."""
    length: float = 0.030
    """Mean strand length."""
    length_jitter: float = 0.3
    """Relative uniform jitter of the strand length."""
    root_radius: float = 0.00045
    """Tube radius at the root."""
    tip_radius: float = 0.00012
    """Tube radius at the tip (linear taper)."""
    sides: int = 3
    """Sides of each tube's cross-section."""
    segments: int = 8
    """Segments along each strand."""
    comb: float = 1.6
    """Weight of the downward combing direction in the root direction (0 = along the normal)."""
    gravity: float = 1.0
    """Droop: weight of -z added to the direction at the tip (grows linearly from the root)."""
    curl: float = 0.3
    """Amplitude of the helical curl (weight of the rotating perpendicular)."""
    curl_turns: float = 0.8
    """Turns of the curl helix over a strand."""
    root_occlusion: float = 0.15
    """Ambient visibility at the root (1 at the tip): attenuation by strand depth."""
    body_occlusion: float = 0.1
    """Ambient visibility of the body skin under the fur."""
    specular: float = 0.08
    """Specular strength of the strands (Kajiya-Kay lobe)."""
    patches: int = 0
    """Dark and light melanin patches over the coat (``fur_variants.melanin_patches``; 0 = none)."""
    coat: str = "tabby"
    """Coat colour: ``tabby`` (stripes and a cream belly) or ``uniform`` (one brown coat, the same
    from every side at coarse scale: ``fur_variants.uniform_coat``)."""


def _sample_ellipsoid(rng, axes: np.ndarray, n: int) -> np.ndarray:
    """n points uniformly distributed by area on the ellipsoid (rejection sampling)."""
    out = []
    while sum(len(o) for o in out) < n:
        u = _unit(rng.normal(size=(2 * n, 3)))
        # area element of x = a*u relative to the unit sphere: prod(a) * |u / a|
        w = np.linalg.norm(u / axes, axis=1)
        keep = rng.uniform(size=len(u)) * (1 / axes.min()) < w
        out.append(u[keep] * axes)
    return np.concatenate(out)[:n]


def _coat_colour(rng, roots: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """(S, 3) linear albedo: ginger tabby stripes across the back, cream belly, per-strand jitter."""
    dark = np.array([0.06, 0.028, 0.012])
    ginger = np.array([0.50, 0.21, 0.065])
    cream = np.array([0.72, 0.58, 0.40])
    q = roots / axes
    az = np.arctan2(q[:, 1], q[:, 2] + 1e-9)
    stripe = 0.5 + 0.5 * np.sin(2 * np.pi * q[:, 0] * 2.2 + 1.2 * np.sin(2 * az))
    stripe = np.clip((stripe - 0.55) * 4.0, 0, 1)
    col = ginger * (1 - stripe[:, None]) + dark * stripe[:, None]
    belly = np.clip((-q[:, 2] - 0.35) * 3.0, 0, 1)[:, None]
    col = col * (1 - belly) + cream * belly
    return col * rng.uniform(0.75, 1.2, size=(len(roots), 1))


def build_furball(seed: int = 0, p: FurballParams = FurballParams()) -> Scene:
    rng = np.random.default_rng(seed)
    axes = np.asarray(p.body_axes, np.float64)
    S, P = int(p.strands), int(p.segments) + 1
    surf = _sample_ellipsoid(rng, axes, S)
    n = _unit(surf / axes**2)
    down = np.array([0.0, 0.0, -1.0])
    flow = down - (n @ down)[:, None] * n
    small = np.linalg.norm(flow, axis=1) < 1e-3
    flow[small] = _perpendicular(n[small])
    flow = _unit(flow)
    d0 = _unit(n + p.comb * flow + 0.25 * rng.normal(size=(S, 3)))
    e1 = _perpendicular(d0)
    e2 = np.cross(d0, e1)
    length = p.length * (1 + p.length_jitter * rng.uniform(-1, 1, S))
    s = np.linspace(0, 1, P)
    phase = rng.uniform(0, 2 * np.pi, S)[:, None]
    ang = 2 * np.pi * p.curl_turns * s[None] + phase
    curl = p.curl * (np.cos(ang)[..., None] * e1[:, None] + np.sin(ang)[..., None] * e2[:, None])
    dirs = _unit(d0[:, None] + p.gravity * s[None, :, None] * down + curl * s[None, :, None] ** 0.5)
    step = (length / (P - 1))[:, None, None]
    root = surf - 0.3 * p.root_radius * 2 * n  # start just below the skin
    paths = root[:, None] + np.concatenate([np.zeros((S, 1, 3)), np.cumsum(dirs[:, :-1] * step, axis=1)], axis=1)
    # strands never pass through the body: push points radially out of the ellipsoid
    f = np.sum((paths / axes) ** 2, axis=-1)
    inside = (f < 1.0) & (np.arange(P) > 1)[None]
    scale = np.where(inside, 1.0 / np.sqrt(np.maximum(f, 1e-12)) * (1 + 1e-3), 1.0)
    paths = paths * scale[..., None]
    radii = p.root_radius + (p.tip_radius - p.root_radius) * s[None] * np.ones((S, 1))
    base = _coat_colour(rng, surf, axes)
    if p.coat == "uniform":
        from datasets_synthetic.fur_variants import uniform_coat

        base = uniform_coat(seed, len(surf))
    elif p.coat != "tabby":
        raise ValueError(f"FurballParams.coat must be 'tabby' or 'uniform', got {p.coat!r}")
    if p.patches:
        from datasets_synthetic.fur_variants import melanin_patches

        base = melanin_patches(seed, surf, axes, base, p.patches)
    shade = 0.65 + 0.5 * s  # roots darker, tips lighter
    colors = np.clip(base[:, None] * shade[None, :, None], 0, 0.95)
    occl = p.root_occlusion + (1 - p.root_occlusion) * s ** 0.8
    fur = tube_sweep(paths, radii, p.sides, colors, np.broadcast_to(occl, (S, P)), p.specular)
    skin = ellipsoid(axes * 0.999, 40, 80, (0.05, 0.025, 0.015), occlusion=p.body_occlusion)
    mesh = merge([skin, fur])
    stats = {"strands": S, "segments": p.segments, "vertices": len(mesh.vertices), "triangles": len(mesh.faces),
             "strand_length_mean_m": float(length.mean())}
    return Scene("furball", seed, mesh, asdict(p), stats)


# -------------------------------------------------------------------------------------- plant
@dataclass(frozen=True)
class PlantParams:
    """Parameters of the pot plant (lengths in metres)."""

    pot_radius_bottom: float = 0.042
    """Outer radius of the pot at its foot."""
    pot_radius_top: float = 0.056
    """Outer radius of the pot below the rim."""
    pot_height: float = 0.075
    """Height of the pot."""
    stem_height: float = 0.20
    """Height of the stem above the soil."""
    stem_radius: float = 0.0032
    """Stem radius at the soil (tapers to 40% at the top)."""
    branches: int = 20
    """Number of needle-bearing branches."""
    branch_length: tuple[float, float] = (0.06, 0.11)
    """Range of branch lengths."""
    needle_spacing: float = 0.00115
    """Distance between needle whorls along a branch (with 20 branches and 6 needles a whorl about
    6,100-6,300 needles, like the 6,400 needle curves of the path-traced evaluation conifer)."""
    needles_per_whorl: int = 6
    """Needles in one whorl."""
    needle_length: tuple[float, float] = (0.010, 0.017)
    """Range of needle lengths."""
    needle_radius: float = 0.0004
    """Needle radius at its base (tapers to 30%)."""
    leaves: int = 5
    """Number of flat leaves on petioles low on the stem."""
    leaf_length: tuple[float, float] = (0.04, 0.055)
    """Range of leaf blade lengths (width is 0.42 of the length)."""


def _curve_path(start, direction, bend_to, length, n, bend):
    """A polyline of n points from ``start`` leaving along ``direction`` and turning towards
    ``bend_to`` by the angle ``bend`` (radians) over its ``length``."""
    d0 = _unit(np.asarray(direction, float))
    b = np.asarray(bend_to, float)
    b = _unit(b - (b @ d0) * d0)
    s = np.linspace(0, 1, n)
    dirs = np.cos(bend * s)[:, None] * d0 + np.sin(bend * s)[:, None] * b
    steps = dirs[:-1] * (length / (n - 1))
    return np.asarray(start, float) + np.concatenate([np.zeros((1, 3)), np.cumsum(steps, axis=0)])


def _vertex_normals(verts, faces):
    n = np.zeros_like(verts, dtype=np.float64)
    fn = face_normals(verts, faces) * 1.0
    for k in range(3):
        np.add.at(n, faces[:, k], fn)
    return _unit(n)


def _leaf(rng, base, direction, length):
    """A two-sided leaf blade (grid 12 x 7) with a folded midrib and droop, plus its petiole."""
    d = _unit(np.asarray(direction, float))
    side = _unit(np.cross([0, 0, 1.0], d))
    up = np.cross(d, side)
    ns, nt = 12, 7
    s, t = np.meshgrid(np.linspace(0, 1, ns), np.linspace(-1, 1, nt), indexing="ij")
    width = 0.42 * length * np.sin(np.pi * np.clip(s, 0, 1)) ** 0.7 * (1 - 0.25 * s)
    pts = (base + (s * length)[..., None] * d + (t * width / 2)[..., None] * side
           + (np.abs(t) * width / 2 * 0.35)[..., None] * up - (0.35 * length * s**2)[..., None] * up)
    verts = pts.reshape(-1, 3)
    faces = grid_faces(ns, nt)
    green = np.array([0.045, 0.17, 0.025]) * rng.uniform(0.85, 1.15)
    rib = np.exp(-(t / 0.12) ** 2)[..., None]
    col = green * (1 - 0.4 * rib) + np.array([0.12, 0.28, 0.07]) * 0.4 * rib
    V = len(verts)
    return RasterMesh(verts, faces, col.reshape(-1, 3), normals=_vertex_normals(verts, faces),
                      occlusion=np.full(V, 0.8), specular=np.full(V, 0.3))


#: Plant bark colour (linear RGB): stem, branches (x 1.2) and petioles (x 1.4).
PLANT_BARK = np.array([0.10, 0.075, 0.03])
#: Needle colours (linear RGB) at the base and the tip of a branch.
NEEDLE_GREEN = np.array([0.025, 0.09, 0.018])
NEEDLE_TIP_GREEN = np.array([0.07, 0.2, 0.04])


def _plant_pot(p: PlantParams, rng) -> tuple[list, float]:
    """([terracotta pot, soil disc] meshes, soil height z)."""
    z0 = 0.0
    rb, rt, h = p.pot_radius_bottom, p.pot_radius_top, p.pot_height
    lip = 0.004
    soil_z = z0 + h - 0.010
    prof = np.array([[0.0, z0], [rb * 0.6, z0], [rb, z0], [rb, z0 + 0.004], [rt, z0 + h - 0.014],
                     [rt + lip, z0 + h - 0.013], [rt + lip, z0 + h], [rt - 0.002, z0 + h], [rt - 0.004, soil_z]])
    terracotta = np.array([0.42, 0.15, 0.07])
    pot_cols = np.tile(terracotta, (len(prof), 1)) * np.array([0.8, 0.9, 1, 1, 1, 1.05, 1.05, 1.0, 0.6])[:, None]
    pot = lathe(prof, 96, pot_cols, occlusion=np.array([1, 1, 1, 1, 1, 1, 1, 0.9, 0.5]), specular=0.05)
    soil_r = np.linspace(rt - 0.004, 0.0, 12)
    soil = lathe(np.stack([soil_r, np.full_like(soil_r, soil_z)], -1), 96, np.tile([0.05, 0.035, 0.022], (12, 1)),
                 occlusion=np.full(12, 0.6))
    soil_col = soil.colors * rng.uniform(0.6, 1.4, size=(len(soil.colors), 1))
    soil = RasterMesh(soil.vertices, soil.faces, soil_col, soil.normals, None, soil.occlusion, soil.specular)
    return [pot, soil], soil_z


def _add_needles(needles: dict, path: np.ndarray, start_frac: float, p: PlantParams, rng) -> None:
    """Append whorls of needles along ``path`` (from ``start_frac`` of its length) to the
    ``needles`` lists (paths, radii, colours): younger (further out) = shorter and lighter."""
    seg = np.linalg.norm(np.diff(path, axis=0), axis=1)
    arc = np.concatenate([[0], np.cumsum(seg)])
    L = arc[-1]
    pos = np.arange(start_frac * L, L, p.needle_spacing)
    for k, a in enumerate(pos):
        i = int(np.clip(np.searchsorted(arc, a), 1, len(path) - 1))
        f = (a - arc[i - 1]) / max(arc[i] - arc[i - 1], 1e-12)
        c = path[i - 1] * (1 - f) + path[i] * f
        T = _unit(path[i] - path[i - 1])
        N = _perpendicular(T)
        B = np.cross(T, N)
        young = a / L
        for w in range(p.needles_per_whorl):
            psi = 2 * np.pi * w / p.needles_per_whorl + k * GOLDEN + rng.normal(0, 0.15)
            alpha = np.radians(rng.uniform(45, 65))
            nd = np.cos(alpha) * T + np.sin(alpha) * (np.cos(psi) * N + np.sin(psi) * B)
            ln = rng.uniform(*p.needle_length) * (0.7 + 0.3 * (1 - young))
            needles["paths"].append(_curve_path(c, nd, [0, 0, -1.0], ln, 4, 0.25))
            needles["radii"].append(p.needle_radius * np.linspace(1.0, 0.3, 4))
            needles["colours"].append((NEEDLE_GREEN * (1 - young) + NEEDLE_TIP_GREEN * young) * rng.uniform(0.8, 1.2))


def _plant_branches(stem_path: np.ndarray, soil_z: float, p: PlantParams, rng, needles: dict) -> list:
    """Branch tubes in a golden-angle spiral up the stem (shorter higher up), their needles and
    the leader's added to ``needles``."""
    parts = []
    z_lo, z_hi = soil_z + 0.3 * p.stem_height, soil_z + 0.93 * p.stem_height
    n_b = int(p.branches)
    for b in range(n_b):
        zb = z_lo + (z_hi - z_lo) * (b + rng.uniform(0.1, 0.9)) / n_b
        i = int(np.clip(np.searchsorted(stem_path[:, 2], zb), 1, len(stem_path) - 1))
        start = stem_path[i]
        az = b * GOLDEN + rng.normal(0, 0.2)
        el = np.radians(rng.uniform(15, 40))
        out = np.array([np.cos(az) * np.cos(el), np.sin(az) * np.cos(el), np.sin(el)])
        ln = rng.uniform(*p.branch_length) * (1.0 - 0.45 * (zb - z_lo) / (z_hi - z_lo))
        path = _curve_path(start, out, [0, 0, 1.0], ln, 10, np.radians(rng.uniform(15, 35)))
        rad = p.stem_radius * 0.45 * np.linspace(1.0, 0.45, 10)
        parts.append(tube_sweep(path[None], rad[None], 6, PLANT_BARK[None] * 1.2, None, 0.05, strand=False))
        _add_needles(needles, path, 0.12, p, rng)
    _add_needles(needles, stem_path[np.searchsorted(stem_path[:, 2], z_hi - 0.02):], 0.0, p, rng)  # the leader
    return parts


def _plant_leaves(stem_path: np.ndarray, soil_z: float, p: PlantParams, rng) -> list:
    """Broad leaves on short petioles low on the stem."""
    parts = []
    for li in range(int(p.leaves)):
        zl = soil_z + p.stem_height * (0.08 + 0.28 * li / max(p.leaves - 1, 1))
        i = int(np.clip(np.searchsorted(stem_path[:, 2], zl), 1, len(stem_path) - 1))
        az = li * 2.4 + 0.7 + rng.normal(0, 0.2)
        out = np.array([np.cos(az), np.sin(az), 0.55])
        petiole = _curve_path(stem_path[i], out, [0, 0, -1.0], 0.012, 4, 0.2)
        parts.append(tube_sweep(petiole[None], np.full((1, 4), 0.0011), 5, PLANT_BARK[None] * 1.4, None, 0.05,
                                strand=False))
        parts.append(_leaf(rng, petiole[-1], out * np.array([1, 1, 0.4]), rng.uniform(*p.leaf_length)))
    return parts


def build_plant(seed: int = 0, p: PlantParams = PlantParams()) -> Scene:
    rng = np.random.default_rng(seed)
    parts, soil_z = _plant_pot(p, rng)
    # stem: a gently curved tapered tube
    stem_path = _curve_path([0, 0, soil_z - 0.005], [0.05, 0.02, 1.0], [1.0, 0.3, 0], p.stem_height + 0.005, 16, 0.15)
    sr = p.stem_radius * np.linspace(1.0, 0.4, 16)
    parts.append(tube_sweep(stem_path[None], sr[None], 8, PLANT_BARK[None], None, 0.05, strand=False))
    needles = {"paths": [], "radii": [], "colours": []}
    parts += _plant_branches(stem_path, soil_z, p, rng, needles)
    parts += _plant_leaves(stem_path, soil_z, p, rng)
    parts.append(tube_sweep(np.array(needles["paths"]), np.array(needles["radii"]), 3, np.array(needles["colours"]),
                            None, 0.04, strand=True))
    mesh = merge(parts)
    b = mesh.bounds
    centre = 0.5 * (b[0] + b[1])
    mesh = transformed(mesh, np.eye(3), -centre)
    stats = {"branches": int(p.branches), "needles": len(needles["paths"]), "leaves": int(p.leaves),
             "vertices": len(mesh.vertices), "triangles": len(mesh.faces)}
    return Scene("plant", seed, mesh, {**asdict(p), "centre_offset_m": (-centre).tolist()}, stats)


# -------------------------------------------------------------------------------------- torus
@dataclass(frozen=True)
class TorusParams:
    """Parameters of the smooth control torus (metres, degrees)."""

    major: float = 0.075
    """Radius of the centre circle."""
    minor: float = 0.028
    """Radius of the tube."""
    tilt_deg: float = 25.0
    """Tilt about the x axis (breaks the rotational symmetry about z)."""
    resolution: tuple[int, int] = (160, 56)
    """Vertices around the major and minor circles."""


def build_torus(seed: int = 0, p: TorusParams = TorusParams()) -> Scene:
    rng = np.random.default_rng(seed)
    ph = rng.uniform(0, 2 * np.pi, 3)
    c1, c2 = np.array([0.55, 0.25, 0.08]), np.array([0.08, 0.22, 0.45])

    def colour(u, v):
        t = 0.5 + 0.5 * np.sin(5 * u + ph[0]) * np.cos(2 * v + ph[1])
        t2 = 0.5 + 0.5 * np.sin(13 * u + 3 * v + ph[2])
        return (c1 * t[:, None] + c2 * (1 - t[:, None])) * (0.75 + 0.25 * t2[:, None])

    m = torus(p.major, p.minor, *p.resolution, colour, specular=0.2)
    m = transformed(m, rotation([1, 0, 0], np.radians(p.tilt_deg)), np.zeros(3))
    return Scene("torus", seed, m, asdict(p), {"vertices": len(m.vertices), "triangles": len(m.faces)})


#: Scene name -> (builder(seed, params), parameter dataclass).
SCENES = {"furball": (build_furball, FurballParams), "plant": (build_plant, PlantParams),
          "torus": (build_torus, TorusParams), "furrybunny": (build_furrybunny, FurryBunnyParams)}


def build_scene(name: str, seed: int = 0, **overrides) -> Scene:
    """Build a named scene; ``overrides`` replace fields of its parameter dataclass (e.g.
    ``strands=5000`` for the furball).  Unknown names / fields raise ValueError."""
    if name not in SCENES:
        raise ValueError(f"unknown scene {name!r}: choose one of {', '.join(SCENES)}")
    builder, params = SCENES[name]
    fields = set(params.__dataclass_fields__)
    bad = sorted(set(overrides) - fields)
    if bad:
        raise ValueError(f"scene {name!r} has no parameter {', '.join(bad)} (parameters: {', '.join(sorted(fields))})")
    return builder(int(seed), params(**overrides))

"""The path-traced hard cases' objects as round curves and spheres (numpy only; world metres, +z up).

Written for this generator, not shared with ``datasets_synthetic.scenes``: the point of the hard
cases is a second, independent path from geometry to pixels.

* :func:`build_conifer`: a conical tree of a tapered trunk, tiers of drooping branches with side
  twigs, and thousands of straight needles far thinner than a pixel (radius 0.14 mm tapering to 0.06 mm:
  0.15-0.37 px at 640x480 and 0.56 m), so most of the crown's pixels are partial.
* :func:`build_furball`: a sphere carrying one uniform coat of smooth strands (roots uniform on
  the sphere, every strand drooping the same way, melanin jittered per strand in a few groups), so it
  looks nearly the same from every side; the body under the coat is a dark diffuse sphere.

Materials are Mitsuba BSDF dictionaries (JSON-able), looked up by name from each part.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

#: Golden angle (radians): the azimuth step of branches and needles.
GOLDEN = np.pi * (3.0 - np.sqrt(5.0))
#: Curve bases (Mitsuba shapes ``linearcurve`` and ``bsplinecurve``).
BASES = ("linear", "bspline")


@dataclass(frozen=True)
class Curves:
    """Round curves of one material.

    points: (P, 3) float64 control points (metres); radii: (P,) float64 radius at each (metres);
    counts: (C,) int control points of each curve, in order (sum = P, each >= 2, >= 4 for bspline);
    basis: "linear" (a polyline of round cones) or "bspline" (uniform cubic B-spline, not through its
    control points); material: a key of the object's materials.
    """

    points: np.ndarray
    radii: np.ndarray
    counts: np.ndarray
    basis: str
    material: str

    def __post_init__(self) -> None:
        p, r, c = np.asarray(self.points, float), np.asarray(self.radii, float), np.asarray(self.counts, int)
        if p.ndim != 2 or p.shape[1] != 3 or r.shape != (len(p),) or int(c.sum()) != len(p):
            raise ValueError(f"curves {self.material!r}: points (P, 3), radii (P,) and counts summing to P, got "
                             f"{p.shape}, {r.shape}, sum {int(c.sum())}")
        if self.basis not in BASES or (c < (2 if self.basis == "linear" else 4)).any() or not (r > 0).all():
            raise ValueError(f"curves {self.material!r}: basis in {BASES}, enough points per curve, radii > 0")
        for k, v in (("points", p), ("radii", r), ("counts", c)):
            object.__setattr__(self, k, v)

    def polylines(self, samples: int = 4) -> list[tuple[np.ndarray, np.ndarray]]:
        """[(points (n, 3), radii (n,))] of every curve: the control polyline (linear) or the B-spline
        evaluated at ``samples`` points per segment (for the ground-truth mesh)."""
        out, start = [], 0
        for n in self.counts:
            ctrl = np.column_stack([self.points[start:start + n], self.radii[start:start + n]])
            start += n
            if self.basis == "bspline":
                ctrl = _bspline_eval(ctrl, samples)
            out.append((ctrl[:, :3], ctrl[:, 3]))
        return out


def _bspline_eval(ctrl: np.ndarray, samples: int) -> np.ndarray:
    """Uniform cubic B-spline through (n, k) control rows, ``samples`` points per segment + the end."""
    t = np.linspace(0.0, 1.0, samples, endpoint=False)
    basis = np.stack([(1 - t) ** 3, 3 * t**3 - 6 * t**2 + 4, -3 * t**3 + 3 * t**2 + 3 * t + 1, t**3], 1) / 6.0
    rows = [basis @ ctrl[i:i + 4] for i in range(len(ctrl) - 3)]
    end = np.array([[0.0, 1.0, 4.0, 1.0]]) / 6.0 @ ctrl[-4:]
    return np.concatenate(rows + [end])


@dataclass(frozen=True)
class Sphere:
    """A sphere of one material: centre (3,) and radius in metres."""

    centre: tuple[float, float, float]
    radius: float
    material: str


@dataclass(frozen=True)
class TriangleMesh:
    """A closed triangle mesh of one material: vertices (V, 3) float64 metres, faces (F, 3) int indices."""

    vertices: np.ndarray
    faces: np.ndarray
    material: str

    def __post_init__(self) -> None:
        v, f = np.asarray(self.vertices, np.float64), np.asarray(self.faces, np.int64)
        if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
            raise ValueError(f"mesh {self.material!r}: vertices (V, 3) and faces (F, 3), got {v.shape}, {f.shape}")
        if f.min() < 0 or f.max() >= len(v):
            raise ValueError(f"mesh {self.material!r}: face indices outside 0..{len(v) - 1}")
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "faces", f)


@dataclass(frozen=True)
class PathObject:
    """An object of the hard cases: its parts, their materials, and what built it."""

    name: str
    parts: tuple
    """Curves, Sphere and TriangleMesh parts."""
    materials: dict
    """Material name -> Mitsuba BSDF dictionary."""
    params: dict = field(default_factory=dict)
    """The builder's parameters (JSON-able)."""
    stats: dict = field(default_factory=dict)
    """Counts (curves per kind, control points)."""

    @property
    def bounds(self) -> np.ndarray:
        """(2, 3) axis-aligned box of every part (curves padded by their radii)."""
        lo, hi = [], []
        for p in self.parts:
            if isinstance(p, Sphere):
                c = np.asarray(p.centre, float)
                lo.append(c - p.radius)
                hi.append(c + p.radius)
            elif isinstance(p, TriangleMesh):
                lo.append(p.vertices.min(0))
                hi.append(p.vertices.max(0))
            else:
                lo.append((p.points - p.radii[:, None]).min(0))
                hi.append((p.points + p.radii[:, None]).max(0))
        return np.stack([np.min(lo, 0), np.max(hi, 0)])

    @property
    def radius(self) -> float:
        """Largest distance of the object's surface from the origin (the rig's bounding radius)."""
        r = [np.linalg.norm(p.centre) + p.radius if isinstance(p, Sphere)
             else float(np.linalg.norm(p.vertices, axis=1).max()) if isinstance(p, TriangleMesh)
             else float((np.linalg.norm(p.points, axis=1) + p.radii).max()) for p in self.parts]
        return float(max(r))


def diffuse(rgb) -> dict:
    """A Lambertian Mitsuba BSDF of linear albedo ``rgb``."""
    return {"type": "diffuse", "reflectance": {"type": "rgb", "value": [float(c) for c in rgb]}}


# --------------------------------------------------------------------------- conifer
@dataclass(frozen=True)
class ConiferParams:
    """A conical conifer (metres)."""

    height: float = 0.26
    """Trunk height (the tree's top)."""
    trunk_radius: tuple[float, float] = (0.0032, 0.0006)
    """Trunk radius at the base and at the top."""
    branches: int = 46
    """Branches in a golden-angle spiral up the trunk."""
    branch_span: tuple[float, float] = (0.12, 0.93)
    """Heights of the lowest and the highest branch, fractions of ``height``."""
    branch_length: tuple[float, float] = (0.105, 0.014)
    """Length of the lowest and of the highest branch (linear in height between)."""
    branch_radius: float = 0.0009
    """Branch radius at the trunk (tapers to 35 %)."""
    branch_tilt_deg: float = 12.0
    """Upward tilt of a branch where it leaves the trunk (it droops by ``droop`` of its length)."""
    droop: float = 0.22
    """Sag of a branch's tip below its straight line, as a fraction of its length."""
    twigs: int = 3
    """Side twigs on each branch longer than 4 cm (alternating sides)."""
    needle_spacing: float = 0.0015
    """Distance between needle nodes along branches, twigs and the trunk's top."""
    needles_per_node: int = 2
    """Needles at every node (turning by the golden angle from node to node)."""
    needle_length: tuple[float, float] = (0.0075, 0.0125)
    """Range of needle lengths."""
    needle_radius: float = 0.00014
    """Needle radius at its base (tapers to 45 % at the tip): 0.28 mm wide at the base, about a third of
    a pixel at 640x480 and the rig's 0.56 m."""
    needle_angle_deg: float = 50.0
    """Angle between a needle and its branch."""


#: Needle materials (linear albedo): old dark needles to young light ones; each needle draws one.
NEEDLE_ALBEDO = ((0.030, 0.085, 0.025), (0.040, 0.110, 0.030), (0.055, 0.140, 0.035), (0.080, 0.180, 0.050))
#: Bark albedo (trunk, branches and twigs).
BARK_ALBEDO = (0.11, 0.065, 0.035)


def _frame(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors perpendicular to unit ``d`` and to each other."""
    a = np.array([0.0, 0.0, 1.0]) if abs(d[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    u = np.cross(d, a)
    u /= np.linalg.norm(u)
    return u, np.cross(d, u)


def _branch_path(start, azimuth: float, length: float, tilt_deg: float, droop: float, n: int = 6) -> np.ndarray:
    """(n, 3) polyline of a branch leaving ``start`` at ``azimuth``, tilted up, sagging by ``droop``."""
    t = np.linspace(0.0, 1.0, n)
    h = np.array([np.cos(azimuth), np.sin(azimuth), 0.0])
    d = h * np.cos(np.radians(tilt_deg)) + np.array([0, 0, np.sin(np.radians(tilt_deg))])
    return np.asarray(start, float) + np.outer(t * length, d) - np.outer(droop * length * t**2, [0, 0, 1.0])


def _needles_along(path: np.ndarray, p: ConiferParams, rng, out: dict, start_frac: float = 0.08) -> None:
    """Append needles along polyline ``path`` to ``out[group] -> list of (2, 3) needles``."""
    seg = np.linalg.norm(np.diff(path, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    for k, s in enumerate(np.arange(start_frac * cum[-1], cum[-1], p.needle_spacing)):
        i = min(int(np.searchsorted(cum, s, side="right")) - 1, len(seg) - 1)
        f = (s - cum[i]) / max(seg[i], 1e-12)
        base, d = path[i] + f * (path[i + 1] - path[i]), (path[i + 1] - path[i]) / max(seg[i], 1e-12)
        u, v = _frame(d)
        young = s / cum[-1]
        for j in range(p.needles_per_node):
            psi = k * GOLDEN + 2 * np.pi * j / p.needles_per_node + rng.normal(0, 0.2)
            a = np.radians(p.needle_angle_deg + rng.normal(0, 6))
            nd = np.cos(a) * d + np.sin(a) * (np.cos(psi) * u + np.sin(psi) * v) + [0, 0, 0.15]
            nd /= np.linalg.norm(nd)
            length = rng.uniform(*p.needle_length) * (1.0 - 0.3 * young)
            group = int(np.clip(young * len(NEEDLE_ALBEDO) + rng.normal(0, 0.7), 0, len(NEEDLE_ALBEDO) - 1))
            out.setdefault(group, []).append(np.stack([base, base + length * nd]))


def build_conifer(seed: int = 0, p: ConiferParams = ConiferParams()) -> PathObject:
    """The conifer of the hard cases (module docstring): the trunk on the z axis from -height/2 to height/2
    (the rig looks at the origin)."""
    rng = np.random.default_rng([int(seed), 11])
    trunk = np.column_stack([rng.normal(0, 0.0008, 12) * np.linspace(0, 1, 12) ** 2,
                             rng.normal(0, 0.0008, 12) * np.linspace(0, 1, 12) ** 2,
                             np.linspace(-p.height / 2, p.height / 2, 12)])
    wood = [(trunk, np.linspace(*p.trunk_radius, 12))]
    needles: dict = {}
    lo, hi = p.branch_span
    for b in range(p.branches):
        f = lo + (hi - lo) * b / max(p.branches - 1, 1)
        z = (f - 0.5) * p.height
        length = (p.branch_length[0] + (p.branch_length[1] - p.branch_length[0]) * (f - lo) / (hi - lo)) \
            * rng.uniform(0.85, 1.15)
        start = trunk[min(int(np.searchsorted(trunk[:, 2], z)), 11)].copy()
        start[2] = z
        path = _branch_path(start, b * GOLDEN + rng.normal(0, 0.1), length, p.branch_tilt_deg + rng.normal(0, 4),
                            p.droop)
        wood.append((path, p.branch_radius * np.linspace(1.0, 0.35, len(path))))
        _needles_along(path, p, rng, needles)
        if length > 0.04:
            for t in range(p.twigs):
                at = path[1 + t] if 1 + t < len(path) - 1 else path[-2]
                az = b * GOLDEN + (1 if t % 2 else -1) * np.radians(rng.uniform(40, 60))
                twig = _branch_path(at, az, 0.4 * length * (1 - 0.2 * t), 5.0, 0.1, 4)
                wood.append((twig, 0.5 * p.branch_radius * np.linspace(1.0, 0.4, 4)))
                _needles_along(twig, p, rng, needles, 0.15)
    _needles_along(trunk[-4:], p, rng, needles, 0.0)  # the leader
    parts = [_curves(wood, "bark")]
    for g in sorted(needles):
        segs = needles[g]
        radii = np.tile([p.needle_radius, 0.45 * p.needle_radius], len(segs))
        parts.append(Curves(np.concatenate(segs), radii, np.full(len(segs), 2), "linear", f"needle{g}"))
    materials = {"bark": diffuse(BARK_ALBEDO), **{f"needle{g}": diffuse(NEEDLE_ALBEDO[g]) for g in needles}}
    n_needles = int(sum(len(v) for v in needles.values()))
    return PathObject("conifer", tuple(parts), materials, _params(p),
                      {"needles": n_needles, "wood_curves": len(wood), "branches": p.branches})


def _curves(polys: list, material: str) -> Curves:
    return Curves(np.concatenate([q for q, _ in polys]), np.concatenate([r for _, r in polys]),
                  np.array([len(q) for q, _ in polys]), "linear", material)


def _params(p) -> dict:
    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(p).items()}


# --------------------------------------------------------------------------- fur ball
@dataclass(frozen=True)
class FurballParams:
    """A fur ball of one uniform coat (metres)."""

    body_radius: float = 0.045
    """Radius of the skin sphere (centred on the origin)."""
    strands: int = 20000
    """Strands, roots uniform on the sphere."""
    length: tuple[float, float] = (0.018, 0.026)
    """Range of strand lengths."""
    root_radius: float = 0.0001
    """Strand radius at the root (tapers to 35 % at the tip)."""
    control_points: int = 5
    """B-spline control points per strand."""
    droop: float = 0.5
    """How far a strand bends toward -z (gravity), fraction of its length at the tip; the same
    everywhere, so the coat keeps the sphere's symmetry about +z."""
    jitter_deg: float = 15.0
    """Random tilt of each strand's direction from the normal (fine texture, no patches)."""
    eumelanin: float = 0.4
    """Mitsuba ``hair`` BSDF eumelanin (brown)."""
    pheomelanin: float = 0.25
    """Mitsuba ``hair`` BSDF pheomelanin (red-brown)."""
    melanin_jitter: float = 0.08
    """Relative spread of the melanin between the strand groups."""
    groups: int = 4
    """Strand groups (each its own melanin), strands assigned at random: per-strand variation."""
    basis: str = "linear"
    """Curve shape handed to Mitsuba: "linear" (the B-spline of the control points evaluated at
    ``samples_per_span`` points per span, a polyline of round cones) or "bspline".  Mitsuba 3.9.1's
    ``hair`` BSDF on its ``bsplinecurve`` crashed the process (segmentation fault, from max_depth 2,
    also under a constant map; a diffuse coat and the linear curves render) on a fur-ball view here."""
    samples_per_span: int = 3
    """Points per B-spline span of the "linear" strands."""


#: Albedo of the skin under the coat.
SKIN_ALBEDO = (0.10, 0.06, 0.035)


def build_furball(seed: int = 0, p: FurballParams = FurballParams()) -> PathObject:
    """The uniform fur ball (module docstring)."""
    rng = np.random.default_rng([int(seed), 12])
    n = rng.normal(size=(p.strands, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    centre = np.zeros(3)
    tilt = rng.normal(size=(p.strands, 3)) * np.radians(p.jitter_deg) / np.sqrt(3)
    d = n + tilt - (tilt * n).sum(1, keepdims=True) * n
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    length = rng.uniform(*p.length, p.strands)[:, None]
    k = p.control_points
    t = np.linspace(0.0, 1.0, k)[None, :, None]
    root = centre + (p.body_radius - 0.2 * p.root_radius) * n
    pts = root[:, None] + length[:, None] * (t * d[:, None] - p.droop * t**2 * np.array([0, 0, 1.0]))
    # keep each strand's length about the same after the droop: rescale the polyline
    seg = np.linalg.norm(np.diff(pts, axis=1), axis=2).sum(1, keepdims=True)
    pts = root[:, None] + (pts - root[:, None]) * (length / seg)[:, None]
    radii = np.tile(p.root_radius * np.linspace(1.0, 0.35, k), (p.strands, 1))
    group = rng.integers(0, p.groups, p.strands)
    parts, materials = [Sphere(tuple(centre), p.body_radius, "skin")], {"skin": diffuse(SKIN_ALBEDO)}
    spread = np.linspace(-1.0, 1.0, p.groups) * p.melanin_jitter if p.groups > 1 else np.zeros(1)
    if p.basis == "linear":  # the same smooth strands as polylines (FurballParams.basis)
        ctrl = np.concatenate([pts, radii[..., None]], axis=2)
        dense = np.stack([_bspline_eval(c, p.samples_per_span) for c in ctrl])
        pts, radii, k = dense[..., :3], dense[..., 3], dense.shape[1]
    elif p.basis != "bspline":
        raise ValueError(f"furball basis must be 'linear' or 'bspline', got {p.basis!r}")
    for g in range(p.groups):
        sel = group == g
        if not sel.any():
            continue
        parts.append(Curves(pts[sel].reshape(-1, 3), radii[sel].reshape(-1), np.full(int(sel.sum()), k), p.basis,
                            f"coat{g}"))
        materials[f"coat{g}"] = {"type": "hair", "eumelanin": p.eumelanin * (1 + spread[g]),
                                 "pheomelanin": p.pheomelanin * (1 + spread[g])}
    return PathObject("furball_uniform", tuple(parts), materials, _params(p), {"strands": int(p.strands)})


def _build_bunny(seed: int, p):
    from datasets_synthetic.pathtraced.bunny import build_bunny

    return build_bunny(seed, p)


def _bunny_params():
    from datasets_synthetic.pathtraced.bunny import BunnyParams

    return BunnyParams


#: Object name -> (builder(seed, params), parameter dataclass, or a function giving it: the bunny's module
#: imports this one).
OBJECTS = {"conifer": (build_conifer, ConiferParams), "furball": (build_furball, FurballParams),
           "furrybunny": (_build_bunny, _bunny_params)}


def build_object(name: str, seed: int = 0, **overrides) -> PathObject:
    """A named object with parameter ``overrides`` (ValueError naming the choices)."""
    if name not in OBJECTS:
        raise ValueError(f"unknown object {name!r}: choose one of {', '.join(OBJECTS)}")
    builder, params = OBJECTS[name]
    params = params if isinstance(params, type) else params()
    bad = set(overrides) - set(params.__dataclass_fields__)
    if bad:
        raise ValueError(f"{name}: unknown parameters {sorted(bad)}; known: {sorted(params.__dataclass_fields__)}")
    return builder(seed, params(**overrides))

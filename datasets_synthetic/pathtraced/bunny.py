"""The furry bunny of the path-traced hard cases: the scanned Stanford Bunny as a triangle mesh of skin
(``datasets_synthetic.scanned.load_bunny``: pymeshlab's test data, +z up, facing -x), with hair-BSDF strands
grown on it by ``datasets_synthetic.fur`` (roots uniform on the surface, combed from the head to the tail,
drooping and curled, pushed outside the body) as Mitsuba linear curves.

Unlike the fur ball it is not the same from every side: ears, a tail, a belly and concave necks show the room
between parts of the body in some frames and not in others, and its coat has large soft patches of darker and
lighter melanin (the strand groups are assigned by position, not at random).  The strands are as thin as the
fur ball's (0.1 mm at the root, 35 % at the tip), so almost every fur pixel is partial.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from datasets_synthetic.pathtraced.objects import (
    SKIN_ALBEDO,
    Curves,
    PathObject,
    TriangleMesh,
    _params,
    diffuse,
)


@dataclass(frozen=True)
class BunnyParams:
    """The path-traced furry bunny (metres)."""

    size_m: float = 0.16
    """Longest side of the scanned body."""
    strands: int = 30000
    """Strands, roots uniform over the body's area (the fur ball's density is about 20,000 on 0.025 m^2)."""
    length: float = 0.014
    """Mean strand length (jittered by ``datasets_synthetic.fur.FurParams.length_jitter``)."""
    root_radius: float = 0.0001
    """Strand radius at the root (tapers to 35 % at the tip, as the fur ball's)."""
    segments: int = 8
    """Segments of each strand's polyline."""
    eumelanin: float = 0.4
    """Mitsuba ``hair`` BSDF eumelanin of the mid patch (brown)."""
    pheomelanin: float = 0.25
    """Mitsuba ``hair`` BSDF pheomelanin of the mid patch."""
    patch_spread: float = 0.35
    """Relative melanin spread from the lightest to the darkest patch."""
    groups: int = 4
    """Strand groups (each its own melanin), assigned by a smooth random field over the body: patches."""

    def __post_init__(self) -> None:
        if self.strands < 1 or self.segments < 1 or self.groups < 1 or not self.size_m > 0:
            raise ValueError("bunny: strands, segments and groups must be >= 1 and size_m > 0")


def _patches(rng: np.random.Generator, roots: np.ndarray, size: float, groups: int) -> np.ndarray:
    """(S,) group of each root: a few random plane waves over the body, cut into ``groups`` equal shares."""
    q = roots / size
    k = rng.normal(size=(4, 3)) * 9.0
    field = np.sin(q @ k.T + rng.uniform(0, 2 * np.pi, 4)).mean(1)
    edges = np.quantile(field, np.linspace(0, 1, groups + 1)[1:-1])
    return np.searchsorted(edges, field)


def build_bunny(seed: int = 0, p: BunnyParams = BunnyParams()) -> PathObject:
    """The furry bunny (module docstring)."""
    from datasets_synthetic.fur import FurParams, grow_strands, push_outside, sample_surface
    from datasets_synthetic.geometry import _unit
    from datasets_synthetic.scanned import bunny_path, load_bunny

    rng = np.random.default_rng([int(seed), 14])
    v, f, vn = load_bunny(p.size_m)
    fp = FurParams(strands=p.strands, length=p.length, root_radius=p.root_radius,
                   tip_radius=0.35 * p.root_radius, segments=p.segments)
    roots, n, _ = sample_surface(rng, v, f, vn, p.strands)
    comb = np.broadcast_to(_unit(np.array([1.0, 0.0, -0.35])), roots.shape)  # head (-x) to tail (+x)
    paths, length = grow_strands(rng, roots, n, comb, fp)
    paths, pushed = push_outside(paths, v, f)
    P = paths.shape[1]
    radii = np.tile(p.root_radius * np.linspace(1.0, 0.35, P), (len(paths), 1))
    group = _patches(rng, roots, p.size_m, p.groups)
    spread = np.linspace(-0.5, 0.5, p.groups) * p.patch_spread if p.groups > 1 else np.zeros(1)
    parts, materials = [TriangleMesh(v, f, "skin")], {"skin": diffuse(SKIN_ALBEDO)}
    for g in range(p.groups):
        sel = group == g
        if not sel.any():
            continue
        parts.append(Curves(paths[sel].reshape(-1, 3), radii[sel].reshape(-1), np.full(int(sel.sum()), P),
                            "linear", f"coat{g}"))
        materials[f"coat{g}"] = {"type": "hair", "eumelanin": p.eumelanin * (1 + spread[g]),
                                 "pheomelanin": p.pheomelanin * (1 + spread[g])}
    stats = {"strands": int(p.strands), "strand_length_mean_m": float(length.mean()),
             "strand_points_pushed_out": int(pushed), "scanned_mesh": str(bunny_path()),
             "scanned_mesh_vertices": len(v), "scanned_mesh_triangles": len(f)}
    return PathObject("furrybunny", tuple(parts), materials, _params(p), stats)

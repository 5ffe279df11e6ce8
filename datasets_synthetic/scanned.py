"""Fur grown on a real scanned surface: the ``furrybunny`` scene.

The surface is the Stanford Bunny as shipped inside the installed ``pymeshlab`` wheel
(``pymeshlab/tests/sample_meshes/bunny.obj``: 28,088 vertices, 56,172 triangles, watertight, y up,
about 0.62 units across).  It is read from the installed package at run time (nothing is
downloaded and furrow ships no copy of it).

Licence of the mesh: the Stanford Bunny comes from the Stanford 3D Scanning Repository (Greg
Turk and Marc Levoy, 1994; https://graphics.stanford.edu/data/3Dscanrep/), whose terms allow
research and other non-commercial use with acknowledgement of the source; it reaches this machine
inside pymeshlab (GPL-3.0), which bundles it as test data.  furrow uses it to build synthetic test
captures only; anyone redistributing a capture made from it should keep this acknowledgement.

The scene: the bunny turned to +z up (facing -x), scaled to ``size_m`` across and centred, dark
skin, and ``FurParams.strands`` strands grown on it (``datasets_synthetic.fur``) combed from the
head towards the tail, in an agouti coat (dark root, light band, dark tip) with a cream belly and
tail patch, darker ears and large soft patches.
"""

from __future__ import annotations

import importlib.util
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from capture.sampling import points_box
from datasets_synthetic.fur import FurParams, grow_strands, push_outside, sample_surface, strand_tubes
from datasets_synthetic.geometry import _unit, merge
from render.mesh.raster.gl import RasterMesh

#: Where the mesh lies inside the installed pymeshlab package.
BUNNY_PACKAGE = "pymeshlab"
BUNNY_RELPATH = "tests/sample_meshes/bunny.obj"
#: The file's y-up frame -> furrow's +z up: (x, y, z) -> (x, -z, y).
Y_UP_TO_Z_UP = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])


class MeshSourceError(FileNotFoundError):
    """The scanned mesh is not where the installed package should hold it."""


def bunny_path() -> Path:
    """Path of the Stanford Bunny inside the installed pymeshlab (MeshSourceError if absent)."""
    spec = importlib.util.find_spec(BUNNY_PACKAGE)
    if spec is None or not spec.submodule_search_locations:
        raise MeshSourceError(f"the furrybunny scene needs the installed package {BUNNY_PACKAGE!r} "
                              "(pip install pymeshlab): its test data holds the scanned mesh")
    p = Path(list(spec.submodule_search_locations)[0]) / BUNNY_RELPATH
    if not p.is_file():
        raise MeshSourceError(f"{p}: the scanned bunny is missing from the installed {BUNNY_PACKAGE}")
    return p


def load_bunny(size_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(vertices (V, 3) metres, +z up, centred, longest side ``size_m``; faces (F, 3); unit
    vertex normals (V, 3))."""
    import open3d as o3d

    path = bunny_path()
    m = o3d.io.read_triangle_mesh(str(path))
    v = np.asarray(m.vertices, np.float64) @ Y_UP_TO_Z_UP.T
    f = np.asarray(m.triangles, np.int64)
    if len(v) == 0 or len(f) == 0:
        raise MeshSourceError(f"{path}: no triangles read")
    lo, hi = points_box(v)
    v = (v - 0.5 * (lo + hi)) * (size_m / float((hi - lo).max()))
    m.vertices = o3d.utility.Vector3dVector(v)
    m.compute_vertex_normals()
    return v, f, _unit(np.asarray(m.vertex_normals, np.float64))


@dataclass(frozen=True)
class FurryBunnyParams:
    """Parameters of the furry bunny (lengths in metres)."""

    size_m: float = 0.16
    """Longest side of the scanned body (the Stanford Bunny is about 0.155 m in real life)."""
    fur: FurParams = field(default_factory=FurParams)
    """Strand shape (count, length, radii, combing, droop, curl)."""
    strands: int | None = None
    """Shortcut overriding ``fur.strands`` (e.g. ``--strands``)."""
    skin_occlusion: float = 0.1
    """Ambient visibility of the skin under the fur."""


def _coat(rng, roots: np.ndarray, normals: np.ndarray, size: float, P: int) -> np.ndarray:
    """(S, P, 3) linear albedo along each strand."""
    brown = np.array([0.26, 0.16, 0.085])
    dark = np.array([0.035, 0.025, 0.018])
    cream = np.array([0.70, 0.64, 0.52])
    q = roots / size
    # large soft patches: a few random plane waves
    k = rng.normal(size=(4, 3)) * 9.0
    ph = rng.uniform(0, 2 * np.pi, 4)
    patch = np.clip(0.5 + 0.5 * np.sin(q @ k.T + ph).mean(1) * 2.2, 0, 1)[:, None]
    base = brown * (0.7 + 0.6 * patch)
    belly = np.clip((-normals[:, 2] - 0.35) * 2.5, 0, 1)[:, None]
    tail = np.clip((q[:, 0] - 0.40) * 12.0, 0, 1)[:, None]
    ears = np.clip((q[:, 2] - 0.22) * 8.0, 0, 1)[:, None]
    base = base * (1 - ears) + dark * 2.5 * ears
    light = np.maximum(belly, tail)
    base = base * (1 - light) + cream * light
    base = base * rng.uniform(0.8, 1.2, size=(len(roots), 1))
    s = np.linspace(0, 1, P)
    band = 0.55 + 0.9 * np.exp(-((s - 0.7) / 0.15) ** 2) - 0.35 * np.clip((s - 0.85) / 0.15, 0, 1)  # agouti
    col = base[:, None] * band[None, :, None]
    col = col * (1 - light[:, None]) + (cream * rng.uniform(0.9, 1.05, size=(len(roots), 1)))[:, None] * light[:, None]
    return np.clip(col, 0, 0.95)


def build_furrybunny(seed: int = 0, p: FurryBunnyParams = FurryBunnyParams()):
    """The furry bunny scene (module docstring)."""
    from dataclasses import replace

    from datasets_synthetic.scenes import Scene

    fp = p.fur if p.strands is None else replace(p.fur, strands=int(p.strands))
    rng = np.random.default_rng(seed)
    v, f, vn = load_bunny(p.size_m)
    roots, n, _ = sample_surface(rng, v, f, vn, fp.strands)
    comb = np.broadcast_to(_unit(np.array([1.0, 0.0, -0.35])), roots.shape)  # head (-x) to tail (+x)
    paths, length = grow_strands(rng, roots, n, comb, fp)
    paths, pushed = push_outside(paths, v, f)
    colors = _coat(rng, roots, n, p.size_m, fp.segments + 1)
    fur = strand_tubes(paths, colors, fp)
    V = len(v)
    skin = RasterMesh(v, f, np.tile([0.05, 0.032, 0.022], (V, 1)), normals=vn,
                      occlusion=np.full(V, p.skin_occlusion), specular=np.zeros(V))
    mesh = merge([skin, fur])
    stats = {"strands": fp.strands, "segments": fp.segments, "vertices": len(mesh.vertices),
             "triangles": len(mesh.faces), "strand_length_mean_m": float(length.mean()),
             "strand_points_pushed_out": pushed, "scanned_mesh": str(bunny_path()),
             "scanned_mesh_vertices": V, "scanned_mesh_triangles": len(f)}
    params = {**asdict(p), "source": "Stanford Bunny (Stanford 3D Scanning Repository) from pymeshlab's test data"}
    return Scene("furrybunny", seed, mesh, params, stats)

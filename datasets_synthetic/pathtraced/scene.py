"""Mitsuba 3 scenes of the hard cases: the object's curves and spheres, the room as a visible
environment map, an optional table top; the room turned per view for a turntable.

World frame = furrow's object frame (metres, +z up), so the cameras need no conversion beyond
``capture.camera``'s.  The environment map is given in **furrow's layout** (``render.shading.envmap``:
u = 0.5 faces +x, u = 0.25 faces +y, top row +z) and handed to Mitsuba's ``envmap`` emitter, whose own
layout (+y up, u = 0.25 facing +x) is a quarter turn away, with the ``to_world`` that undoes it
(:func:`env_to_world`), resampled to Mitsuba's texel rows (:func:`mitsuba_texels`): a capture's
metadata can therefore name the map with ``convention: furrow`` and be read by ``--env-convention
furrow`` (the default), not ``mitsuba``.  A turntable turns the room (map and table) about +z by the
view's angle; the object never moves, so its curves are built once.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from datasets_synthetic.pathtraced.objects import Curves, PathObject, Sphere, TriangleMesh
from datasets_synthetic.pathtraced.runtime import load_mitsuba
from render.shading.envmap import ENV_CONVENTIONS, EnvMap, dir_to_uv, sample_equirect

#: Mitsuba's +y-up world to a +z-up one, the change of axes ``ENV_CONVENTIONS["mitsuba"]`` is stated
#: with (render.shading.envmap: (x, y, z) -> (x, -z, y)).
Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
#: Supports under the object: none, or a textured table top (room frames: colour and depth).
SUPPORTS = ("none", "table")
#: Half the side of the square table top, in object radii.
TABLE_HALF_SIZE = 2.5
#: Gap between the object's lowest point and the table top (metres): the object stands on it.
TABLE_GAP = 0.0005
#: Side of the table's wood texture (texels).
TABLE_TEXELS = 512
#: Rows of the environment copy whose irradiance sets the exposure.
EXPOSURE_ENV_ROWS = 64
#: Normals probed for the largest irradiance.
EXPOSURE_PROBES = 1024


@dataclass(frozen=True)
class Room:
    """What surrounds the object: the map (linear radiance, furrow's layout), its base turn, a support."""

    env: EnvMap
    """The environment (lights the object; visible behind it in the room frames)."""
    rotation_deg: float = 0.0
    """Turn of the map about +z (right-handed, furrow's ``EnvMap.rotated``) at turntable angle 0."""
    support: str = "none"
    """'none' or 'table' (a textured square table top under the object)."""

    def __post_init__(self) -> None:
        if self.support not in SUPPORTS:
            raise ValueError(f"support must be one of {', '.join(SUPPORTS)}, got {self.support!r}")


def turn_z(deg: float) -> np.ndarray:
    """(3, 3) right-handed rotation about +z."""
    a = np.radians(deg)
    return np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])


def env_to_world(rotation_deg: float = 0.0) -> np.ndarray:
    """(4, 4) ``to_world`` of Mitsuba's envmap showing a furrow-layout map turned by ``rotation_deg``:
    Mitsuba's pixel uv faces Q^T P m(uv) = furrow's direction of uv (``ENV_CONVENTIONS``), then the turn."""
    m = np.eye(4)
    m[:3, :3] = turn_z(rotation_deg) @ ENV_CONVENTIONS["mitsuba"].T @ Y_UP_TO_Z_UP
    return m


def mitsuba_texels(env: EnvMap) -> np.ndarray:
    """(H, W, 3) float32 texels to hand Mitsuba's envmap so that it shows ``env`` on furrow's grid.

    Mitsuba puts column j at furrow's u of column j (measured) but row i at v = i / (H - 1) (the first
    and the last row on the poles), where furrow puts it at the row's centre: unresampled, the map is
    stretched about the horizon by up to half a texel at the poles (0.18 degrees at 512 rows, about a
    pixel of a 640x480 view 40 degrees off the horizon).  So row i is furrow's map read at that v."""
    h = env.height
    u = dir_to_uv(env.pixel_directions()[0])[:, 0]  # furrow's column centres
    uv = np.stack(np.meshgrid(u, np.linspace(0.0, 1.0, h)), -1)
    return np.ascontiguousarray(np.maximum(sample_equirect(env.data, uv), 0.0), dtype=np.float32)


def exposure_for(env: EnvMap, key: float) -> float:
    """Linear gain that takes a white Lambertian surface under the map's largest irradiance to ``key``
    (the rule of ``datasets_synthetic.lighting``, on the whole map)."""
    from render.shading.sh import irradiance_brute

    small = env.resized(min(EXPOSURE_ENV_ROWS, env.height))
    n = np.random.default_rng(0).normal(size=(EXPOSURE_PROBES, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    e = irradiance_brute(small, n) @ np.array([0.2126, 0.7152, 0.0722])
    return float(key * np.pi / max(float(e.max()), 1e-12))


def wood_texture(seed: int, n: int = TABLE_TEXELS) -> np.ndarray:
    """(n, n, 3) float32 linear albedo of a light wood table top: grain bands, knots of noise, planks."""
    rng = np.random.default_rng([int(seed), 21])
    y, x = np.mgrid[0:n, 0:n] / n
    warp = sum(rng.uniform(0.01, 0.03) * np.sin(2 * np.pi * (f * x + rng.uniform())) for f in (1, 3, 7))
    grain = 0.5 + 0.5 * np.sin(2 * np.pi * 38 * (y + warp) + 4 * np.sin(2 * np.pi * 2 * x))
    plank = np.floor(x * 5)
    tone = 0.85 + 0.15 * rng.uniform(size=5)[plank.astype(int)]
    seam = np.where(np.abs(x * 5 - np.round(x * 5)) < 0.004, 0.4, 1.0)
    base = np.array([0.42, 0.27, 0.15]) * (0.75 + 0.25 * grain[..., None]) * (tone * seam)[..., None]
    return base.astype(np.float32)


def write_curves(c: Curves, path: Path) -> None:
    """Mitsuba's curve file: one ``x y z radius`` line per control point, a blank line between curves."""
    rows = np.column_stack([c.points, c.radii])
    ends = np.cumsum(c.counts)
    lines, start = [], 0
    for e in ends:
        lines.append("\n".join(" ".join(f"{v:.7g}" for v in r) for r in rows[start:e]))
        start = e
    Path(path).write_text("\n\n".join(lines) + "\n")


def write_obj(m: TriangleMesh, path: Path) -> None:
    """A Wavefront OBJ of the mesh's vertices and faces (Mitsuba's ``obj`` shape; smooth normals of its own)."""
    v = "\n".join(f"v {a:.7g} {b:.7g} {c:.7g}" for a, b, c in m.vertices)
    f = "\n".join(f"f {a} {b} {c}" for a, b, c in m.faces + 1)
    Path(path).write_text(v + "\n" + f + "\n")


def _matrix(m) -> object:
    mi = load_mitsuba()
    return mi.ScalarTransform4f(np.asarray(m, np.float64).tolist())


def _part_dict(part, folder: Path, index: int, materials: dict) -> dict:
    if part.material not in materials:
        raise ValueError(f"part {index}: material {part.material!r} is not one of {sorted(materials)}")
    if isinstance(part, Sphere):
        return {"type": "sphere", "center": [float(v) for v in part.centre], "radius": float(part.radius),
                "bsdf": {"type": "ref", "id": part.material}}
    if isinstance(part, TriangleMesh):
        path = folder / f"part{index}.obj"
        write_obj(part, path)
        return {"type": "obj", "filename": str(path), "bsdf": {"type": "ref", "id": part.material}}
    path = folder / f"part{index}.txt"
    write_curves(part, path)
    return {"type": f"{part.basis}curve", "filename": str(path), "bsdf": {"type": "ref", "id": part.material}}


def table_to_world(obj: PathObject, rotation_deg: float) -> np.ndarray:
    """(4, 4) ``to_world`` of Mitsuba's rectangle (z = 0, [-1, 1]^2) as the table top under ``obj``."""
    half = TABLE_HALF_SIZE * obj.radius
    m = np.diag([half, half, 1.0, 1.0])
    m[2, 3] = float(obj.bounds[0, 2]) - TABLE_GAP
    r = np.eye(4)
    r[:3, :3] = turn_z(rotation_deg)
    return r @ m


def scene_dict(obj: PathObject, room: Room, folder: Path, seed: int = 0) -> dict:
    """The Mitsuba scene dictionary (curve files written to ``folder``); no sensor (rays are made by
    ``datasets_synthetic.pathtraced.film``)."""
    mi = load_mitsuba()
    d = {"type": "scene"}
    for name, bsdf in obj.materials.items():
        d[name] = bsdf
    for i, part in enumerate(obj.parts):
        d[f"part{i}"] = _part_dict(part, folder, i, obj.materials)
    d["env"] = {"type": "envmap", "bitmap": mi.Bitmap(mitsuba_texels(room.env)),
                "to_world": _matrix(env_to_world(room.rotation_deg))}
    if room.support == "table":
        d["table"] = {"type": "rectangle", "to_world": _matrix(table_to_world(obj, room.rotation_deg)),
                      "bsdf": {"type": "diffuse", "reflectance": {
                          "type": "bitmap", "bitmap": mi.Bitmap(wood_texture(seed)), "raw": True}}}
    return d


class PathScene:
    """A loaded Mitsuba scene of ``obj`` in ``room`` (owns the curve files' folder; a context manager).

    ``turn(deg)`` turns the room (map and table) about +z by ``deg`` on top of its base rotation:
    the turntable's view at angle deg, seen in the object's frame.
    """

    def __init__(self, obj: PathObject, room: Room, seed: int = 0):
        mi = load_mitsuba()
        self.obj, self.room = obj, room
        self._tmp = tempfile.TemporaryDirectory(prefix="furrow-mitsuba-")
        self.scene = mi.load_dict(scene_dict(obj, room, Path(self._tmp.name), seed))
        self._params = mi.traverse(self.scene)
        self._angle = 0.0
        self.table = next((s for s in self.scene.shapes() if s.id() == "table"), None)

    def turn(self, deg: float) -> None:
        """Turn the room to turntable angle ``deg`` (no-op when already there)."""
        if float(deg) == self._angle:
            return
        mi = load_mitsuba()
        rot = self.room.rotation_deg + float(deg)
        self._params["env.to_world"] = mi.AffineTransform4f(_matrix(env_to_world(rot)))
        if self.table is not None:
            self._params["table.to_world"] = mi.AffineTransform4f(_matrix(table_to_world(self.obj, rot)))
        self._params.update()
        self._angle = float(deg)

    def close(self) -> None:
        self._tmp.cleanup()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

"""The path-traced furry bunny (datasets_synthetic/pathtraced/bunny.py) and the triangle-mesh part it stands on.

The mesh part's render test needs Mitsuba 3 and skips without it (as tests/datasets_synthetic/test_pathtraced.py).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from capture.camera import Camera, look_at, make_K
from datasets_synthetic.pathtraced.objects import PathObject, TriangleMesh, build_object, diffuse
from datasets_synthetic.pathtraced.runtime import mitsuba_available
from render.shading.envmap import EnvMap


def _quad(z: float, half: float) -> TriangleMesh:
    """A square in the plane z = ``z`` (two triangles), side 2 ``half``, centred on the z axis."""
    v = np.array([[-half, -half, z], [half, -half, z], [half, half, z], [-half, half, z]], float)
    return TriangleMesh(v, np.array([[0, 1, 2], [0, 2, 3]]), "m")


def test_triangle_mesh_is_validated():
    """Bad shapes and face indices outside the vertices are refused, naming the material."""
    with pytest.raises(ValueError, match="skin"):
        TriangleMesh(np.zeros((3, 2)), np.array([[0, 1, 2]]), "skin")
    with pytest.raises(ValueError, match="outside"):
        TriangleMesh(np.zeros((3, 3)), np.array([[0, 1, 3]]), "skin")


def test_mesh_part_written_for_mitsuba_and_the_ground_truth(tmp_path):
    """The scene's OBJ holds the mesh's vertices and 1-based faces; gt/mesh.ply and the object's box count it."""
    from datasets_synthetic.pathtraced.assemble import gt_mesh_bytes
    from datasets_synthetic.pathtraced.scene import _part_dict

    q = _quad(0.25, 0.1)
    d = _part_dict(q, tmp_path, 0, {"m": diffuse((0.5, 0.5, 0.5))})
    assert d["type"] == "obj"
    rows = [r.split() for r in (tmp_path / "part0.obj").read_text().splitlines()]
    v = np.array([[float(x) for x in r[1:]] for r in rows if r[0] == "v"])
    f = np.array([[int(x) for x in r[1:]] for r in rows if r[0] == "f"])
    np.testing.assert_allclose(v, q.vertices, atol=1e-7)
    np.testing.assert_array_equal(f, q.faces + 1)
    obj = PathObject("quad", (q,), {"m": diffuse((0.5, 0.5, 0.5))})
    np.testing.assert_allclose(obj.bounds, [[-0.1, -0.1, 0.25], [0.1, 0.1, 0.25]])
    assert obj.radius == pytest.approx(np.sqrt(0.02 + 0.0625))
    assert b"element vertex 4" in gt_mesh_bytes(obj) and b"element face 2" in gt_mesh_bytes(obj)


def test_bunny_is_the_scanned_body_under_thin_strands():
    """build_object('furrybunny'): the scanned body as a mesh part of the size asked, strands in patched groups
    whose roots lie on it and whose radii taper from 0.1 mm to 35 %; the same seed builds the same bunny."""
    a = build_object("furrybunny", 3, strands=400)
    b = build_object("furrybunny", 3, strands=400)
    body, coats = a.parts[0], a.parts[1:]
    assert isinstance(body, TriangleMesh) and len(body.faces) > 50000
    extent = body.vertices.max(0) - body.vertices.min(0)
    assert extent.max() == pytest.approx(0.16, rel=1e-6)
    assert sum(len(c.counts) for c in coats) == 400 and len(coats) >= 2
    for c in coats:
        r = c.radii.reshape(len(c.counts), -1)
        np.testing.assert_allclose(r[:, 0], 1e-4)
        np.testing.assert_allclose(r[:, -1], 3.5e-5)
        assert a.materials[c.material]["type"] == "hair"
    roots = np.concatenate([c.points.reshape(len(c.counts), -1, 3)[:, 0] for c in coats])
    near = np.min(np.linalg.norm(roots[:, None] - body.vertices[None, ::7], axis=-1), axis=1)
    assert np.median(near) < 0.004  # on the skin (the nearest of every 7th vertex)
    for p, q in zip(a.parts[1:], b.parts[1:], strict=True):
        np.testing.assert_array_equal(p.points, q.points)
    with pytest.raises(ValueError, match="unknown parameters"):
        build_object("furrybunny", 0, hairs=3)


def test_bunny_case_is_full_size_before_the_brown_room(tmp_path):
    """bunny_room_turntable: the bunny at the evaluation's 640x480 and 16 spp, before fur_similar_bg's room."""
    from datasets_synthetic.pathtraced.cases import BROWN_ROOM, Options, case_spec

    s = case_spec("bunny_room_turntable", Options(out=tmp_path, cache=tmp_path))
    assert (s.object, s.rig.width, s.rig.height, s.spp, s.motion) == ("furrybunny", 640, 480, 16, "turntable")
    assert (s.env, s.env_rotation_deg) == BROWN_ROOM
    o = case_spec("bunny_room_orbit", Options(out=tmp_path, cache=tmp_path))
    assert o.motion == "orbit" and dataclasses.replace(o, motion="turntable") == s


def test_mesh_part_renders_at_its_depth():
    """Mitsuba reads the OBJ where it was put: a square at z = 0.25 seen straight down the z axis from
    z = 0.85 has z-depth 0.6 at every pixel it covers, and covers the pixels its corners project around."""
    ok, why = mitsuba_available()
    if not ok:
        pytest.skip(f"Mitsuba 3 cannot start: {why}")
    from datasets_synthetic.pathtraced.film import z_depth
    from datasets_synthetic.pathtraced.scene import PathScene, Room

    cam = Camera(make_K(60.0, 60.0, 31.5, 23.5), look_at((0.0, 0.0, 0.85), (0.0, 0.0, 0.0), up=(0, 1, 0)), 64, 48,
                 name="t")
    obj = PathObject("quad", (_quad(0.25, 0.1),), {"m": diffuse((0.5, 0.5, 0.5))})
    with PathScene(obj, Room(EnvMap(np.full((8, 16, 3), 0.5, np.float32), "grey"))) as ps:
        z = z_depth(ps, cam, samples=1)
    hit = z > 0
    half_px = 60.0 * 0.1 / 0.6  # the square's half side in pixels
    assert abs(np.sqrt(hit.sum()) - 2 * half_px) <= 2
    np.testing.assert_allclose(z[hit], 0.6, atol=1e-5)

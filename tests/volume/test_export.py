"""Exports (volume.export, written with Open3D) read back by OTHER libraries: trimesh for GLB and PLY,
plyfile for PLY properties.  Same vertex / point / sphere counts, positions and colours."""

from __future__ import annotations

import numpy as np
import plyfile
import pytest
import trimesh

from capture.scan import to_uint8_srgb
from tests.scenes import SPHERES, build_model, colour_at, ring_cameras, spheres_scene
from volume.export import ExportError, fused_points, write_mesh, write_points, write_spheres

#: Positions are stored as float32: relative agreement after a float32 round trip.
POS_ATOL = 1e-6
#: 8-bit colour: one code value of rounding either way.
CODE_TOL = 1


@pytest.fixture(scope="module")
def model():
    return build_model(ring_cameras(6, 48, 36))


def _ply(path):
    return plyfile.PlyData.read(str(path))


def test_glb_read_back_by_trimesh(model, tmp_path):
    r = write_mesh(model, tmp_path / "m.glb")
    assert r.count == len(model.mesh_vertices) and r.faces == len(model.mesh_faces)
    # trimesh drops COLOR_0 of a primitive with a material unless materials are skipped
    t = trimesh.load(str(r.path), force="mesh", process=False, skip_materials=True)
    assert len(t.vertices) == len(model.mesh_vertices)
    assert len(t.faces) == len(model.mesh_faces)
    np.testing.assert_allclose(t.vertices, model.mesh_vertices, atol=POS_ATOL)
    np.testing.assert_array_equal(t.faces, model.mesh_faces)
    # glTF COLOR_0 is linear: trimesh turns the float colours into bytes of the same linear values
    assert t.visual.kind == "vertex"
    cols = np.asarray(t.visual.vertex_colors)[:, :3].astype(int)
    expect = np.round(model.mesh_colors * 255).astype(int)
    assert np.abs(cols - expect).max() <= CODE_TOL


def test_glb_material_is_rough_dielectric(model, tmp_path):
    import json
    import struct

    path = write_mesh(model, tmp_path / "m.glb").path
    # the GLB's JSON chunk, read with the standard library (a third reader)
    raw = path.read_bytes()
    n = struct.unpack_from("<I", raw, 12)[0]
    gj = json.loads(raw[20:20 + n])
    assert gj["asset"]["version"] == "2.0"
    prim = gj["meshes"][0]["primitives"][0]
    assert {"POSITION", "NORMAL", "COLOR_0"} <= set(prim["attributes"])
    assert gj["accessors"][prim["attributes"]["COLOR_0"]]["componentType"] == 5126  # float32 linear
    pbr = gj["materials"][prim["material"]]["pbrMetallicRoughness"]
    assert pbr["metallicFactor"] == 0.0 and pbr["roughnessFactor"] == 1.0
    mat = next(iter(trimesh.load(str(path), process=False).geometry.values())).visual.material
    assert mat.metallicFactor == 0.0


def test_ply_mesh_read_back_by_plyfile_and_trimesh(model, tmp_path):
    path = write_mesh(model, tmp_path / "m.ply").path
    ply = _ply(path)
    v = ply["vertex"]
    assert v.count == len(model.mesh_vertices)
    assert ply["face"].count == len(model.mesh_faces)
    np.testing.assert_allclose(np.stack([v["x"], v["y"], v["z"]], 1), model.mesh_vertices, atol=POS_ATOL)
    cols = np.stack([v["red"], v["green"], v["blue"]], 1).astype(int)
    assert np.abs(cols - to_uint8_srgb(model.mesh_colors).astype(int)).max() <= CODE_TOL
    t = trimesh.load(str(path), force="mesh", process=False)
    assert len(t.vertices) == len(model.mesh_vertices)
    np.testing.assert_array_equal(t.faces, model.mesh_faces)
    assert np.abs(np.asarray(t.visual.vertex_colors)[:, :3].astype(int) - cols).max() == 0


def test_points_read_back_and_match_the_scene(model, tmp_path):
    r = write_points(model, tmp_path / "p.ply")
    p, c = fused_points(model)
    ply = _ply(r.path)["vertex"]
    assert ply.count == r.count == len(p) > 500
    xyz = np.stack([ply["x"], ply["y"], ply["z"]], 1)
    np.testing.assert_allclose(xyz, p, atol=POS_ATOL)
    cols = np.stack([ply["red"], ply["green"], ply["blue"]], 1).astype(int)
    assert np.abs(cols - to_uint8_srgb(c).astype(int)).max() <= CODE_TOL
    # independently of the writer: the fused points lie on the exact surface and carry its colour
    scene = spheres_scene()
    voxel = model.pyramid.levels[-1].voxel_size
    assert np.abs(scene.sdf(p)).max() < voxel
    assert np.median(np.abs(c - colour_at(p))) < 0.02
    tp = trimesh.load(str(r.path), process=False)
    assert len(tp.vertices) == len(p)


def test_points_without_fusion_keep_every_depth_pixel(model):
    p, c = fused_points(model, voxel=0)
    assert len(p) == int(np.count_nonzero(model.rgbz.depth > 0)) == len(c)
    fused, _ = fused_points(model)
    assert len(fused) < len(p)


def test_spheres_ply_centres_and_radii(model, tmp_path):
    r = write_spheres(model, tmp_path / "s.ply")
    v = _ply(r.path)["vertex"]
    assert v.count == r.count == len(SPHERES)
    np.testing.assert_allclose(np.stack([v["x"], v["y"], v["z"]], 1), SPHERES[:, :3], atol=POS_ATOL)
    np.testing.assert_allclose(v["radius"], SPHERES[:, 3], rtol=1e-6)


def test_bad_suffix_names_the_file_and_writes_nothing(model, tmp_path):
    for fn, name in ((write_mesh, "m.obj"), (write_points, "p.glb"), (write_spheres, "s.txt")):
        with pytest.raises(ExportError, match=name):
            fn(model, tmp_path / name)
    assert list(tmp_path.iterdir()) == []


def test_failed_write_leaves_nothing(model, tmp_path, monkeypatch):
    import open3d as o3d

    monkeypatch.setattr(o3d.io, "write_triangle_mesh", lambda *a, **k: False)
    with pytest.raises(ExportError, match="could not write"):
        write_mesh(model, tmp_path / "m.ply")
    assert list(tmp_path.iterdir()) == []

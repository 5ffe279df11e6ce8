"""The furry bunny: fur grown on the scanned Stanford Bunny shipped in pymeshlab (datasets_synthetic/scanned.py)."""

from __future__ import annotations

import numpy as np
import pytest

from datasets_synthetic.fur import SKIN_CLEARANCE_M, push_outside
from datasets_synthetic.scanned import MeshSourceError, bunny_path, load_bunny
from datasets_synthetic.scenes import build_scene


def _signed_distance(v, f, q):
    import open3d as o3d

    rc = o3d.t.geometry.RaycastingScene()
    rc.add_triangles(o3d.core.Tensor(v.astype(np.float32)), o3d.core.Tensor(f.astype(np.uint32)))
    return rc.compute_signed_distance(o3d.core.Tensor(q.astype(np.float32))).numpy()


def test_scanned_mesh_is_the_installed_bunny_turned_z_up():
    assert bunny_path().name == "bunny.obj" and "pymeshlab" in str(bunny_path())
    v, f, n = load_bunny(0.16)
    assert len(v) == 28088 and len(f) == 56172
    size = v.max(0) - v.min(0)
    assert np.isclose(size.max(), 0.16) and np.allclose(0.5 * (v.max(0) + v.min(0)), 0, atol=1e-9)
    # upright: the ears are the highest part, near the head at -x; the body is longer in x than tall
    top = v[v[:, 2] > v[:, 2].max() - 0.01]
    assert top[:, 0].mean() < 0 and size[0] > size[1]
    # outward normals: a point moved out along the normal is outside the closed surface
    idx = np.arange(0, len(v), 97)
    assert (_signed_distance(v, f, v[idx] + 1e-3 * n[idx]) > 0).mean() > 0.97


def test_fur_roots_on_the_skin_and_strands_outside():
    sc = build_scene("furrybunny", 1, strands=3000)
    P = sc.params["fur"]["segments"] + 1
    sides = sc.params["fur"]["sides"]
    assert sc.stats["strands"] == 3000
    tang = np.linalg.norm(sc.mesh.tangents, axis=1) > 0.5
    assert tang.sum() == 3000 * P * sides
    v, f, _ = load_bunny(sc.params["size_m"])
    ring = sc.mesh.vertices[tang].reshape(3000, P, sides, 3).mean(2)  # strand centre lines
    sd = _signed_distance(v, f, ring[:, 1:].reshape(-1, 3))
    assert sd.min() > SKIN_CLEARANCE_M * 0.5, sd.min()  # float32 round-off only
    root_sd = _signed_distance(v, f, ring[:, 0])
    assert np.abs(root_sd).max() < 1e-3


def test_push_outside_moves_inside_points_out():
    v, f, _ = load_bunny(0.16)
    paths = np.zeros((1, 3, 3))
    paths[0, 1] = [0.02, 0.0, -0.02]  # inside the body
    paths[0, 2] = [0.0, 0.0, 0.5]     # far outside
    out, moved = push_outside(paths, v, f)
    assert moved == 1
    sd = _signed_distance(v, f, out[0, 1:])
    assert np.isclose(sd[0], SKIN_CLEARANCE_M, atol=5e-5) and np.array_equal(out[0, 2], paths[0, 2])


def test_missing_package_is_named(monkeypatch):
    import importlib.util

    monkeypatch.setattr(importlib.util, "find_spec", lambda name: None)
    with pytest.raises(MeshSourceError, match="pymeshlab"):
        bunny_path()

"""The fast mesh paths against their references: the numba z-buffer (volume.mesh_depth)
against Open3D's ray cast (volume.rgbz.raycast_depth) and an analytic plane; quadric
decimation by fast-simplification against pymeshlab's (volume.mesh)."""

from __future__ import annotations

import numpy as np
import pytest

from capture.camera import Camera, make_K
from tests.scenes import scan_ring as ring_cameras
from tests.scenes import sphere_scene
from tests.volume.test_parts import _level
from volume.mesh import MeshConfig, clean_and_decimate, marching_cubes
from volume.mesh_depth import mesh_depth
from volume.rgbz import raycast_depth


def test_triangle_depth_is_the_plane_depth_at_pixel_centres():
    """A tilted triangle: every pixel centre inside it gets the exact depth of its plane, both windings."""
    cam = Camera(make_K(50.0, 50.0, 19.5, 14.5), np.eye(4), 40, 30)
    # plane z = 0.5 + 0.1 x (camera frame), triangle spanning much of the image
    xy = np.array([[-0.15, -0.12], [0.18, -0.1], [0.0, 0.14]])
    tri = np.column_stack([xy, 0.5 + 0.1 * xy[:, 0]])
    for faces in (np.array([[0, 1, 2]]), np.array([[0, 2, 1]])):
        d = mesh_depth(tri, faces, [cam])[0]
        ray = cam.pixel_rays(cam.pixel_grid())  # z = 1: point = z * ray
        exact = 0.5 / (1.0 - 0.1 * ray[..., 0])  # z = 0.5 + 0.1 z rx
        # inside test by the exact projected triangle (independent of the rasteriser's arithmetic)
        uv = tri[:, :2] / tri[:, 2:] * 50.0 + [19.5, 14.5]
        g = cam.pixel_grid()

        def side(a, b, g=g):
            return (b[0] - a[0]) * (g[..., 1] - a[1]) - (b[1] - a[1]) * (g[..., 0] - a[0])

        s = np.stack([side(uv[0], uv[1]), side(uv[1], uv[2]), side(uv[2], uv[0])])
        inside = np.all(s > 1e-9, 0) | np.all(s < -1e-9, 0)
        edge = ~inside & (np.abs(s).min(0) <= 1e-9)  # centres on an edge: either answer
        assert inside.sum() > 200
        np.testing.assert_allclose(d[inside], exact[inside], rtol=1e-6)
        assert np.all(d[~inside & ~edge] == 0)


def test_mesh_depth_matches_the_ray_cast():
    lv = _level(sphere_scene(), 48)
    v, f = marching_cubes(lv)
    cams = ring_cameras(6, 96, 72)
    a = mesh_depth(v, f, cams)
    b = raycast_depth(v, f, cams)
    assert (b > 0).sum() > 6 * 1000
    # hit masks differ only where a pixel centre lies within rounding of the silhouette
    assert np.mean((a > 0) != (b > 0)) <= 1e-4
    both = (a > 0) & (b > 0)
    err = np.abs(a - b)[both]
    assert np.mean(err <= 1e-5) >= 0.9999 and err.max() < lv.voxel_size
    assert mesh_depth(v, f[:0], cams).max() == 0


def test_mesh_depth_skips_triangles_behind_the_camera():
    cam = Camera(make_K(50.0, 50.0, 19.5, 14.5), np.eye(4), 40, 30)
    tri = np.array([[-0.1, -0.1, -0.5], [0.1, -0.1, 0.5], [0.0, 0.1, 0.5]])  # one vertex behind
    assert mesh_depth(tri, np.array([[0, 1, 2]]), [cam]).max() == 0


def test_fast_decimation_matches_pymeshlab():
    lv = _level(sphere_scene(), 64)
    v, f = marching_cubes(lv)
    r0 = 0.07
    out = {}
    for dec in ("fast", "pymeshlab"):
        v2, f2 = clean_and_decimate(v, f, MeshConfig(target_faces=2000, decimator=dec))
        assert 1800 <= len(f2) <= 2000, dec
        assert f2.min() >= 0 and f2.max() < len(v2) and len(np.unique(f2)) == len(v2)  # no unused vertices
        tri = v2[f2].astype(np.float64)
        vol = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6
        assert vol == pytest.approx(4 / 3 * np.pi * r0 ** 3, rel=0.03), dec  # winding kept (outwards)
        out[dec] = np.abs(np.linalg.norm(v2, axis=1) - r0)
    # both stay on the sphere; the fast one no worse than 1.5x the reference (+ a tenth of a voxel)
    assert out["pymeshlab"].max() < 0.5 * lv.voxel_size
    assert out["fast"].mean() <= 1.5 * out["pymeshlab"].mean() + 0.1 * lv.voxel_size
    assert out["fast"].max() < 0.5 * lv.voxel_size


def test_mesh_config_is_validated():
    with pytest.raises(ValueError, match="decimator"):
        MeshConfig(decimator="meshlab")
    with pytest.raises(ValueError, match="power of two"):
        MeshConfig(level=100)

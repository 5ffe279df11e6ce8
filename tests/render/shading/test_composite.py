"""Compositing pieces: background through a camera, tone mapping, ground hits, and the shadow
ratio (seed 004 Eq. 16-17) against ray-cast irradiance."""

from __future__ import annotations

import numpy as np
import pytest

from capture.camera import Camera, look_at, make_K
from render.shading.composite import (background, composite, ground_hits, ground_shadow_ratio,
                                      ground_shadow_ratio_raycast, tonemap, view_directions)
from render.shading.envmap import bundled_envmap, procedural_sky


def _camera(eye=(1.0, -1.0, 0.6), target=(0, 0, 0.1)):
    return Camera(make_K(120, 120, 79.5, 59.5), look_at(eye, target), 160, 120)


def test_background_and_ground():
    env = bundled_envmap("studio").resized(64)
    cam = _camera()
    d = view_directions(cam)
    np.testing.assert_allclose(np.linalg.norm(d, axis=-1), 1, atol=1e-12)
    # pixel (79, 59) is half a pixel from the principal point (79.5, 59.5): ~ the optical axis
    np.testing.assert_allclose(d[59, 79] @ cam.forward, 1, atol=1e-4)
    bg = background(env, cam)
    np.testing.assert_allclose(bg[10, 20], env.sample(d[10, 20]), rtol=1e-5)
    pts, hit = ground_hits(cam)
    assert hit.any() and not hit.all()
    np.testing.assert_allclose(pts[hit][:, 2], 0, atol=1e-12)
    uv, z = cam.project(pts[hit])
    np.testing.assert_allclose(uv, cam.pixel_grid()[hit], atol=1e-6)  # back to their own pixels
    assert np.all(d[~hit][:, 2] >= 0)  # rays that miss the ground go up


def test_tonemap():
    x = np.array([[0.0, 0.0, 0.0], [0.5, 0.5, 0.5], [1e5, 5e4, 1e4]])
    c = tonemap(x, 1.0, "clamp")
    np.testing.assert_allclose(c[1], 0.5)
    r = tonemap(x, 2.0, "reinhard")
    assert np.all((r >= 0) & (r <= 1)) and r[2].max() <= 1 and r[2, 0] > r[2, 1] > r[2, 2]
    with pytest.raises(ValueError):
        tonemap(x, 1.0, "filmic")


@pytest.mark.parametrize("name", ["procedural", "courtyard"])
def test_shadow_ratio_vs_raycast(name):
    import open3d as o3d

    from render.shading.sg_fit import fit_env_sg

    env = procedural_sky(64) if name == "procedural" else bundled_envmap(name).resized(64)
    c, r = np.array([0.0, 0.0, 0.15]), 0.1
    m = o3d.geometry.TriangleMesh.create_sphere(radius=r, resolution=60)
    V, F = np.asarray(m.vertices) + c, np.asarray(m.triangles)
    g = np.linspace(-0.4, 0.4, 15)
    X, Y = np.meshgrid(g, g)
    P = np.stack([X.ravel(), Y.ravel(), np.full(X.size, 1e-4)], 1)
    ref = ground_shadow_ratio_raycast(env, P, V, F)
    f = fit_env_sg(env, 10)
    got = ground_shadow_ratio(P, f.axes, f.lams, f.mus, c[None], [r])
    e = np.abs(got - ref)
    # measured (K = 10): procedural sun sky mean 0.019 max 0.22; courtyard mean 0.013 max 0.06
    assert e.mean() < 0.03 and e.max() < 0.3, (e.mean(), e.max())
    assert np.linalg.norm(P[got.argmin()] - P[ref.argmin()]) <= 0.06  # the shadow is where it is
    assert ref.max() > 0.98 and got.max() > 0.98  # far away: unshadowed


def test_composite():
    bg = np.ones((4, 4, 3), np.float32)
    shadow = np.full((4, 4), 0.5)
    ground = np.zeros((4, 4), bool)
    ground[2:] = True
    obj = np.zeros((4, 4, 3))
    a = np.zeros((4, 4))
    a[0, 0] = 1
    out = composite(bg, obj, a, shadow, ground)
    assert out[0, 0].max() == 0 and out[1, 1].min() == 1 and np.allclose(out[3, 3], 0.5)

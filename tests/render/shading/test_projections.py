"""Geodesic domes (docs/methods.md §2 Table 2), cube maps, fisheye and mirror-ball layouts."""

from __future__ import annotations

import numpy as np
import pytest

from render.shading.envmap import EnvMap, bundled_envmap
from render.shading.projections import (
    DOME_TABLE2,
    cubemap_from_equirect,
    dome_frequency_for_width,
    dome_from_equirect,
    dome_solid_angles,
    equirect_from_cubemap,
    equirect_from_fisheye,
    equirect_from_mirror_ball,
    fisheye_from_equirect,
    geodesic_dome,
    mirror_ball_from_equirect,
)


@pytest.mark.parametrize("width", [64, 128, 256, 512])
def test_dome_vertex_counts_match_table2(width):
    nu = dome_frequency_for_width(width)
    v, f = geodesic_dome(nu)
    assert len(v) == DOME_TABLE2[width]
    assert len(f) == 20 * nu * nu
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), 1, atol=1e-12)
    if width <= 128:
        np.testing.assert_allclose(dome_solid_angles(v, f).sum(), 4 * np.pi, rtol=1e-9)
        # outward, counter-clockwise triangles
        a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
        assert np.all(np.einsum("ij,ij->i", np.cross(b - a, c - a), a + b + c) > 0)


def _smooth_env(h=64):
    e = EnvMap(np.zeros((h, 2 * h, 3), np.float32))
    d = e.pixel_directions()
    return EnvMap((1.5 + d @ np.array([[0.5, 0.1, -0.3], [0.2, 0.4, 0.0], [0.3, -0.2, 0.6]])).astype(np.float32))


def test_dome_resampling_preserves_power():
    env = bundled_envmap("forest").resized(64)
    v, L, om = dome_from_equirect(env, 18)
    np.testing.assert_allclose((L * om[:, None]).sum(0), env.total_power(), rtol=0.02)


def test_cubemap_round_trip_and_faces():
    env = _smooth_env()
    cube = cubemap_from_equirect(env, 32)
    # face +X centre looks along +x, +Z face centre along +z (OpenGL order)
    o = 1 / 32  # texel (16, 16) centre: s = t = +1/32 (GL face table, rows top-down)
    np.testing.assert_allclose(cube[0, 16, 16], env.sample([1, -o, -o]), rtol=1e-5)
    np.testing.assert_allclose(cube[4, 16, 16], env.sample([o, -o, 1]), rtol=1e-5)
    back = equirect_from_cubemap(cube, 64)
    np.testing.assert_allclose(back.data, env.data, rtol=0.01)


@pytest.mark.gl
def test_cubemap_matches_gl_texture_cube(gl_ctx):
    """Our face table / orientation = OpenGL's: random texels, LINEAR lookups compared away from
    face edges (where GL's seamless filtering blends faces)."""
    import moderngl

    from render.shading.projections import sample_cubemap
    from tests.render.shading.glsl_harness import eval_glsl

    n = 16
    cube = np.random.default_rng(1).uniform(0, 1, (6, n, n, 3)).astype(np.float32)
    tex = gl_ctx.texture_cube((n, n), 3, b"".join(np.ascontiguousarray(cube[k]).tobytes() for k in range(6)),
                              dtype="f4")
    tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
    d = np.random.default_rng(0).normal(size=(3000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    m = np.abs(d).max(1)
    other = np.sort(np.abs(d), 1)[:, 1] / m  # the larger of the two minor coordinates
    d = d[other < 1 - 2.0 / n]
    try:
        out = eval_glsl(gl_ctx, [], "vec4(texture(u_cube, x.xyz).rgb, 1.0)", d.astype(np.float32),
                        textures={"u_cube": tex}, prelude="uniform samplerCube u_cube;\n")
    finally:
        tex.release()
    np.testing.assert_allclose(out[:, :3], sample_cubemap(cube, d), atol=5e-3)


def test_fisheye_round_trip():
    env = _smooth_env()
    img = fisheye_from_equirect(env, 256, 185.0)
    back = equirect_from_fisheye(img, 64, 185.0, below=-1.0)
    d = env.pixel_directions()
    up = d[..., 2] > 0.1
    np.testing.assert_allclose(back.data[up], env.data[up], rtol=0.01)
    assert np.all(back.data[d[..., 2] < -0.1] == 0)  # below = -1 clamped to 0 (radiance >= 0)
    # orientation: world +x is image right, world +y is image top
    e2 = EnvMap(np.maximum(d[..., 0:1] * np.ones(3), 0).astype(np.float32))
    f = fisheye_from_equirect(e2, 64)
    assert f[32, 60, 0] > 0.5 and f[32, 4, 0] == 0
    e3 = EnvMap(np.maximum(d[..., 1:2] * np.ones(3), 0).astype(np.float32))
    f = fisheye_from_equirect(e3, 64)
    assert f[4, 32, 0] > 0.5 and f[60, 32, 0] == 0


def test_mirror_ball_round_trip():
    env = _smooth_env()
    # camera looking along world +y from -y: camera z (towards viewer) = world -y, y up = world +z
    R = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])
    img = mirror_ball_from_equirect(env, 512, R)
    back = equirect_from_mirror_ball(img, 32, R)
    d = back.pixel_directions()
    toward = d @ (R @ np.array([0, 0, 1.0])) > -0.5  # away from the unreliable rim (behind the ball)
    np.testing.assert_allclose(back.data[toward], env.resized(32).data[toward], rtol=0.02)

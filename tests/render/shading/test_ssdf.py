"""SSDF from spheres (docs/methods.md §3, Algorithm 1) vs ray-cast visibility, hard cases, GLSL twin."""

from __future__ import annotations

import numpy as np
import pytest

from render.shading.sg import fh_fit, sg_hemi_integral
from render.shading.ssdf import (
    SSDF_MAX,
    fibonacci_directions,
    raycast_visibility,
    sg_visible_integral_raycast,
    ssdf_from_visibility,
    ssdf_ground,
    ssdf_spheres,
)
from tests.render.shading.glsl_harness import eval_glsl


def _sphere_mesh(center, radius):
    import open3d as o3d

    m = o3d.geometry.TriangleMesh.create_sphere(radius=radius, resolution=80)
    return np.asarray(m.vertices) + center, np.asarray(m.triangles)


def test_single_sphere_matches_raycast():
    c, r = np.array([0.0, 0.0, 0.15]), 0.1
    V, F = _sphere_mesh(c, r)
    rng = np.random.default_rng(0)
    P = np.c_[rng.uniform(-0.3, 0.3, (30, 2)), rng.uniform(0.0, 0.3, 30)]
    P = P[np.linalg.norm(P - c, axis=1) > r + 0.02]
    D = fibonacci_directions(12000)
    axes = fibonacci_directions(40)
    vis = raycast_visibility(V, F, P[:12], D)
    ref = ssdf_from_visibility(vis, D, axes)
    got = ssdf_spheres(P[:12], None, axes, c[None], [r], cull=False)
    # sampling resolution of the reference sqrt(4pi/D) = 0.032 rad, + mesh facetting
    assert np.abs(got - ref).max() < 0.04


def test_hard_cases():
    axes = np.array([[0, 0, 1.0], [1, 0, 0], [0, 0, -1]])
    # point inside a sphere: that sphere is skipped
    assert np.all(ssdf_spheres([[0, 0, 0.0]], [[0, 0, 1.0]], axes, [[0, 0, 0.0]], [1.0]) == SSDF_MAX)
    # point exactly on a sphere's surface: skipped too (dist <= r), no NaN
    v = ssdf_spheres([[0, 0, 1.0]], [[0, 0, 1.0]], axes, [[0, 0, 0.0]], [1.0], cull=False)
    assert np.all(np.isfinite(v))
    # asin argument above 1 by rounding: tangent-ish, finite
    x = np.array([[0, 0, 1.0 + 1e-16]])
    assert np.all(np.isfinite(ssdf_spheres(x, [[0, 0, 1.0]], axes, [[0, 0, 0.0]], [1.0], cull=False)))
    # zeta exactly towards the centre: -asin(r/d)
    v = ssdf_spheres([[0, 0, 0.0]], [[0, 0, 1.0]], axes[:1], [[0, 0, 2.0]], [1.0])
    np.testing.assert_allclose(v, -np.arcsin(0.5), atol=1e-12)
    # zeta exactly away: pi - asin(r/d) > pi/2 -> capped
    v = ssdf_spheres([[0, 0, 0.0]], [[0, 0, 1.0]], axes[2:], [[0, 0, 2.0]], [1.0], cull=False)
    assert v[0, 0] == SSDF_MAX
    # tangent-plane culling: a sphere below the tangent plane is ignored; one touching it is not
    below = ssdf_spheres([[0, 0, 0.0]], [[0, 0, 1.0]], axes, [[0, 0, -2.0]], [1.0])
    assert np.all(below == SSDF_MAX)
    touching = ssdf_spheres([[0, 0, 0.0]], [[0, 0, 1.0]], axes[1:2], [[2, 0, -0.9]], [1.0])
    assert touching[0, 0] < SSDF_MAX


def test_ground_plane():
    z = np.array([[0, 0, 1.0], [1, 0, 0], [0.6, 0, -0.8]])
    np.testing.assert_allclose(ssdf_ground(z), [np.pi / 2, 0.0, -np.arcsin(0.8)], atol=1e-12)
    with pytest.raises(ValueError):
        ssdf_ground(z, 0.0, points=[[0, 0, -1.0]])
    # matches ray casting against a big ground quad
    V = np.array([[-50, -50, 0.0], [50, -50, 0], [50, 50, 0], [-50, 50, 0]])
    F = np.array([[0, 1, 2], [0, 2, 3]])
    D = fibonacci_directions(20000)
    axes = fibonacci_directions(40)
    vis = raycast_visibility(V, F, np.array([[0, 0, 0.05]]), D)
    ref = ssdf_from_visibility(vis, D, axes)[0]
    assert np.abs(ssdf_ground(axes) - ref).max() < 0.035


def test_visibility_weighted_sg_integral_vs_raycast():
    """The SSDF + fitted f_h approximation of the integral of G V (001 Eq. 12-14) against the
    ray-cast quadrature, for points on a ground plane next to a sphere. The model treats the
    occluder boundary as a great circle, so it is only approximate: measured errors (units of
    the unoccluded hemisphere integral) lambda 1: mean 0.060 max 0.157; lambda 10: mean 0.036
    max 0.301; lambda 100: mean 0.003 max 0.040."""
    c, r = np.array([0.0, 0.0, 0.12]), 0.1
    V, F = _sphere_mesh(c, r)
    G = np.array([[-50, -50, 0.0], [50, -50, 0], [50, 50, 0], [-50, 50, 0]])
    V, F = np.vstack([V, G]), np.vstack([F, np.array([[0, 1, 2], [0, 2, 3]]) + len(V)])
    P = np.array([[0.15, 0.0, 1e-4], [0.25, 0.05, 1e-4], [0.0, 0.3, 1e-4], [0.12, 0.12, 1e-4]])
    N = np.tile([0, 0, 1.0], (len(P), 1))
    D = fibonacci_directions(40000)
    axes = fibonacci_directions(30)
    axes = axes[axes[:, 2] > 0.1]
    vis = raycast_visibility(V, F, P, D)
    ssdf = np.minimum(ssdf_spheres(P, N, axes, c[None], [r]), ssdf_ground(axes)[None])
    for lam, mean_max, max_max in ((1.0, 0.07, 0.18), (10.0, 0.045, 0.33), (100.0, 0.005, 0.05)):
        ref = sg_visible_integral_raycast(vis, D, axes, np.full(len(axes), lam))
        err = np.abs(fh_fit(ssdf, lam) - ref) / sg_hemi_integral(lam)
        assert err.mean() < mean_max and err.max() < max_max, (lam, err.mean(), err.max())


@pytest.mark.gl
def test_ssdf_glsl_twin(gl_ctx):
    rng = np.random.default_rng(3)
    S = 40
    centers = rng.uniform(-0.2, 0.2, (S, 3)) + [0, 0, 0.2]
    radii = rng.uniform(0.01, 0.06, S)
    n = 1500
    P = np.c_[rng.uniform(-0.3, 0.3, (n, 2)), rng.uniform(0, 0.1, n)]
    Z = rng.normal(size=(n, 3)); Z /= np.linalg.norm(Z, axis=1, keepdims=True)
    normal = np.array([0.2, 0.1, 0.97]); normal /= np.linalg.norm(normal)
    ref = np.array([ssdf_spheres(P[i:i + 1], normal[None], Z[i:i + 1], centers, radii)[0, 0] for i in range(n)])
    buf = gl_ctx.buffer(np.c_[centers, radii].astype(np.float32).tobytes())
    buf.bind_to_storage_buffer(5)
    zt = gl_ctx.texture((n, 1), 4, np.c_[Z, np.zeros(n)].astype(np.float32).tobytes(), dtype="f4")
    try:
        out = eval_glsl(gl_ctx, ["shading_ssdf.glsl"],
                        "vec4(ssdf_from_spheres(x.xyz, u_n, "
                        "texelFetch(u_z, ivec2(int(gl_FragCoord.x) + 256 * int(gl_FragCoord.y), 0), 0).xyz), "
                        "ssdf_ground(x.xyz), 0.0, 1.0)",
                        P.astype(np.float32), textures={"u_z": zt},
                        uniforms={"u_ssdf_count": S, "u_n": tuple(normal)},
                        prelude="uniform sampler2D u_z;\nuniform vec3 u_n;\n")
    finally:
        zt.release()
        buf.release()
    # float32 acos near +-1 loses ~3e-4 rad
    np.testing.assert_allclose(out[:, 0], ref, atol=1e-3)
    np.testing.assert_allclose(out[:, 1], ssdf_ground(P), atol=1e-3)

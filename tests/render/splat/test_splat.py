"""The ``splat`` method: its GL owner (render/splat/gl.py) against its numpy twin
(render/splat/reference.py), the twin against a one-Gaussian-at-a-time brute force, and the EWA
projection against the closed form of a Gaussian facing the camera."""

from __future__ import annotations

import numpy as np
import pytest

from capture.camera import Camera, look_at, make_K
from render.splat import reference as sr
from render.splat.gl import SplatRenderer, draw_order
from volume import splat_sh
from volume.splats import Splats, matrix_to_quat, quat_to_matrix

pytestmark = pytest.mark.gl

#: GL (float32 blending, float32 projection) against the float64 twin: measured at most 2e-6 on
#: every value (rgb premultiplied linear, alpha; SH degree 0, 2, 3); the tolerance leaves 50x room
#: and is far below one 8-bit code.
GL_TWIN_ATOL = 1e-4
#: Depth (alpha-weighted mean z, metres): measured 1e-7 at 0.12 m.
GL_TWIN_DEPTH_ATOL = 1e-5


def random_splats(rng, n=300, degree=2, spread=0.03) -> Splats:
    """Seeded Gaussians in a box of +-``spread`` m around the origin: anisotropic (one axis up to
    8x another), random rotations and opacities, SH of ``degree`` with view dependence."""
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    scales = rng.uniform(0.0004, 0.003, (n, 3))
    k = splat_sh.n_coeffs(degree)
    sh = rng.normal(scale=0.25, size=(n, k, 3))
    sh[:, 0, :] = splat_sh.dc_from_colour(rng.uniform(0.1, 0.9, (n, 3)))
    return Splats(rng.uniform(-spread, spread, (n, 3)), scales, q, rng.uniform(0.05, 0.99, n), sh)


def eye(width=64, height=48, f=90.0, skew=0.0, at=(0.09, -0.075, 0.04)) -> Camera:
    K = make_K(f, f * 1.05, (width - 1) / 2 + 1.3, (height - 1) / 2 - 0.7, skew)
    return Camera(K, look_at(np.array(at), np.zeros(3), (0.0, 0.0, 1.0)), width, height)


@pytest.mark.parametrize("degree,skew", [(0, 0.0), (2, 0.0), (3, 4.0)])
def test_gl_matches_the_numpy_twin(gl_ctx, degree, skew):
    rng = np.random.default_rng(7 + degree)
    s = random_splats(rng, degree=degree)
    cam = eye(skew=skew)
    rgb, alpha, depth, n = sr.splat_frame(s, cam)
    with SplatRenderer(gl_ctx, s) as r:
        f = r.render(cam)
    assert f.stats.facets == n == len(s)
    assert alpha.max() > 0.9 and (alpha > 0).mean() > 0.3  # the test draws something
    np.testing.assert_allclose(f.rgb, rgb, atol=GL_TWIN_ATOL)
    np.testing.assert_allclose(f.alpha, alpha, atol=GL_TWIN_ATOL)
    np.testing.assert_allclose(f.depth, depth, atol=GL_TWIN_DEPTH_ATOL)


def test_gl_twin_comparison_can_fail(gl_ctx):
    """The same comparison with the draw order reversed (back to front blended as front to back)
    is far outside the tolerance: the test sees the order."""
    rng = np.random.default_rng(3)
    s = random_splats(rng)
    cam = eye()
    rgb, *_ = sr.splat_frame(s, cam)
    with SplatRenderer(gl_ctx, s) as r:
        order = draw_order(s.positions, s.opacities, cam)[::-1].copy()
        tgt = r._draw(cam, order)
        from capture.camera import gl_rows_to_image

        c = gl_rows_to_image(tgt.read_colour(0))
        d = gl_rows_to_image(tgt.read_colour(1))
        wrong = sr.to_frame(c[..., :3], c[..., 3], d[..., 0])[0]
    assert np.abs(wrong - rgb).max() > 100 * GL_TWIN_ATOL


def brute_force(s: Splats, cam: Camera):
    """Per Gaussian, in depth order, per pixel: the reference's formulas written out (no fragment
    lists, no batching): (C, A, D) as reference.blend returns them."""
    W, H = cam.width, cam.height
    C, A, D, T = np.zeros((H, W, 3)), np.zeros((H, W)), np.zeros((H, W)), np.ones((H, W))
    R = cam.cam_from_world[:3, :3]
    cov3 = s.covariances()
    t_all = s.positions.astype(np.float64) @ R.T + cam.cam_from_world[:3, 3]
    for i in np.argsort(t_all[:, 2], kind="stable"):
        t = t_all[i]
        if t[2] <= sr.NEAR_M or s.opacities[i] < sr.ALPHA_MIN:
            continue
        cov = sr.screen_covariance(t[None], (R @ cov3[i] @ R.T)[None], cam)[0]
        inv = np.linalg.inv(cov)
        (u, v), _ = cam.project(s.positions[i].astype(np.float64))
        d = s.positions[i] - cam.center
        col = splat_sh.colour(s.sh[i:i + 1], (d / np.linalg.norm(d))[None])[0]
        for y in range(H):
            for x in range(W):
                dd = np.array([x - u, y - v])
                a = min(sr.ALPHA_MAX, s.opacities[i] * np.exp(-0.5 * dd @ inv @ dd))
                if a < sr.ALPHA_MIN:
                    continue
                C[y, x] += T[y, x] * a * col
                A[y, x] += T[y, x] * a
                D[y, x] += T[y, x] * a * t[2]
                T[y, x] *= 1 - a
    return C, A, D


def test_twin_matches_brute_force():
    rng = np.random.default_rng(11)
    s = random_splats(rng, n=40, spread=0.02)
    cam = eye(24, 18, f=40.0)
    pr = sr.project(s.positions, s.covariances(), s.opacities, s.sh, cam)
    C, A, D = sr.blend(pr, cam.width, cam.height)
    bC, bA, bD = brute_force(s, cam)
    assert bA.max() > 0.5
    np.testing.assert_allclose(C, bC, atol=1e-9)
    np.testing.assert_allclose(A, bA, atol=1e-9)
    np.testing.assert_allclose(D, bD, atol=1e-9)


def test_projection_of_a_gaussian_facing_the_camera():
    """An isotropic Gaussian of sigma s at depth z on the optical axis: screen variance
    (f s / z)^2 + 0.3 per axis, the centre on the principal point, alpha there the opacity
    (under 0.99), the colour 0.5 + C0 dc."""
    cam = Camera(make_K(100.0, 100.0, 15.0, 10.0), look_at(np.array([0, 0, -0.5]), np.zeros(3), (0, -1, 0)), 31, 21)
    sig, op, col = 0.002, 0.6, np.array([0.2, 0.5, 0.8])
    sh = splat_sh.dc_from_colour(col)[None, None, :]
    s = Splats(np.zeros((1, 3)), np.full((1, 3), sig), np.array([[1.0, 0, 0, 0]]), np.array([op]), sh)
    pr = sr.project(s.positions, s.covariances(), s.opacities, s.sh, cam)
    np.testing.assert_allclose(pr.mean[0], [15.0, 10.0], atol=1e-9)
    want = (100.0 * sig / 0.5) ** 2 + sr.LOW_PASS_PX2
    np.testing.assert_allclose(pr.cov[0], np.diag([want, want]), atol=1e-9)
    C, A, _ = sr.blend(pr, cam.width, cam.height)
    assert A[10, 15] == pytest.approx(op)
    np.testing.assert_allclose(C[10, 15] / A[10, 15], col, atol=1e-9)
    # one pixel to the right: exp(-1 / (2 var))
    assert A[10, 16] == pytest.approx(op * np.exp(-0.5 / want))


def test_quaternions_round_trip():
    rng = np.random.default_rng(2)
    q = rng.normal(size=(50, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q *= np.sign(q[:, :1])
    np.testing.assert_allclose(matrix_to_quat(quat_to_matrix(q)), q, atol=1e-12)
    r = quat_to_matrix(q)
    np.testing.assert_allclose(np.einsum("nij,nkj->nik", r, r), np.broadcast_to(np.eye(3), r.shape), atol=1e-12)
    assert np.allclose(np.linalg.det(r), 1.0)


def test_sh_basis_constants_and_signs():
    """Degree 1 of the reference is (-C1 y, C1 z, -C1 x); the basis is orthonormal over the sphere
    (Monte Carlo, 200k directions: within 1 %)."""
    b = splat_sh.basis(np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]]), 1)
    np.testing.assert_allclose(b[:, 1:], -splat_sh.SH_C1 * np.array([[0, 0, 1], [1, 0, 0], [0, -1, 0]]), atol=1e-15)
    rng = np.random.default_rng(0)
    d = rng.normal(size=(200_000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    B = splat_sh.basis(d, 3)
    gram = 4 * np.pi * B.T @ B / len(d)
    np.testing.assert_allclose(gram, np.eye(16), atol=0.03)

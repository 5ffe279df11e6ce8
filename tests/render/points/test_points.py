"""The plain point splatter (render/points/reference.py, the ``points`` method): its vectorised
numpy against a per-point brute-force loop, the camera choice, and the hard cases."""

from __future__ import annotations

import numpy as np
import pytest

from capture.camera import Camera, look_at
from render.methods import RenderOptions, create_renderer
from render.points import reference as pr
from tests import scenes as scene


def _brute_splat(eye: Camera, clouds, weights, side: int, tol: float):
    """One point at a time, one pixel at a time: pass 1 the front depth, pass 2 the weighted mean."""
    W, H = eye.width, eye.height
    front = np.full((H, W), np.inf)
    hits = []
    for cl, w in zip(clouds, weights):
        for p, c in zip(cl.points, cl.colours):
            pc = eye.world_to_cam(p)
            if pc[2] <= 0:
                continue
            u = eye.K[0, 0] * pc[0] / pc[2] + eye.K[0, 1] * pc[1] / pc[2] + eye.K[0, 2]
            v = eye.K[1, 1] * pc[1] / pc[2] + eye.K[1, 2]
            for y in range(H):
                for x in range(W):
                    # pixel centre inside [u - side/2, u + side/2) x [v - side/2, v + side/2)
                    if u - side / 2 <= x < u + side / 2 and v - side / 2 <= y < v + side / 2:
                        front[y, x] = min(front[y, x], pc[2])
                        hits.append((y, x, pc[2], c, w))
    acc = np.zeros((H, W, 3))
    wsum = np.zeros((H, W))
    for y, x, z, c, w in hits:
        if z < front[y, x] + tol:
            acc[y, x] += w * c
            wsum[y, x] += w
    cov = np.isfinite(front)
    rgb = np.where(wsum[..., None] > 0, acc / np.maximum(wsum, 1e-300)[..., None], 0)
    return rgb, cov, np.where(cov, front, 0)


def _random_clouds(rng, n_views=3, n=60):
    """Clouds in front of a small eye: points in a 3 cm square 0.4 m away, some of them in
    depth layers closer together than the tolerance, colours random."""
    out = []
    for _ in range(n_views):
        p = rng.uniform(-0.015, 0.015, (n, 3))
        p[:, 2] = rng.choice([0.0, 0.002, 0.01, 0.025], n) + rng.normal(0, 0.0005, n)
        out.append(pr.Cloud(p, rng.uniform(0, 1, (n, 3)).astype(np.float32)))
    return out


@pytest.mark.parametrize("side", [1, 2, 3])
def test_splat_matches_brute_force(side):
    rng = np.random.default_rng(4)
    eye = Camera(np.array([[200.0, 0, 9.5], [0, 200.0, 7.5], [0, 0, 1]]),
                 look_at([0.0, 0.0, -0.4], [0.0, 0.0, 0.0], (0.0, 1.0, 0.0)), 20, 16)
    clouds = _random_clouds(rng)
    weights = [1.0, 0.5, 0.25]
    rgb, cov, depth, n = pr.splat(eye, clouds, weights, side, pr.VIS_TOL_M)
    ref_rgb, ref_cov, ref_depth = _brute_splat(eye, clouds, weights, side, pr.VIS_TOL_M)
    assert n == sum(len(c.points) for c in clouds)  # all in front of the eye
    np.testing.assert_array_equal(cov > 0, ref_cov)
    assert ref_cov.sum() > 50
    np.testing.assert_allclose(rgb, ref_rgb, atol=1e-6)
    np.testing.assert_allclose(depth, ref_depth, atol=1e-6)


def test_splat_covers_the_two_nearest_pixels():
    """A point projected at u = 3.2 covers pixel columns 3 and 4 (centres in [2.2, 4.2))."""
    eye = Camera(np.array([[10.0, 0, 4.0], [0, 10.0, 4.0], [0, 0, 1]]), np.eye(4), 9, 9)
    p = eye.unproject(np.array([[3.2, 5.7]]), np.array([1.0]))
    rgb, cov, depth, _ = pr.splat(eye, [pr.Cloud(p, np.ones((1, 3), np.float32))], [1.0])
    ys, xs = np.nonzero(cov)
    assert set(xs) == {3, 4} and set(ys) == {5, 6}
    np.testing.assert_allclose(depth[cov > 0], 1.0)


def test_nearest_views_by_angle_at_the_centre():
    cams = scene.ring_cameras(12)  # 30 degrees apart
    eye = scene.ring_cameras(12, phase_deg=10)[3]
    centre = scene.BOUNDS.mean(axis=0)
    idx, ang = pr.nearest_views(eye, cams, centre, 4)
    ref = pr.view_angles(eye, cams, centre)
    assert list(idx) == list(np.argsort(ref, kind="stable")[:4])
    assert np.all(np.diff(ang) >= 0) and idx[0] == 3
    # an eye at the object centre looks along its optical axis: its direction is -forward
    inside = Camera(eye.K, look_at(centre, centre + np.array([0.3, 0.0, 0.0])), eye.width, eye.height)
    ang_in = pr.view_angles(inside, cams, centre)
    assert np.all(np.isfinite(ang_in))


@pytest.fixture(scope="module")
def model():
    return scene.build_model(scene.ring_cameras(12))


def test_points_renderer_is_the_reference(gl_ctx, model):
    """The registered method returns exactly points_frame() of the model's RGBz images."""
    eye = scene.ring_cameras(12, phase_deg=17, elevations=(12,))[2]
    clouds = pr.back_project(model.rgbz.cameras, model.rgbz.rgb, model.rgbz.depth)
    rgb, cov, depth, n = pr.points_frame(eye, clouds, model.rgbz.cameras, model.bounds.mean(0))
    with create_renderer("points", gl_ctx, model, RenderOptions(supersample=2)) as r:
        fr = r.render(eye)
    np.testing.assert_array_equal(fr.rgb, rgb)
    np.testing.assert_array_equal(fr.alpha, cov)
    np.testing.assert_array_equal(fr.depth, depth)
    assert fr.stats.facets == n > 0 and fr.stats.supersample == 1  # one sample whatever the options say


def test_points_hard_cases(gl_ctx, model):
    """One camera; an eye inside the bounds; a grazing (top-down) eye; a model with no depth."""
    from volume.model import Model, RgbzImages

    cams = model.rgbz.cameras
    centre = model.bounds.mean(0)
    one = RgbzImages(model.rgbz.rgb[:1], model.rgbz.depth[:1], cams[:1])
    m1 = Model(model.pyramid, one, model.spheres, model.mesh_vertices, model.mesh_faces, model.mesh_colors,
               model.bounds)
    eye = scene.ring_cameras(12, phase_deg=10)[0]
    with create_renderer("points", gl_ctx, m1) as r:
        fr = r.render(eye)
        assert fr.mask.sum() > 100 and np.all(np.isfinite(fr.rgb))
        inside = Camera(eye.K, look_at(centre, centre + np.array([0.3, 0.0, 0.0])), eye.width, eye.height)
        fi = r.render(inside)
        assert np.all(np.isfinite(fi.rgb)) and np.all(fi.depth >= 0)
        top = Camera(eye.K, look_at(centre + np.array([0, 0, 0.45]), centre, (0.0, 1.0, 0.0)), eye.width, eye.height)
        ft = r.render(top)
        assert ft.mask.any() and np.all(np.isfinite(ft.rgb))
    empty = RgbzImages(model.rgbz.rgb, np.zeros_like(model.rgbz.depth), cams)
    m0 = Model(model.pyramid, empty, model.spheres, model.mesh_vertices, model.mesh_faces, model.mesh_colors,
               model.bounds)
    with create_renderer("points", gl_ctx, m0) as r:
        fe = r.render(eye)
        assert not fe.mask.any() and fe.stats.facets == 0


def test_points_carry_the_matte(gl_ctx, model):
    """With a matte: the method is its reference with premultiplied colour + alpha; a constant
    matte 0.5 halves the colour and gives alpha 0.5 wherever a point lands (straight colour kept)."""
    eye = scene.ring_cameras(12, phase_deg=17, elevations=(12,))[2]
    cams, centre = model.rgbz.cameras, model.bounds.mean(0)
    matte = scene.soft_matte(model.rgbz.depth)
    ma = scene.with_alpha(model, matte)
    clouds = pr.back_project(cams, model.rgbz.rgb, model.rgbz.depth, ma.rgbz.alpha)
    rgb, a, depth, n = pr.points_frame(eye, clouds, cams, centre)
    with create_renderer("points", gl_ctx, ma) as r:
        fr = r.render(eye)
    np.testing.assert_array_equal(fr.rgb, rgb)
    np.testing.assert_array_equal(fr.alpha, a)
    np.testing.assert_array_equal(fr.depth, depth)
    assert np.mean((a > 0) & (a < 0.99)) > 0.05
    rgb0, a0, d0, _ = pr.points_frame(eye, pr.back_project(cams, model.rgbz.rgb, model.rgbz.depth), cams, centre)
    half = np.where(model.rgbz.depth > 0, 0.5, 0.0)
    rgb1, a1, d1, _ = pr.points_frame(eye, pr.back_project(cams, model.rgbz.rgb, model.rgbz.depth, half), cams, centre)
    np.testing.assert_array_equal(a1 > 0, a0 > 0)
    np.testing.assert_allclose(a1[a0 > 0], 0.5, atol=1e-6)
    np.testing.assert_allclose(rgb1, 0.5 * rgb0, atol=1e-6)
    np.testing.assert_array_equal(d1, d0)

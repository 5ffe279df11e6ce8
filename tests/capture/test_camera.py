"""Camera round trips and conventions (property tests over random poses and intrinsics)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from capture.camera import (
    CV_TO_GL,
    Camera,
    CameraError,
    cam_from_world_of_transform,
    gl_ndc_depth_to_z,
    gl_rows_to_image,
    look_at,
    make_K,
)

TOL = 1e-9


def rotation_from_quat(q):
    q = np.asarray(q, float)
    q = q / np.linalg.norm(q)
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


finite = st.floats(-1.0, 1.0, allow_nan=False)
quat = st.tuples(finite, finite, finite, finite).filter(lambda q: np.linalg.norm(q) > 0.1)


@st.composite
def cameras(draw):
    R = rotation_from_quat(draw(quat))
    t = np.array(draw(st.tuples(*[st.floats(-5, 5)] * 3)))
    w = draw(st.integers(8, 4000))
    h = draw(st.integers(8, 4000))
    fx = draw(st.floats(10, 5000))
    fy = fx * draw(st.floats(0.5, 2.0))
    cx = draw(st.floats(-0.5, w - 0.5))
    cy = draw(st.floats(-0.5, h - 0.5))
    M = np.eye(4)
    M[:3, :3] = R
    M[:3, 3] = t
    return Camera(make_K(fx, fy, cx, cy), M, w, h)


@settings(max_examples=200, deadline=None)
@given(cameras(), st.floats(0.05, 50.0), st.floats(0, 1), st.floats(0, 1))
def test_world_pixel_world_round_trip(cam, z, fu, fv):
    uv = np.array([fu * (cam.width - 1), fv * (cam.height - 1)])
    p = cam.unproject(uv, z)
    uv2, z2 = cam.project(p)
    scale = max(1.0, np.abs(uv).max())
    assert np.abs(uv2 - uv).max() < TOL * scale * 10
    assert abs(z2 - z) < TOL * max(1.0, z)
    p3 = cam.unproject(uv2, z2)
    assert np.abs(p3 - p).max() < TOL * max(1.0, np.abs(p).max()) * 10


@settings(max_examples=200, deadline=None)
@given(cameras())
def test_nerfstudio_round_trip(cam):
    ns = cam.to_nerfstudio()
    cam2 = Camera.from_nerfstudio(ns["transform_matrix"], ns["fl_x"], ns["fl_y"], ns["cx"], ns["cy"], ns["w"], ns["h"])
    assert np.abs(cam2.K - cam.K).max() < TOL * max(1.0, np.abs(cam.K).max())
    assert np.abs(cam2.cam_from_world - cam.cam_from_world).max() < TOL * 10
    # nerfstudio principal point sits half a pixel further (pixel centres at i + 0.5)
    assert ns["cx"] == pytest.approx(cam.K[0, 2] + 0.5, abs=1e-12)
    # transform_matrix is camera-to-world with y up and z back
    c2w = np.asarray(ns["transform_matrix"])
    assert np.allclose(c2w[:3, 3], cam.center, atol=1e-9)
    assert np.allclose(-c2w[:3, 2], cam.forward, atol=1e-9)


@settings(max_examples=200, deadline=None)
@given(cameras(), st.floats(0.1, 20.0), st.floats(0, 1), st.floats(0, 1))
def test_gl_projection_matches_K(cam, z, fu, fv):
    """The GL view+projection maps a point to the framebuffer location of its OpenCV pixel."""
    near, far = 0.01, 100.0
    uv = np.array([fu * (cam.width - 1), fv * (cam.height - 1)])
    p = cam.unproject(uv, z)
    clip = cam.gl_projection(near, far) @ cam.gl_view() @ np.append(p, 1.0)
    ndc = clip[:3] / clip[3]
    # window coordinates (origin bottom-left, pixel centres at +0.5)
    xw = (ndc[0] + 1) / 2 * cam.width - 0.5
    yw = (ndc[1] + 1) / 2 * cam.height - 0.5
    scale = max(1.0, cam.width, cam.height)
    assert abs(xw - uv[0]) < 1e-9 * scale * 100
    assert abs((cam.height - 1 - yw) - uv[1]) < 1e-9 * scale * 100   # image row = H-1-framebuffer row
    depth01 = (ndc[2] + 1) / 2
    assert gl_ndc_depth_to_z(depth01, near, far) == pytest.approx(z, rel=1e-7)
    # view matrix = OpenCV pose with y, z flipped
    assert np.allclose(cam.gl_view(), CV_TO_GL @ cam.cam_from_world)


def test_gl_rows_flip_is_involution():
    a = np.arange(12).reshape(4, 3)
    assert np.array_equal(gl_rows_to_image(gl_rows_to_image(a)), a)
    assert np.array_equal(gl_rows_to_image(a)[0], a[-1])


def test_look_at_conventions():
    M = look_at([0, -1, 0], [0, 0, 0], up=[0, 0, 1])
    cam = Camera(make_K(100, 100, 49.5, 49.5), M, 100, 100)
    assert np.allclose(cam.forward, [0, 1, 0])
    uv, z = cam.project(np.array([[0.0, 0.0, 0.1], [0.1, 0.0, 0.0]]))
    assert uv[0, 1] < 49.5        # world up appears above the centre (image y down)
    assert uv[1, 0] > 49.5        # world +x appears to the right when looking along +y
    assert np.allclose(z, 1.0)


def test_scaled_keeps_pixel_centres():
    cam = Camera(make_K(100, 100, 49.5, 29.5), look_at([0, -1, 0], [0, 0, 0]), 100, 60)
    half = cam.scaled(0.5)
    assert (half.width, half.height) == (50, 30)
    assert half.K[0, 2] == pytest.approx(24.5) and half.K[1, 2] == pytest.approx(14.5)


@pytest.mark.parametrize("bad, msg", [
    (np.diag([2.0, 1, 1, 1]), "not rigid"),
    (np.diag([1.0, 1, -1, 1]), "not rigid"),
    (np.full((4, 4), np.nan), "NaN"),
    (np.eye(3), "4x4"),
])
def test_invalid_pose_rejected(bad, msg):
    with pytest.raises(CameraError, match=msg):
        Camera(make_K(100, 100, 50, 50), bad, 100, 100)


def test_invalid_intrinsics_rejected():
    with pytest.raises(CameraError):
        Camera(make_K(-1, 100, 50, 50), np.eye(4), 100, 100)
    with pytest.raises(CameraError):
        Camera(make_K(100, 100, 50, 50), np.eye(4), 0, 100)


def test_cam_from_world_of_transform_reads_what_to_nerfstudio_writes():
    cam = Camera(make_K(100, 100, 49.5, 29.5), look_at([0.3, -1, 0.4], [0, 0.1, 0]), 100, 60)
    got = cam_from_world_of_transform(cam.to_nerfstudio()["transform_matrix"])
    assert np.allclose(got, cam.cam_from_world, atol=1e-12)
    # OpenCV axes: the target lies in front of the camera, along its +z
    assert got[2, :3] @ (np.array([0, 0.1, 0]) - cam.center) > 0



def test_mirror_pixels_reverses_rows_and_columns_and_is_its_own_inverse():
    from capture.camera import mirror_pixels

    uv = np.array([[0.0, 0.0], [9.0, 4.0], [2.5, 1.0]])
    np.testing.assert_array_equal(mirror_pixels(uv, (5, 10), True, False), [[0, 4], [9, 0], [2.5, 3]])
    np.testing.assert_array_equal(mirror_pixels(uv, (5, 10), False, True), [[9, 0], [0, 4], [6.5, 1]])
    np.testing.assert_array_equal(mirror_pixels(mirror_pixels(uv, (5, 10), True, True), (5, 10), True, True), uv)
    img = np.arange(50).reshape(5, 10)  # a pixel's value moves where the mirror says
    assert img[::-1][4, 0] == img[tuple(mirror_pixels([[0, 4]], (5, 10), True, False)[0, ::-1].astype(int))]

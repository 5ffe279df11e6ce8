"""The viser (web viewer) camera -> Camera conversion, checked against viser's own code.

viser builds a client camera's quaternion from (position, look_at, up_direction) in
``CameraHandle._update_wxyz``; these tests run that very code (pinned viser 1.1.1) and check
that the converted Camera sees the look-at point at the image centre, viser's up direction up
in the image, its right to the right and the field of view at the image edges.  A flipped axis
or a horizontal / mislabelled field of view fails them; the real-browser test
(tests/furrow/test_view_browser.py) checks the same against the actual client.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from capture.camera import Camera, CameraError, camera_from_viser, look_at, make_K, rotation_from_wxyz, viser_view

viser = pytest.importorskip("viser")
from viser._viser import CameraHandle  # noqa: E402

TOL = 1e-6


def viser_wxyz(position, target, up) -> np.ndarray:
    """The quaternion viser's server computes for this pose (its own code)."""
    h = CameraHandle.__new__(CameraHandle)
    h._state = SimpleNamespace(position=np.asarray(position, float), look_at=np.asarray(target, float),
                               up_direction=np.asarray(up, float), wxyz=np.array([1.0, 0, 0, 0]))
    CameraHandle._update_wxyz(h)
    return h._state.wxyz


POSES = [((0.0, -2.0, 0.5), (0.0, 0.0, 0.5), (0.0, 0.0, 1.0)),
         ((1.3, 0.7, -0.4), (0.1, -0.2, 0.3), (0.0, 1.0, 0.0)),
         ((-0.5, 2.0, 1.5), (0.2, 0.1, 0.0), (0.3, -0.2, 1.0))]


@pytest.mark.parametrize("pose", POSES)
@pytest.mark.parametrize("size", [(800, 600), (333, 517)])
def test_viser_camera_axes_and_fov(pose, size):
    position, target, up = (np.asarray(v, float) for v in pose)
    W, H = size
    fov = np.radians(50.0)
    cam = camera_from_viser(viser_wxyz(position, target, up), position, fov, W, H)
    np.testing.assert_allclose(cam.center, position, atol=TOL)
    # the look-at point is at the image centre (OpenCV pixel centres: (W - 1) / 2)
    uv, z = cam.project(target)
    np.testing.assert_allclose(uv, [(W - 1) / 2, (H - 1) / 2], atol=1e-6)
    assert z > 0
    fwd = (target - position) / np.linalg.norm(target - position)
    up_perp = up - (up @ fwd) * fwd
    up_perp /= np.linalg.norm(up_perp)
    right = np.cross(fwd, up_perp)
    c = (W - 1) / 2, (H - 1) / 2
    # a point at half the vertical field of view above the axis lands on the top edge (v = -0.5)
    top = position + fwd + np.tan(fov / 2) * up_perp
    uv_top, _ = cam.project(top)
    np.testing.assert_allclose(uv_top, [c[0], -0.5], atol=1e-6)
    # right in the world (forward x up) is right in the image, square pixels
    uv_r, _ = cam.project(position + fwd + np.tan(fov / 2) * right)
    np.testing.assert_allclose(uv_r, [c[0] + H / 2, c[1]], atol=1e-6)


def test_viser_camera_agrees_with_look_at():
    """Same pose through furrow's look_at (OpenCV) and through viser: the same camera."""
    position, target, up = (0.4, -1.5, 0.8), (0.0, 0.1, 0.2), (0.0, 0.0, 1.0)
    cam = camera_from_viser(viser_wxyz(position, target, up), position, np.radians(40.0), 640, 480)
    np.testing.assert_allclose(cam.cam_from_world, look_at(position, target, up), atol=TOL)


@pytest.mark.parametrize("pose", POSES)
def test_viser_view_round_trip(pose):
    """Snapping a client to a camera (viser_view) and reading the client back gives that camera."""
    position, target, up = pose
    W, H = 640, 480
    f = 500.0
    cam = Camera(make_K(f, f, (W - 1) / 2, (H - 1) / 2), look_at(position, target, up), W, H)
    v = viser_view(cam, distance=1.7)
    back = camera_from_viser(viser_wxyz(v["position"], v["look_at"], v["up_direction"]), v["position"], v["fov"], W, H)
    np.testing.assert_allclose(back.cam_from_world, cam.cam_from_world, atol=1e-9)
    np.testing.assert_allclose(back.K, cam.K, atol=1e-9)


def test_bad_viser_input():
    with pytest.raises(CameraError, match="field of view"):
        camera_from_viser([1, 0, 0, 0], [0, 0, 0], 0.0, 10, 10)
    with pytest.raises(CameraError, match="quaternion"):
        rotation_from_wxyz([0, 0, 0, 0])

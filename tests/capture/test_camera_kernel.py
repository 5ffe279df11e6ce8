"""Camera.unproject's compiled path (capture.camera_kernel) against its numpy reference: random poses
(look_at from random eyes, with a skewed K and without), random pixels (integer and sub-pixel, inside and
outside the frame), float32 and float64 depths.  Tolerance: TOL_M metres (points within a few metres; the
kernel sums the pose in this machine's OpenBLAS order, so another BLAS may round the last bit otherwise);
measured here: 0, the same points bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

import capture.camera as camera_mod
from capture.camera import Camera, look_at, make_K

#: Largest difference (metres) between the compiled and the numpy world points.
TOL_M = 1e-12


def _camera(rng, skew: float) -> Camera:
    eye = rng.normal(0.0, 1.5, 3) + np.array([0.0, 0.0, 0.5])
    K = make_K(rng.uniform(400, 1500), rng.uniform(400, 1500), rng.uniform(200, 700), rng.uniform(150, 500), skew)
    return Camera(K, np.linalg.inv(look_at(eye, rng.normal(0.0, 0.1, 3))), 1280, 960)


@pytest.mark.parametrize("skew", [0.0, 1.7])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_compiled_unproject_matches_numpy(monkeypatch, skew, dtype):
    rng = np.random.default_rng(7)
    n = camera_mod.UNPROJECT_COMPILED_MIN * 3
    for _ in range(5):
        cam = _camera(rng, skew)
        uv = np.stack([rng.integers(-20, 1300, n), rng.integers(-20, 980, n)], -1)
        uv = uv + (rng.random(uv.shape) if dtype is np.float64 else 0.0)
        depth = rng.uniform(0.05, 4.0, n).astype(dtype)
        monkeypatch.setattr(camera_mod, "UNPROJECT_COMPILED", True)
        fast = cam.unproject(uv, depth)
        monkeypatch.setattr(camera_mod, "UNPROJECT_COMPILED", False)
        ref = cam.unproject(uv, depth)
        assert fast.shape == ref.shape == (n, 3) and fast.dtype == ref.dtype == np.float64
        np.testing.assert_allclose(fast, ref, rtol=0.0, atol=TOL_M)


def test_small_and_shaped_inputs_keep_numpy(monkeypatch):
    """Few pixels, or pixels in an (H, W, 2) grid, take the numpy lines (the same results either way)."""
    cam = _camera(np.random.default_rng(3), 0.0)
    grid = cam.pixel_grid()[:40, :50]
    depth = np.full(grid.shape[:2], 1.25)
    out = cam.unproject(grid, depth)
    assert out.shape == (40, 50, 3)
    flat = cam.unproject(grid.reshape(-1, 2), depth.ravel())
    np.testing.assert_allclose(out.reshape(-1, 3), flat, rtol=0.0, atol=TOL_M)
    # a pixel on the optical axis lands on the ray through the camera centre at the given depth
    c = cam.unproject(np.array([[cam.K[0, 2], cam.K[1, 2]]]), np.array([2.0]))[0]
    axis = cam.world_from_cam[:3, 2]
    np.testing.assert_allclose(c, cam.world_from_cam[:3, 3] + 2.0 * axis, atol=1e-12)

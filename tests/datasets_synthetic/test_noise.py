"""The noise models do what they claim, measured (datasets_synthetic/noise.py)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from capture.camera import Camera, look_at, make_K
from datasets_synthetic.noise import (
    NoiseConfig,
    depth_noise,
    grazing_dropout,
    hole_mask,
    perturb_pose,
    pose_error,
    random_holes,
)

#: Relative tolerance on measured standard deviations / RMS values (sampling error is ~1-3%).
STAT_RTOL = 0.06


def test_depth_noise_sigma_grows_with_z_squared():
    rng = np.random.default_rng(0)
    k = 0.004
    for z in (0.3, 0.6, 1.2):
        d = np.full((200, 200), z, np.float32)
        d[:10] = 0  # no-measurement pixels stay 0
        out = depth_noise(d, rng, k)
        assert np.all(out[:10] == 0)
        diff = (out - d)[10:].astype(np.float64)
        assert abs(diff.std() / (k * z * z) - 1) < STAT_RTOL, (z, diff.std(), k * z * z)
        assert abs(diff.mean()) < 4 * k * z * z / np.sqrt(diff.size)
    assert np.array_equal(depth_noise(d, np.random.default_rng(5), k), depth_noise(d, np.random.default_rng(5), k))


def _sphere_view(W=160, H=120):
    """Analytic sphere (centre 0, radius r) depth + normals seen from +x at distance 0.5 m."""
    r = 0.1
    cam = Camera(make_K(150.0, 150.0, (W - 1) / 2, (H - 1) / 2), look_at((0.5, 0, 0), (0, 0, 0)), W, H)
    rays = cam.pixel_rays(cam.pixel_grid()) @ cam.world_from_cam[:3, :3].T  # world dirs, cam-z = 1
    o = cam.center
    b = rays @ o
    a = np.sum(rays * rays, -1)
    disc = b * b - a * (o @ o - r * r)
    hit = disc > 0
    t = np.where(hit, (-b - np.sqrt(np.maximum(disc, 0))) / a, 0.0)  # t = z-depth since cam-z = 1
    pts = o + rays * np.where(hit, t, 1.0)[..., None]
    n = pts / r
    view = o - pts
    view /= np.linalg.norm(view, axis=-1, keepdims=True)
    ang = np.degrees(np.arccos(np.clip(np.sum(n * view, -1), -1, 1)))
    return cam, np.where(hit, t, 0).astype(np.float32), np.where(hit[..., None], n, 0), np.where(hit, ang, np.nan)


@pytest.mark.parametrize("thr", [60.0, 75.0])
def test_grazing_dropout_removes_exactly_the_grazing_pixels(thr):
    cam, depth, normals, ang = _sphere_view()
    out = grazing_dropout(cam, depth, normals, thr)
    valid = depth > 0
    away = valid & (np.abs(ang - thr) > 0.5)  # pixels clearly on one side of the threshold
    assert np.all(out[away & (ang > thr)] == 0)
    assert np.array_equal(out[away & (ang < thr)], depth[away & (ang < thr)])
    assert np.all(out[~valid] == 0)
    # the dropped ring has the expected share of the disc: fraction of the sphere's visible
    # pixels beyond thr is measured against the analytic angle map
    expect = np.mean(ang[valid] > thr)
    got = np.mean(out[valid] == 0)
    assert abs(got - expect) < 0.01


@pytest.mark.parametrize("frac", [0.02, 0.1])
def test_holes_cover_the_requested_fraction_as_blobs(frac):
    rng = np.random.default_rng(1)
    radius = (2.0, 6.0)
    m = hole_mask((240, 320), rng, frac, radius)
    max_blob = np.pi * (radius[1] + 1) ** 2 / m.size
    assert frac <= m.mean() <= frac + max_blob
    labels, n = ndimage.label(m)
    sizes = np.bincount(labels.ravel())[1:]
    assert sizes.min() >= np.pi * (radius[0] - 1) ** 2 * 0.5  # blobs, not salt noise
    assert n <= m.sum() / (np.pi * (radius[0] - 1) ** 2 * 0.5)
    d = np.full((240, 320), 0.5, np.float32)
    out = random_holes(d, np.random.default_rng(1), frac, radius)
    assert np.array_equal(out == 0, m)


def test_pose_perturbation_has_the_requested_rms():
    cam = Camera(make_K(300.0, 300.0, 159.5, 119.5), look_at((0.4, 0.2, 0.3), (0, 0, 0)), 320, 240)
    rng = np.random.default_rng(2)
    rot, trans = 1.5, 0.004
    errs = np.array([pose_error(perturb_pose(cam, rng, rot, trans), cam) for _ in range(1500)])
    assert abs(np.sqrt(np.mean(errs[:, 0] ** 2)) / rot - 1) < STAT_RTOL
    assert abs(np.sqrt(np.mean(errs[:, 1] ** 2)) / trans - 1) < STAT_RTOL
    p = perturb_pose(cam, np.random.default_rng(3), rot, trans)
    assert np.array_equal(p.K, cam.K) and (p.width, p.height) == (cam.width, cam.height)
    # the rotation is about the camera centre: zero translation noise leaves the centre in place
    q = perturb_pose(cam, np.random.default_rng(3), rot, 0.0)
    assert np.allclose(q.center, cam.center, atol=1e-12)
    assert pose_error(q, cam)[0] > 0


def test_noise_config_validation():
    with pytest.raises(ValueError, match="grazing"):
        NoiseConfig(grazing_deg=95)
    with pytest.raises(ValueError, match="depth_sigma"):
        NoiseConfig(depth_sigma_at_1m=-1)
    assert not NoiseConfig().any_depth and not NoiseConfig().any_pose

"""A moving camera's lens vignetting (capture.vignetting) against the true vignette of the synthetic orbit
(tests/plate_scenes.py), which has none of its own.

Tolerances: the orbit at 192x144 with the frames times 1 - 0.3 r^2 (0.7 at the corners) gives a corner of 0.702
(z 39.8; the right orbit 0.9996, z 3.1, not applied) and the plates' band error 0.0005 against 0.0003 without the
vignette, 0.030 with the vignette left in (measured); the tests allow CORNER_TOL and WORKING_TOL
(tests/capture/test_plate_scale.py's plate tolerance).  Rows made from known exposures and coefficients with 1 %
noise and a tenth of outliers must give the coefficients within COEF_TOL.
"""

from __future__ import annotations

import numpy as np
import pytest

from capture.camera import Camera, make_K
from capture.plate import PlateConfig, PlateView, background_plates
from capture.scan import Scan, srgb_to_linear
from capture.vignetting import devignette_view, fit, radius2, vignette, vignette_map
from tests import plate_scenes as ps

#: The vignette the frames are given: v = 1 - K_TRUE r^2.
K_TRUE = 0.3
CORNER_TOL = 0.03
WORKING_TOL = 0.004
COEF_TOL = 0.01
PLANE = np.array([0.0, 0.0, 1.0, -ps.TABLE_Z])


def _vignetted(views):
    out = []
    for v in views:
        y, x = np.mgrid[0:v.camera.height, 0:v.camera.width]
        r2 = radius2(v.camera, np.stack([x.ravel(), y.ravel()], 1)).reshape(y.shape)
        out.append(PlateView(v.camera, (v.linear * (1.0 - K_TRUE * r2)[..., None]).astype(np.float32),
                             v.object_depth, v.depth))
    return out


@pytest.fixture(scope="module")
def orbit():
    return ps.orbit_capture(12, 192, 144)


def test_a_moving_cameras_vignette_is_measured_and_taken_out(orbit):
    views, truth = orbit
    right, rec_right = background_plates(views, PlateConfig(), PLANE)
    got, rec = background_plates(_vignetted(views), PlateConfig(), PLANE)
    left, rec_off = background_plates(_vignetted(views), PlateConfig(vignetting="off"), PLANE)
    assert rec["mode"] == rec_right["mode"] == "panorama"
    vig = rec["vignetting"]
    assert vig["applied"] and vig["corner"] == pytest.approx(1.0 - K_TRUE, abs=CORNER_TOL), vig
    assert "vignetting" not in rec_off
    err, _ = ps.band_error(views, got, truth)  # the plates of the corrected frames: the scene's own background
    err_right, _ = ps.band_error(views, right, truth)
    assert err <= err_right + WORKING_TOL, (err, err_right)
    dark = [t * vignette_map(v.camera, [-K_TRUE])[..., None] for v, t in zip(views, truth, strict=True)]
    err_off, _ = ps.band_error(views, left, dark)  # left in: each view's plate drawn from its neighbours' radii
    assert err_off > err + WORKING_TOL, (err_off, err)


def test_a_right_orbit_keeps_its_frames(orbit):
    _, rec = background_plates(orbit[0], PlateConfig(), PLANE)
    assert rec["vignetting"]["applied"] is False, rec["vignetting"]


def test_frames_of_two_lenses_are_not_given_one(orbit, monkeypatch):
    """Every other view vignetted (two cameras, one lens corrected): the even and the odd views find different v
    (measured corners 0.96 and 0.73), so no v is taken, even with the z rule switched off."""
    import capture.vignetting as cv

    monkeypatch.setattr(cv, "VIGNETTE_Z", -np.inf)
    views = orbit[0]
    mixed = [v if k % 2 else w for k, (v, w) in enumerate(zip(views, _vignetted(views), strict=True))]
    _, rec = background_plates(mixed, PlateConfig(), PLANE)
    vig = rec["vignetting"]
    assert not vig["applied"] and abs(vig["halves"][0] - vig["halves"][1]) > 0.1 and "disagree" in vig["reason"], vig


def test_a_fixed_camera_is_not_measured():
    views, *_ = ps.turntable_capture(12, 96, 72)
    _, rec = background_plates(views, PlateConfig())
    assert rec["mode"] == "fixed" and "vignetting" not in rec


def test_the_fit_recovers_known_coefficients_through_outliers():
    rng = np.random.default_rng(2)
    V, n, coef = 10, 20000, np.array([-0.25, -0.08])
    u = rng.normal(0, 0.2, V)
    i, j = rng.integers(0, V, n), rng.integers(0, V, n)
    ri, rj = rng.random(n), rng.random(n)
    y = u[j] - u[i] + np.log(vignette(coef, rj) / vignette(coef, ri)) + rng.normal(0, 0.01, n)
    bad = rng.random(n) < 0.1
    y[bad] += rng.uniform(-1, 1, bad.sum())
    got, u_got = fit({"y": y, "i": i, "j": j, "ri": ri, "rj": rj}, V, 2)
    assert np.abs(got - coef).max() < COEF_TOL, got
    assert np.abs((u_got - u_got.mean()) - (u - u.mean())).max() < COEF_TOL


def test_devignette_view_divides_the_linear_colour_by_v():
    cam = Camera(make_K(60.0, 60.0, 39.5, 29.5), np.eye(4), 80, 60)
    rgb = np.random.default_rng(0).integers(20, 200, (60, 80, 3)).astype(np.uint8)
    out, _ = devignette_view(Scan(rgb, np.ones((60, 80), np.float32), cam), 0, [-K_TRUE])
    want = srgb_to_linear(rgb / np.float32(255)) / vignette_map(cam, [-K_TRUE])[..., None]
    got = srgb_to_linear(out.rgb / np.float32(255))
    assert out.rgb.dtype == np.uint8
    assert np.abs(got - np.minimum(want, 1.0)).max() <= 0.01  # one 8-bit sRGB step at the brightest
    assert np.array_equal(out.rgb[29:31, 39:41], rgb[29:31, 39:41])  # the centre stays


def test_the_callers_views_are_left_as_they_were(orbit):
    """background_plates divides copies of the views by v, not the arrays it was given (a float Scan's linear_rgb
    is its own colour array)."""
    views = _vignetted(orbit[0])
    before = [v.linear.copy() for v in views]
    _, rec = background_plates(views, PlateConfig(), PLANE)
    assert rec["vignetting"]["applied"]
    assert all(np.array_equal(v.linear, b) for v, b in zip(views, before, strict=True))

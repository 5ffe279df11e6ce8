"""The RGB-D sensor traits do what they claim, measured (datasets_synthetic/sensor.py)."""

from __future__ import annotations

import numpy as np
import pytest

from datasets_synthetic.sensor import (
    SENSORS,
    SensorModel,
    apply_sensor,
    discontinuity_mask,
    flying_pixels,
    quantise_disparity,
    quantise_unit,
    sensor_preset,
)

#: Relative tolerance on measured rates / standard deviations (sampling error ~1-3 %).
STAT_RTOL = 0.08


def _step_image(near=0.40, far=0.45, H=120, W=160):
    """A vertical depth edge: near plane on the left half, far plane on the right, a hole row."""
    d = np.full((H, W), far, np.float32)
    d[:, : W // 2] = near
    d[:5] = 0.0
    return d


def test_flying_pixels_sit_on_edges_between_the_two_depths():
    d = _step_image()
    edge = discontinuity_mask(d, 0.005)
    cols = np.nonzero(edge[60])[0]
    assert list(cols) == [79, 80]  # the two columns beside the step, nothing else
    assert not edge[:5].any()  # empty pixels are never candidates without a backdrop
    rng = np.random.default_rng(0)
    out = flying_pixels(d, rng, 0.3, 0.005)
    moved = out != d
    assert not moved[~edge].any()
    frac = moved[edge].mean()
    assert abs(frac / 0.3 - 1) < STAT_RTOL * 2, frac  # ~230 edge pixels
    assert np.all((out[moved] > 0.40) & (out[moved] < 0.45))
    # uniform between the two: mean halfway
    assert abs(out[moved].mean() - 0.425) < 0.004


def test_backdrop_pulls_silhouettes_and_empty_pixels():
    d = np.zeros((60, 80), np.float32)
    d[20:40, 20:40] = 0.4
    out = flying_pixels(d, np.random.default_rng(1), 1.0, 0.005, backdrop_m=0.9)
    ring = discontinuity_mask(d, 0.005, backdrop_m=0.9)
    assert ring.sum() == (20 * 20 - 18 * 18) + (22 * 22 - 20 * 20)  # both sides of the outline
    assert (out[ring] > 0.4).all() and (out[ring] < 0.9).all()
    assert (out[(d == 0) & ring] > 0).all()  # empty pixels beside the object now hold a flying depth
    assert (out[~ring] == d[~ring]).all()


def test_z_squared_noise_of_the_presets():
    for name in ("d435", "kinect-v1"):
        s = sensor_preset(name, flying_fraction=0.0, depth_unit_m=0.0, disparity_step_at_1m=0.0)
        for z in (0.4, 0.8):
            d = np.full((200, 200), z, np.float32)
            diff = apply_sensor(d, np.random.default_rng(2), s).astype(np.float64) - z
            assert abs(diff.std() / (s.sigma_at_1m * z * z) - 1) < STAT_RTOL, (name, z, diff.std())
    # D435: 0.08 px subpixel over f B (447 px, 50 mm): about 3.6 mm at 1 m
    assert 3.5e-3 < SENSORS["d435"].sigma_at_1m < 3.7e-3


def test_disparity_quantisation_steps_grow_with_z_squared():
    c = SENSORS["kinect-v1"].disparity_step_at_1m
    for z0 in (0.6, 1.5, 4.0):
        z = np.linspace(z0, z0 * 1.05, 20000).astype(np.float32)[None]
        q = np.unique(quantise_disparity(z, c))
        step = np.median(np.diff(q))
        assert abs(step / (c * z0 * z0) - 1) < 0.06, (z0, step, c * z0 * z0)
    assert quantise_disparity(np.zeros((2, 2)), c).max() == 0


def test_unit_quantisation_keeps_measurements():
    d = np.array([[0.0, 0.0004, 0.4003, 0.4006]], np.float32)
    q = quantise_unit(d, 1e-3)
    np.testing.assert_allclose(q, [[0.0, 0.001, 0.400, 0.401]], atol=1e-7)


def test_default_sensor_output_is_millimetres_and_deterministic():
    d = _step_image()
    a = apply_sensor(d, np.random.default_rng(3), SENSORS["d435"])
    b = apply_sensor(d, np.random.default_rng(3), SENSORS["d435"])
    assert np.array_equal(a, b)
    mm = a[a > 0] / 1e-3
    np.testing.assert_allclose(mm, np.round(mm), atol=1e-3)
    assert np.array_equal(a > 0, d > 0)
    assert np.array_equal(apply_sensor(d, np.random.default_rng(3), SENSORS["ideal"]), d)


def test_sensor_validation():
    with pytest.raises(ValueError, match="flying_fraction"):
        SensorModel(flying_fraction=1.5)
    with pytest.raises(ValueError, match="sigma_at_1m"):
        SensorModel(sigma_at_1m=-1)
    with pytest.raises(ValueError, match="unknown sensor"):
        sensor_preset("kinect-v9")

"""The path tracer's film filter (datasets_synthetic/pixel_filter.py)."""

from __future__ import annotations

import numpy as np

from datasets_synthetic.pixel_filter import BOX_VARIANCE_PX2, path_tracer_filter, residual_sigma


def test_box_plus_residual_is_the_requested_gaussian():
    img = np.zeros((41, 41, 3), np.float32)
    img[20, 20] = [1.0, 2.0, 3.0]
    out = path_tracer_filter(img, 0.5)
    np.testing.assert_allclose(out.sum((0, 1)), [1, 2, 3], rtol=1e-5)  # energy kept away from the border
    w = out[..., 0] / out[..., 0].sum()
    y, x = np.mgrid[0:41, 0:41]
    var_x = (w * (x - 20) ** 2).sum()
    # the residual Gaussian on a pixel grid: its variance plus the box's is 0.5^2
    assert abs(var_x + BOX_VARIANCE_PX2 - 0.25) < 1e-5, var_x
    assert np.isclose(residual_sigma(0.5), np.sqrt(0.25 - 1 / 12))


def test_no_filter_at_or_below_the_box():
    img = np.random.default_rng(0).uniform(size=(8, 9, 3)).astype(np.float32)
    assert np.array_equal(path_tracer_filter(img, 0.0), img)
    assert np.array_equal(path_tracer_filter(img, 0.28), img)

"""The compiled gathering of a frame's plate samples (capture.plate_gather) against the numpy passes,
its reference: equal bit for bit (weights, colours times the gain, blown-out flags; NaN colours)."""

from __future__ import annotations

import numpy as np
import pytest

from capture import plate_gather
from capture.plate_gather import gather_frame, gather_frame_reference


def _frame(seed):
    rng = np.random.default_rng(seed)
    H, W, N = 40, 50, 600
    linear = rng.random((H, W, 3)).astype(np.float32)
    linear[rng.random((H, W)) < 0.1] = 0.99  # blown out
    linear[3, :, 1] = np.nan  # a row with a NaN channel
    weight = np.where(rng.random((H, W)) < 0.3, 0.0, rng.random((H, W))).astype(np.float32)
    y, x = rng.integers(0, H, N), rng.integers(0, W, N)
    y[:20] = 3
    return linear, weight, y, x, rng.random(3) + 0.5


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("gain_dtype", [np.float64, np.float32])
def test_compiled_gather_equals_the_reference(seed, gain_dtype):
    linear, weight, y, x, gain = _frame(seed)
    gain = gain.astype(gain_dtype)
    outs = []
    for fn in (gather_frame, gather_frame_reference):
        s = np.full((2, len(y), 3), np.nan, np.float32)
        w = np.zeros((2, len(y)), np.float32)
        hot = np.zeros((2, len(y)), bool)
        fn(linear, weight, y, x, gain, 0.975, s[1], w[1], hot[1])
        outs.append((s, w, hot))
    (s1, w1, h1), (s2, w2, h2) = outs
    np.testing.assert_array_equal(s1, s2)  # NaN where the weight is 0, as the reference leaves it
    np.testing.assert_array_equal(w1, w2)
    np.testing.assert_array_equal(h1, h2)
    assert h1[1].any() and not h1[0].any() and np.isnan(s1[0]).all()  # the test can fail
    assert (w1[1] > 0).any() and np.isnan(s1[1][w1[1] <= 0]).all()


def test_switch_off_is_the_reference(monkeypatch):
    linear, weight, y, x, gain = _frame(3)
    monkeypatch.setattr(plate_gather, "GATHER_COMPILED", False)
    s = np.full((len(y), 3), np.nan, np.float32)
    w, hot = np.zeros(len(y), np.float32), np.zeros(len(y), bool)
    gather_frame(linear, weight, y, x, gain, 0.975, s, w, hot)
    s2, w2, h2 = s.copy() * np.nan, np.zeros_like(w), np.zeros_like(hot)
    gather_frame_reference(linear, weight, y, x, gain, 0.975, s2, w2, h2)
    np.testing.assert_array_equal(s, s2)
    np.testing.assert_array_equal(hot, h2)

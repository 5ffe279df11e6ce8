"""The compiled multilevel foreground (capture.foreground_ml) against pymatting's, its reference:
equal bit for bit (the same float32 / float64 arithmetic in the same order)."""

from __future__ import annotations

import numpy as np
import pytest
from pymatting import estimate_foreground_ml as reference

from capture import foreground_ml
from capture.foreground_ml import estimate_foreground_ml


@pytest.mark.parametrize("shape", [(2, 2), (2, 7), (31, 33), (64, 17), (97, 130)])
@pytest.mark.parametrize("seed", [0, 1])
def test_equal_to_pymatting_bit_for_bit(shape, seed):
    rng = np.random.default_rng(seed)
    img = rng.random((*shape, 3))
    alpha = np.clip(rng.random(shape) * 1.6 - 0.3, 0.0, 1.0)  # opaque, background and partial pixels
    got = estimate_foreground_ml(img, alpha)
    want = reference(img, alpha)
    assert got.dtype == want.dtype == np.float32
    np.testing.assert_array_equal(got, want)


def test_a_matte_like_alpha_and_the_switch(monkeypatch):
    """A smooth disc with a soft edge on a textured image (the case the matte gives it), float64
    inputs; COMPILED off hands back pymatting's own."""
    rng = np.random.default_rng(2)
    yy, xx = np.mgrid[:120, :150]
    alpha = np.clip((40.0 - np.hypot(yy - 60, xx - 70)) / 6.0, 0.0, 1.0)
    img = np.clip(alpha[..., None] * [0.2, 0.6, 0.1] + (1 - alpha[..., None]) * rng.random((120, 150, 3)), 0, 1)
    want = reference(img, alpha)
    np.testing.assert_array_equal(estimate_foreground_ml(img, alpha), want)
    assert np.abs(want[60, 70] - [0.2, 0.6, 0.1]).max() < 0.05  # the test can fail: the disc's colour
    monkeypatch.setattr(foreground_ml, "COMPILED", False)
    np.testing.assert_array_equal(estimate_foreground_ml(img, alpha), want)

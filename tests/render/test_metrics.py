"""Image metrics against hand-computed values."""

from __future__ import annotations

import numpy as np
import pytest

from render import metrics


def test_psnr_by_hand():
    a = np.zeros((8, 8, 3), np.uint8)
    b = a.copy()
    b[0, 0, 0] = 255  # one value off by 255 out of 192: mse = 255^2 / 192
    assert metrics.psnr(a, b) == pytest.approx(10 * np.log10(192.0))
    mask = np.zeros((8, 8), bool)
    mask[0, :2] = True  # 6 values, one off by 255
    assert metrics.psnr(a, b, mask) == pytest.approx(10 * np.log10(6.0))
    assert metrics.psnr(a, a) == metrics.PSNR_IDENTICAL
    assert np.isnan(metrics.psnr(a, b, np.zeros((8, 8), bool)))


def test_psnr_uses_8bit_srgb_of_linear_input():
    lin = np.full((4, 4, 3), 0.214, np.float32)  # sRGB ~ 0.5
    a8 = metrics.as_srgb8(lin)
    assert a8.dtype == np.uint8 and abs(int(a8[0, 0, 0]) - 128) <= 1
    assert metrics.psnr(lin, a8) == metrics.PSNR_IDENTICAL


def test_ssim_identical_and_masked():
    rng = np.random.default_rng(0)
    a = rng.integers(0, 256, (32, 32, 3), dtype=np.uint8)
    assert metrics.ssim(a, a) == pytest.approx(1.0)
    b = a.copy()
    b[:, 16:] = 0
    mask = np.zeros((32, 32), bool)
    mask[:, :8] = True  # far from the damaged half (window 7)
    assert metrics.ssim(a, b, mask) == pytest.approx(1.0)
    assert metrics.ssim(a, b) < 0.8


def test_hole_fraction_and_largest_hole():
    ref = np.zeros((20, 20), bool)
    ref[2:18, 2:18] = True  # 256 px
    ren = ref.copy()
    ren[8:11, 8:11] = False  # a 3x3 interior hole
    ren[2, 2:6] = False  # silhouette disagreement (eroded away)
    assert metrics.hole_fraction(ref, ren) == pytest.approx(13 / 256)
    assert metrics.largest_interior_hole(ref, ren) == 9
    assert metrics.hole_fraction(np.zeros((3, 3), bool), ren[:3, :3]) == 0.0


def test_compare_keys():
    a = np.zeros((16, 16, 3), np.float32)
    a[4:12, 4:12] = 0.5
    out = metrics.compare(a, a)
    assert set(out) == {"psnr", "ssim", "psnr_masked", "ssim_masked", "hole_fraction", "largest_hole"}
    assert out["psnr"] == metrics.PSNR_IDENTICAL and out["hole_fraction"] == 0.0

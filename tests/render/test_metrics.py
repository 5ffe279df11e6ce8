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
    assert set(out) == {"psnr", "ssim", "psnr_masked", "ssim_masked", "sharpness", "hole_fraction", "largest_hole"}
    assert out["psnr"] == metrics.PSNR_IDENTICAL and out["hole_fraction"] == 0.0 and out["sharpness"] == 1.0


def test_laplacian_rms_by_hand():
    """One bright grey pixel v in a black image: the 5-point Laplacian is -4 v there and v at its
    four neighbours, 0 elsewhere."""
    img = np.zeros((9, 9, 3), np.uint8)
    img[4, 4] = 100  # grey 100 (the luma weights sum to 1)
    mask = np.zeros((9, 9), bool)
    mask[3:6, 3:6] = True  # the pixel, its 4 neighbours and 4 diagonal zeros
    expect = np.sqrt((400.0 ** 2 + 4 * 100.0 ** 2) / 9)
    assert metrics.laplacian_rms(img, mask) == pytest.approx(expect, rel=1e-3)
    assert np.isnan(metrics.laplacian_rms(img, np.zeros((9, 9), bool)))


def test_sharpness_ratio_falls_with_blur_and_rises_with_noise():
    from scipy import ndimage

    rng = np.random.default_rng(3)
    ref = (ndimage.gaussian_filter(rng.uniform(0, 1, (64, 64)), 1.0) * 255).astype(np.uint8)
    ref = np.repeat(ref[..., None], 3, -1)
    mask = np.ones((64, 64), bool)
    blur = ndimage.gaussian_filter(ref.astype(float), (0.8, 0.8, 0)).round().astype(np.uint8)
    noisy = np.clip(ref + rng.normal(0, 8, ref.shape[:2])[..., None], 0, 255).astype(np.uint8)
    assert metrics.sharpness_ratio(ref, ref, mask) == 1.0
    assert metrics.sharpness_ratio(ref, blur, mask) < 0.8
    assert metrics.sharpness_ratio(ref, noisy, mask) > 1.25
    assert np.isnan(metrics.sharpness_ratio(np.zeros_like(ref), ref, mask))


def test_side_by_side_layout():
    from render.evaluate import ERROR_GAIN, side_by_side

    ref = np.full((48, 64, 3), 100, np.uint8)
    a = ref.copy()
    a[40:, 40:] = 110  # off by 10 in the corner (below the labels)
    sheet = side_by_side(ref, {"a": a, "b": ref})
    assert sheet.shape == (96, 192, 3)
    np.testing.assert_array_equal(sheet[40:48, 104:128], 110)  # panel "a", top row
    np.testing.assert_array_equal(sheet[48 + 40:, 64 + 40:128], int(10 * ERROR_GAIN))  # its error, bottom row
    np.testing.assert_array_equal(sheet[48 + 30:, 128 + 30:], 0)  # "b" equals the reference

"""capture.plate_weight: the sample weights on the object's box against the whole frame's (bit for bit)."""

import numpy as np
import pytest
from scipy import ndimage

from capture.matting_scale import object_box
from capture.plate import SOURCE_BAND_FRACTION, px
from capture.plate_fixed import FIXED_EXCLUDE_FRACTION, _near_weight, fixed_sample_weight
from capture.plate_weight import near_weight_box


def _masks(shape):
    """Masks that stress the box: an object, one near each border and corner, scattered needles, one
    pixel, a dense random mask, none, all."""
    rng = np.random.default_rng(9)
    H, W = shape
    out = [np.zeros(shape, bool) for _ in range(9)]
    out[0][H // 3:H // 2, W // 2:W // 2 + 60] = True
    out[1][:40, W - 30:] = True
    out[2][H - 1, 0] = True
    out[3][rng.random(shape) < 2e-4] = True
    out[4][H // 2, W // 2] = True
    out[5] = rng.random(shape) < 0.3
    out[7][:] = True
    out[8][5:9, 3:H] = True  # within the band of the left and top borders
    return out


@pytest.mark.parametrize("shape", [(960, 1280), (894, 1192), (61, 83)])
def test_box_weights_equal_the_whole_frames(shape):
    """near_weight_box equals plate_fixed._near_weight (and so scipy's reference) bit for bit."""
    W = shape[1]
    band, exclude = px(SOURCE_BAND_FRACTION, W), px(FIXED_EXCLUDE_FRACTION, W)
    for m in _masks(shape):
        got, want = near_weight_box(m, band, exclude), _near_weight(m, band, exclude)
        assert got.dtype == want.dtype == np.float32
        np.testing.assert_array_equal(got, want)
        if m.any():
            d = ndimage.distance_transform_edt(~m)
            ref = np.where(d > exclude, np.clip(d / band, 0.0, 1.0), 0.0).astype(np.float32)
            np.testing.assert_array_equal(got, ref)


def test_box_margin_matters():
    """A box one band too tight gives different weights (the test above can fail)."""
    import capture.plate_weight as pw

    m = np.zeros((200, 300), bool)
    m[90:110, 140:160] = True
    band, exclude = 15, 4
    keep = pw.BOX_MARGIN_PX
    try:
        pw.BOX_MARGIN_PX = -band + 2
        assert not np.array_equal(near_weight_box(m, band, exclude), _near_weight(m, band, exclude))
    finally:
        pw.BOX_MARGIN_PX = keep


def test_object_box_and_the_switch():
    """object_box holds every True widened and clipped; fixed_sample_weight takes the box by default
    and the whole frame with WEIGHT_BOX off, the same values."""
    import capture.plate_weight as pw

    m = np.zeros((50, 70), bool)
    m[3, 60] = m[20, 10] = True
    rows, cols = object_box(m, 5)
    assert (rows.start, rows.stop, cols.start, cols.stop) == (0, 26, 5, 66)
    assert object_box(np.zeros((4, 4), bool), 2) is None
    depth = np.where(m, 1.0, 0.0).astype(np.float32)
    on = fixed_sample_weight(depth)
    try:
        pw.WEIGHT_BOX = False
        off = fixed_sample_weight(depth)
    finally:
        pw.WEIGHT_BOX = True
    np.testing.assert_array_equal(on, off)


@pytest.mark.parametrize("shape", [(960, 1280), (894, 1192), (48, 64)])
def test_need_by_one_dilation_equals_the_trimaps(shape):
    """capture.plate.need_mask by one dilation equals the trimap's path (fast=False), bit for bit, on
    masks at the borders, in corners, scattered, dense, empty and full; one dilation too few differs."""
    from capture.matting import BAND_FRACTION, _px
    from capture.matting_fast import dilate
    from capture.matting_known import widen_px
    from capture.plate import need_mask

    for m in _masks(shape):
        depth = np.where(m, 1.25, 0.0).astype(np.float32)
        want = need_mask(depth, fast=False)
        np.testing.assert_array_equal(need_mask(depth, fast=True), want)
        if m.any() and not want.all():
            W = shape[1]
            assert not np.array_equal(dilate(m, _px(BAND_FRACTION, W) + widen_px(W) - 1), want)

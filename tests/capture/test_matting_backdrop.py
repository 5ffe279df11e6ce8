"""The plain-backdrop test counted on an 8-bit view's codes (capture.matting_backdrop) against the
test on its linear colour (capture.matting.detect_backdrop's numpy path): the same answer bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

import capture.matting as matting
from capture.matting import BG, FG, UNKNOWN, detect_backdrop
from capture.scan import srgb8_to_linear


def _both(rgb8, tri, monkeypatch):
    monkeypatch.setattr(matting, "BACKDROP_CODES", False)
    ref = detect_backdrop(srgb8_to_linear(rgb8), tri)
    monkeypatch.setattr(matting, "BACKDROP_CODES", True)
    got = detect_backdrop(srgb8_to_linear(rgb8), tri, rgb8)
    return ref, got


def _scene(rng, h, w, colour, spread, clutter):
    """A backdrop of ``colour`` (codes) with +-``spread`` code noise, ``clutter`` of its pixels random,
    an object disc in the middle (its trimap: FG inside, UNKNOWN on a ring, BG outside)."""
    rgb = np.clip(np.asarray(colour)[None, None] + rng.integers(-spread, spread + 1, (h, w, 3)), 0, 255)
    junk = rng.uniform(size=(h, w)) < clutter
    rgb[junk] = rng.integers(0, 256, (int(junk.sum()), 3))
    yy, xx = np.mgrid[:h, :w]
    r = np.hypot(yy - h / 2, xx - w / 2)
    tri = np.where(r < h / 4, FG, np.where(r < h / 4 + 3, UNKNOWN, BG))
    return rgb.astype(np.uint8), tri


@pytest.mark.parametrize("size", [(48, 64), (49, 63), (120, 90)])
@pytest.mark.parametrize("colour,spread,clutter", [((20, 20, 20), 2, 0.0), ((240, 240, 240), 3, 0.01),
                                                   ((30, 200, 40), 1, 0.019), ((30, 200, 40), 1, 0.03),
                                                   ((0, 0, 0), 0, 0.0), ((255, 255, 255), 0, 0.5),
                                                   ((128, 128, 128), 40, 0.0), ((128, 60, 10), 12, 0.02)])
def test_codes_give_the_same_backdrop_bit_for_bit(size, colour, spread, clutter, monkeypatch):
    rng = np.random.default_rng(sum(size) + sum(colour) + spread)
    rgb8, tri = _scene(rng, *size, colour, spread, clutter)
    ref, got = _both(rgb8, tri, monkeypatch)
    assert (ref is None) == (got is None)
    if ref is not None:
        assert got.dtype == ref.dtype and np.array_equal(got, ref)


def test_both_answers_occur_and_the_median_of_an_even_count_is_numpys(monkeypatch):
    """The cases above include a plain backdrop and a room; an even count whose two middle codes
    differ takes numpy's float32 mean of the two (a median of one of them would differ)."""
    rng = np.random.default_rng(0)
    rgb8, tri = _scene(rng, 48, 64, (20, 20, 20), 2, 0.0)
    assert _both(rgb8, tri, monkeypatch)[0] is not None
    rgb8, tri = _scene(rng, 48, 64, (128, 128, 128), 40, 0.0)
    assert _both(rgb8, tri, monkeypatch)[0] is None
    rgb8 = np.zeros((4, 8, 3), np.uint8)
    rgb8[:2] = 10
    rgb8[2:] = 11  # 16 background pixels: 16 of code 10, 16 of code 11
    tri = np.full((4, 8), BG)
    ref, got = _both(rgb8, tri, monkeypatch)
    assert np.array_equal(got, ref)
    lut = srgb8_to_linear(np.array([10, 11], np.uint8))
    assert ref[0] != lut[0] and ref[0] != lut[1]


def test_too_few_background_pixels_give_none(monkeypatch):
    rgb8 = np.full((4, 4, 3), 50, np.uint8)
    tri = np.full((4, 4), FG)
    tri[0, :3] = BG
    assert _both(rgb8, tri, monkeypatch) == (None, None)


def test_codes_of_another_shape_are_refused(monkeypatch):
    rgb8, tri = _scene(np.random.default_rng(3), 48, 64, (20, 20, 20), 2, 0.0)
    monkeypatch.setattr(matting, "BACKDROP_CODES", True)
    with pytest.raises(ValueError, match="not the image's"):
        detect_backdrop(srgb8_to_linear(rgb8), tri, rgb8[:, :32])

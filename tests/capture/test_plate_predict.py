"""capture.plate_predict: the fixed camera's compiled prediction against plate_fixed's numpy path (bit for bit)."""

from types import SimpleNamespace

import numpy as np
import pytest

from capture import plate_fixed as pf
from capture import plate_predict as pp
from capture.matting_known import CLIP_LEVEL


def _frames(seed, K=24, H=23, W=31, special=True):
    """K frames of float16 colour around one background per pixel: noise, a needle colour in some
    frames, 8-bit-like quantised values full of ties, blown-out samples, zero weights, and (``special``)
    NaN, +-inf, negative and above-1 codes."""
    rng = np.random.default_rng(seed)
    bg = rng.uniform(0.02, 1.0, (H, W, 3))
    gains = rng.uniform(0.8, 1.25, (K, 3))
    gains[0] = 1.0
    share = rng.uniform(0.0, 0.6, (H, W))  # of a second cluster per pixel: up to as heavy as the first
    views, weights = [], []
    for k in range(K):  # the background in each frame's exposure (colour x gain = bg), with noise
        c = bg / gains[k] + rng.normal(0, 0.002, (H, W, 3))
        needle = rng.random((H, W)) < 0.3
        c[needle] = rng.uniform(0, 0.6, 3)
        half = rng.random((H, W)) < share  # the second cluster: ambiguous pixels where it is heavy
        c[half] = np.clip(bg[half] + 0.05, 0, None)
        q = rng.random((H, W)) < 0.3
        c[q] = np.round(c[q] * 255) / 255
        c[rng.random((H, W)) < 0.05] = 1.0  # blown out
        c = c.astype(np.float16)
        if special:
            for val in (np.nan, np.inf, -np.inf, -0.25, 1.7, -0.0):
                c[rng.random((H, W)) < 0.01, rng.integers(0, 3)] = val
        w = np.where(rng.random((H, W)) < 0.15, 0.0, rng.uniform(0.05, 1.0, (H, W))).astype(np.float32)
        w[rng.random((H, W)) < 0.3] = 1.0
        views.append(SimpleNamespace(linear=c))
        weights.append(w)
    yy, xx = np.mgrid[:H, :W]
    pix = np.stack([xx.ravel(), yy.ravel()], axis=1)
    return views, weights, gains, pix


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("chunk", [8000, 7])
def test_fused_prediction_equals_fixed_prediction(seed, chunk, monkeypatch):
    """fused_prediction's colour and bound equal fixed_prediction's bit for bit (NaN, inf, ties,
    ambiguous pixels, bounds), for every frame and for a subset in a shuffled order, in chunks."""
    monkeypatch.setattr(pp, "FUSED_CHUNK", chunk)
    views, weights, gains, pix = _frames(seed)
    for frames in ([5, 3, 17, 0, 9, 11, 2, 21], list(range(len(views)))):
        want = pf.fixed_prediction(views, pix, None, gains, weights, frames)
        got = pp.fused_prediction(views, pix, gains, weights, frames)
        assert got[0].dtype == want[0].dtype == np.float32 and got[1].dtype == want[1].dtype
        np.testing.assert_array_equal(got[0].view(np.uint32), want[0].view(np.uint32))
        np.testing.assert_array_equal(got[1], want[1])
    col = want[0][:, 0]
    assert want[1].any() and np.isnan(col).any() and np.isfinite(col).mean() > 0.3  # bounds, unknown, kept


def test_the_case_holds_ambiguous_pixels_and_the_test_can_fail(monkeypatch):
    """The scene has pixels the rival cluster makes unknown (without the rival's check they would be
    kept: the rival's sum and its shortcut are exercised), and another tolerance gives other values."""
    views, weights, gains, pix = _frames(1, special=False)
    frames = list(range(len(views)))
    want = pp.fused_prediction(views, pix, gains, weights, frames)
    monkeypatch.setattr(pf, "MODE_AMBIGUOUS", 10.0)  # no rival ever heavy enough
    loose = pp.fused_prediction(views, pix, gains, weights, frames)
    assert (np.isnan(want[0][:, 0]) & np.isfinite(loose[0][:, 0])).sum() > 5
    monkeypatch.setattr(pf, "MODE_AMBIGUOUS", 0.5)
    monkeypatch.setattr(pf, "MODE_TOL", 2 / 255)
    assert not np.array_equal(pp.fused_prediction(views, pix, gains, weights, frames)[0], want[0], equal_nan=True)


def test_srgb_table_and_hot_codes_are_the_samples():
    """Each non-negative float16 code's table entry is linear_to_srgb of its sample in the common
    exposure, and hot_codes is the float16 comparison with the clip level."""
    from capture.scan import linear_to_srgb

    g = np.array([0.83, 1.0, 1.31])
    codes = np.arange(0, 0x7C01, 37, dtype=np.uint16)
    c = codes.view(np.float16)
    want = linear_to_srgb(np.fmax((c[:, None] * g[None]).astype(np.float32), 0.0)).T
    np.testing.assert_array_equal(pp.srgb_table(g)[:, codes], want)
    hot = pp.hot_codes()
    assert hot[np.float16(CLIP_LEVEL).view(np.uint16)] and not hot[np.float16(0.5).view(np.uint16)]
    assert not hot[np.array(np.nan, np.float16).view(np.uint16)]


def test_applies_only_where_the_values_are_the_same(monkeypatch):
    """The fused path is taken for float16 views, float64 gains and float32 weights, and not otherwise."""
    views, weights, gains, _ = _frames(0, K=4)
    assert pp.applies(views, gains, weights)
    assert not pp.applies([SimpleNamespace(linear=v.linear.astype(np.float32)) for v in views], gains, weights)
    assert not pp.applies(views, gains.astype(np.float32), weights)
    assert not pp.applies(views, gains, None)
    monkeypatch.setattr(pf, "FIXED_CENSOR_CLIPPED", False)
    assert not pp.applies(views, gains, weights)


def test_background_plates_the_same_with_the_fused_prediction(monkeypatch):
    """The whole plate stage on a turntable with auto exposure and float16 colour (as the pipeline
    gives it): the same plates and record bit for bit with FUSED_PREDICTION on and off."""
    from dataclasses import replace

    from capture.plate import PlateConfig, background_plates
    from scripts.plate_stage_sha import plates_sha1
    from tests import plate_scenes as ps

    gains = np.exp(np.random.default_rng(3).normal(0.0, 0.25, (12, 3)))
    views, _, _, _ = ps.turntable_capture(gains=gains)
    views = [replace(v, linear=v.linear.astype(np.float16)) for v in views]
    calls = []
    fused = pp.fused_prediction
    monkeypatch.setattr(pp, "fused_prediction", lambda *a: calls.append(1) or fused(*a))
    got = background_plates(views, PlateConfig(mode="fixed"), crop=True)
    assert got[1]["mode"] == "fixed" and len(calls) > 3 * 12  # the rings three times, and the drawing
    monkeypatch.setattr(pp, "FUSED_PREDICTION", False)
    want = background_plates(views, PlateConfig(mode="fixed"), crop=True)
    assert plates_sha1(*got) == plates_sha1(*want)

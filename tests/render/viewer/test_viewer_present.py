"""The viewer's fast 8-bit conversion (render.viewer.present.srgb8) against its reference
capture.scan.to_uint8_srgb: at most SRGB8_TOLERANCE code apart, equal on the table's steps and on
almost every value."""

from __future__ import annotations

import numpy as np

from capture.scan import to_uint8_srgb
from render.viewer.present import LUT_SIZE, SRGB8_TOLERANCE, srgb8, srgb8_table

#: Share of uniformly spread linear values whose code may differ by one (the reference's rounding
#: threshold between two table steps): measured 0.23 %.
MAX_OFF_SHARE = 0.005


def test_srgb8_matches_the_reference_within_one_code():
    rng = np.random.default_rng(7)
    # a frame-like spread: dark-heavy values, exact 0 and 1, out-of-range values both sides
    x = np.concatenate([rng.random(200_000) ** 3, rng.random(100_000), [0.0, 1.0, -0.5, 3.0, 1e-7, 0.0031308]])
    x = x.astype(np.float32).reshape(-1, 3)
    got, ref = srgb8(x), to_uint8_srgb(x)
    assert got.dtype == np.uint8 and got.shape == x.shape
    diff = np.abs(got.astype(int) - ref)
    assert diff.max() <= SRGB8_TOLERANCE
    assert (diff > 0).mean() <= MAX_OFF_SHARE
    assert got[-2:].tolist() == ref[-2:].tolist()                 # clipping as the reference


def test_srgb8_is_exact_on_the_table_steps_and_reads_nan_as_black():
    steps = (np.arange(0, LUT_SIZE, 97, dtype=np.float64) / (LUT_SIZE - 1)).astype(np.float32)
    np.testing.assert_array_equal(srgb8(steps), to_uint8_srgb(steps))
    assert srgb8_table().shape == (LUT_SIZE,) and srgb8_table()[0] == 0 and srgb8_table()[-1] == 255
    assert srgb8(np.array([np.nan, np.inf, -np.inf], np.float32)).tolist() == [0, 255, 0]


def test_srgb8_of_a_rendered_frame():
    """A premultiplied frame over black as the viewer sends it: a soft-edged disc of colour."""
    yy, xx = np.mgrid[0:120, 0:160]
    alpha = np.clip(40.0 - np.hypot(xx - 80, yy - 60), 0, 1).astype(np.float32)
    rgb = alpha[..., None] * np.array([0.8, 0.35, 0.05], np.float32) * (0.2 + xx[..., None] / 200.0)
    got, ref = srgb8(rgb.astype(np.float32)), to_uint8_srgb(rgb)
    assert np.abs(got.astype(int) - ref).max() <= SRGB8_TOLERANCE
    assert (got == ref).mean() >= 1 - MAX_OFF_SHARE

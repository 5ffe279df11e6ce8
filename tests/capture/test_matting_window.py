"""Triangulation matting within a window (capture.matting_window) against exact truth.

Pixel scene: one object colour F over a textured known background, coverage uniform in [0.1, 1]:
every window's lines meet at F (measured: largest error 2e-15 where the fit passes, 100 % of the
pixels pass).  Over a plain backdrop the lines meet at B: no colour anywhere.  On the needle scene
(tests/plate_scenes.needle_composite, seed 0, the photo in 8-bit sRGB) the candidate cut the
known-background matte's alpha MSE 0.0036 -> 0.0025 (it is off in the pipeline: docs/matting.md,
issue 30 third round).
"""

from __future__ import annotations

import numpy as np

from capture import matting_known as mk
from capture.matting import depth_trimap
from capture.matting_window import window_foreground, window_foreground_reference
from capture.scan import srgb_to_linear, to_uint8_srgb
from tests import plate_scenes as ps

#: Largest error of the recovered colour on exact data, share of the pixels that must pass.
EXACT_TOL = 1e-6
EXACT_PASS_MIN = 0.2
#: The matte with the candidate: alpha MSE at most this fraction of the one without.
NEEDLE_BEAT = 0.85
#: Fast box sums against the explicit loop.
TWIN_TOL = 1e-9


def _scene(background, seed=0):
    rng = np.random.default_rng(seed)
    F = np.array([0.1, 0.35, 0.05])
    a = rng.uniform(0.1, 1.0, background.shape[:2])[..., None]
    return a * F + (1 - a) * background, F


def test_a_window_of_lines_meets_at_the_object_colour():
    B = ps.room_image(40, 30, seed=3).astype(np.float64)
    C, F = _scene(B)
    Fw = window_foreground(C, B, np.ones(B.shape[:2], bool), 2)
    ok = np.isfinite(Fw[..., 0])
    assert ok.mean() >= EXACT_PASS_MIN
    assert np.abs(Fw[ok] - F).max() <= EXACT_TOL


def test_a_plain_backdrop_gives_no_colour():
    B = np.broadcast_to(np.array([0.2, 0.2, 0.2]), (30, 40, 3)).copy()
    C, _ = _scene(B)
    assert not np.isfinite(window_foreground(C, B, np.ones((30, 40), bool), 2)).any()
    assert not np.isfinite(window_foreground(C, np.zeros_like(B), np.ones((30, 40), bool), 2)).any()


def test_fast_path_matches_the_slow_reference():
    C, B, A, F, D = ps.needle_composite(seed=1)
    sl = (slice(30, 60), slice(40, 80))
    known = np.ones(A.shape, bool)[sl]
    fast = window_foreground(C[sl], B[sl], known, 2)
    slow = window_foreground_reference(C[sl], B[sl], known, 2)
    assert np.array_equal(np.isfinite(fast), np.isfinite(slow))
    assert np.nanmax(np.abs(fast - slow)) <= TWIN_TOL


def test_the_candidate_helps_the_needles(monkeypatch):
    C, B, A, F, D = ps.needle_composite(seed=0)
    C = srgb_to_linear(to_uint8_srgb(C) / np.float32(255.0))
    tri = depth_trimap(D)
    region = (A > 0) | (tri > 0)
    mse = ps.switched_alpha_mse(monkeypatch, mk, "WINDOW_CANDIDATE", C, tri, B, A, D, region)
    assert mse[True] <= NEEDLE_BEAT * mse[False], mse

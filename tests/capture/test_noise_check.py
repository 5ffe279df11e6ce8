"""capture.noise_check: the smoothed frames' plate against the frames' own, on held-back background (issue 30)."""

from __future__ import annotations

import numpy as np

from capture import noise
from capture.noise_check import CHECK_TOL, check_frames, smoothing_check
from capture.plate import PlateConfig, PlateView
from capture.scan import linear_to_srgb, srgb8_to_linear
from tests import plate_scenes as ps


def _codes(views, sigma: float) -> list[np.ndarray]:
    """The views as a camera writes them: 8-bit sRGB with independent noise ``sigma`` steps."""
    out = []
    for i, v in enumerate(views):
        n = np.random.default_rng(200 + i).normal(0.0, sigma, v.linear.shape) if sigma else 0.0
        out.append(np.clip(np.round(linear_to_srgb(v.linear) * 255.0 + n), 0, 255).astype(np.uint8))
    return out


def _both(views, codes, scale: float):
    """(as read, smoothed at ``scale``) PlateView lists of the check's views."""
    idx = check_frames(len(views))
    raw = [PlateView(views[i].camera, srgb8_to_linear(codes[i]), views[i].object_depth, views[i].depth) for i in idx]
    sm = [PlateView(views[i].camera, srgb8_to_linear(noise.smooth_frame(codes[i], scale)), views[i].object_depth,
                    views[i].depth) for i in idx]
    return raw, sm


def test_noisy_frames_pass_the_check():
    """The turntable scene with noise of 3 steps: the smoothed frames' plate predicts the noisy held-back rings
    better than the noisy frames' own by the views' median error (the noise adds alike to both errors), and its RMS
    stays within CHECK_TOL, so the check keeps the smoothing.  (The RMS, swamped by needles the depth misses, as
    CHECK_TOL's comment says, is a tie here that the CPU decides: smoothed lower on the AVX-512 machines of earlier
    stops, 0.06973 against 0.06968 on an AVX2 one in stop 83, where the medians were 0.02365 against 0.02473; the
    test had asked the RMS to fall.)"""
    views, _, _, _ = ps.turntable_capture(n=12, width=128, height=96)
    codes = _codes(views, 3.0)
    got = smoothing_check(*_both(views, codes, noise.smoothing(3.0)), None, None, PlateConfig())
    assert got["mode"] == "fixed" and got["smoothed"], got
    assert got["median_smoothed"] < 0.97 * got["median_raw"], got
    assert got["rms_smoothed"] <= CHECK_TOL * got["rms_raw"], got


def test_a_textured_room_smoothed_fails_the_check():
    """The turntable before a room with pixel-scale grain and no noise, smoothed as if its detail were noise (what the
    frames' own detail asked for before capture.noise.pair_noise): the smoothed plate misses the held-back texture by
    more than CHECK_TOL (the views' median error; their RMS is swamped by needles the depth misses), so the check
    refuses it."""
    w, h = 128, 96
    g = np.random.default_rng(7).standard_normal((h, w, 1)).astype(np.float32)
    room = np.clip(ps.room_image(w, h) * (1 + 0.05 * g), 0.02, 0.95).astype(np.float32)
    views, _, _, _ = ps.turntable_capture(n=12, width=w, height=h, room=room)
    codes = _codes(views, 0.0)
    detail = noise.capture_noise([codes[i] for i in noise.noise_frames(12)])  # no depths: a rough upper reading
    got = smoothing_check(*_both(views, codes, noise.SMOOTH_COLOUR * max(detail, 3.0)), None, None, PlateConfig())
    assert not got["smoothed"] and got["median_smoothed"] > CHECK_TOL * got["median_raw"], got


def test_one_view_is_not_checked():
    """A single view has nothing to hold back against: not checked (the errors None in the record), the measured
    noise stands (smoothed True)."""
    views, _, _, _ = ps.turntable_capture(n=12, width=128, height=96)
    codes = _codes(views, 3.0)
    raw, sm = _both(views, codes, noise.smoothing(3.0))
    got = smoothing_check(raw[:1], sm[:1], None, None, PlateConfig())
    assert got["smoothed"] and got["rms_raw"] is None and got["median_smoothed"] is None, got

"""The frames' sensor noise (capture.noise): measured against the noise added, the smoothing's residual and
edges, and the fixed camera's plate from noisy frames with and without it against the true background."""

from __future__ import annotations

import numpy as np
import pytest

from capture import noise
from capture.plate import PlateConfig, PlateView, background_plates
from capture.scan import linear_to_srgb, srgb8_to_linear
from tests import plate_scenes as ps

#: The noise measured within this fraction of the noise added (an image of 240 x 320 pixels a channel).
MEASURE_TOL = 0.05
#: The orbit's plate from smoothed noisy frames: band error at most this above the clean frames' (linear; measured
#: clean 0.0016, noisy 0.0070, smoothed 0.0063: the panorama's medians already average the noise away).
ORBIT_NOISY_TOL = 0.006
#: A noise-free 8-bit image of smooth content measures at most this (8-bit steps): its rounding is noise of
#: 1 / sqrt(12) = 0.29 steps, which the grouped median reads (0.23 here; the plain median read 0.00).  Far under
#: NOISE_MIN_SIGMA (1), so such frames are read as they are.
CLEAN_MAX = 0.35
#: The smoothed noise of a flat frame at most this fraction of the noise (a 5 x 5 mean would keep 0.2 of it;
#: the colour weights keep more, 0.35 measured at 4 steps, and the 8-bit rounding adds 0.29 steps) ...
SMOOTHED_MAX = 0.4
#: ... and a step of EDGE 8-bit steps (20 sigma at 3) kept within EDGE_TOL steps two pixels beside it.
EDGE = 60.0
EDGE_TOL = 1.0


def _smooth_image(h: int = 240, w: int = 320, seed: int = 0) -> np.ndarray:
    """(H, W, 3) float sRGB codes 0-255 of a smooth textured image: gradients and slow waves, a sharp edge."""
    y, x = np.mgrid[0:h, 0:w] / h
    ph = np.random.default_rng(seed).uniform(0, 2 * np.pi, 3)
    img = np.stack([90 + 60 * np.sin(3 * x + ph[0]) + 20 * y, 120 + 50 * np.cos(4 * y + ph[1]),
                    70 + 40 * np.sin(2 * (x + y) + ph[2])], -1)
    img[:, w // 2:] += 40.0  # an edge: the estimator reads it in a few 2 x 2 blocks only
    return img


def _noisy(img: np.ndarray, sigma: float, seed: int) -> np.ndarray:
    n = np.random.default_rng(seed).normal(0.0, sigma, img.shape)
    return np.clip(np.round(img + n), 0, 255).astype(np.uint8)


@pytest.mark.parametrize("sigma", [1.5, 2.5, 3.0, 3.5, 5.0])  # 2.5 and 3.5: between the plain median's steps
def test_frame_noise_measures_the_noise_added(sigma):
    got = noise.frame_noise(_noisy(_smooth_image(), sigma, seed=int(sigma * 10)))
    assert abs(got - sigma) <= MEASURE_TOL * sigma, (got, sigma)


def test_a_clean_frame_measures_no_noise_and_is_read_as_it_is():
    frames = [_noisy(_smooth_image(seed=s), 0.0, s) for s in range(3)]
    got = noise.capture_noise(frames)
    assert got <= CLEAN_MAX, got
    assert noise.smoothing(got) == 0.0
    assert noise.smooth_frame(frames[0], noise.smoothing(got)) is frames[0]


def test_the_object_is_left_out_of_the_measurement():
    """A clean room with a rough object before it (fur: its texture and a path tracer's noise, here noise of 6 steps
    on two thirds of the frame) measures the room's noise, not the object's; with too little room, none."""
    img = _smooth_image()
    rough = _noisy(img, 6.0, seed=3)
    depth = np.zeros(img.shape[:2], np.float32)
    depth[20:220, 30:290] = 0.5
    frame = np.where((depth > 0)[..., None], rough, _noisy(img, 0.0, seed=0))
    assert noise.frame_noise(frame) > 0.5  # the whole frame sees the object (measured 0.74 on a fur ball)
    assert noise.frame_noise(frame, depth) <= CLEAN_MAX
    assert noise.capture_noise([frame, frame], [depth, depth]) <= CLEAN_MAX
    assert np.isnan(noise.frame_noise(frame, np.ones_like(depth)))


def test_only_8_bit_frames_are_measured():
    assert np.isnan(noise.frame_noise(_smooth_image().astype(np.float32) / 255))
    assert np.isnan(noise.capture_noise([]))
    assert noise.smoothing(float("nan")) == 0.0
    assert noise.noise_frames(100) == sorted(set(noise.noise_frames(100)))
    assert len(noise.noise_frames(100)) == noise.NOISE_FRAMES and noise.noise_frames(3) == [0, 1, 2]


@pytest.mark.parametrize("sigma", [2.0, 4.0])
def test_the_smoothing_averages_the_noise_and_keeps_an_edge_above_it(sigma):
    """A flat frame's noise falls to at most SMOOTHED_MAX of it; a step of EDGE steps between two flat halves
    stays a step: two pixels from it the smoothed frame is within EDGE_TOL steps of each side's level."""
    img = np.full((120, 160, 3), 100.0)
    img[:, 80:] += EDGE
    frame = _noisy(img, sigma, seed=7)
    scale = noise.smoothing(noise.frame_noise(frame))
    assert scale > 0 and noise.smoothing(noise.NOISE_MIN_SIGMA * 0.9) == 0.0
    out = noise.smooth_frame(frame, scale).astype(np.float64)
    assert out.shape == frame.shape
    left, right = out[10:-10, 10:70], out[10:-10, 90:-10]
    assert max(left.std(), right.std()) <= SMOOTHED_MAX * sigma, (left.std(), right.std())
    assert abs(out[10:-10, 77].mean() - 100.0) <= EDGE_TOL and abs(out[10:-10, 82].mean() - 100.0 - EDGE) <= EDGE_TOL


def _frames_8bit(views, sigma: float, smooth: bool) -> list[PlateView]:
    """The turntable's views as a camera writes them (8-bit sRGB, independent noise ``sigma`` steps), read back
    as the plate stage reads them: smoothed by capture.noise where ``smooth`` (the stage's 'auto')."""
    codes = [_noisy(linear_to_srgb(v.linear) * 255.0, sigma, seed=100 + i) for i, v in enumerate(views)]
    scale = noise.smoothing(noise.capture_noise([codes[i] for i in noise.noise_frames(len(codes))])) if smooth else 0
    return [PlateView(v.camera, srgb8_to_linear(noise.smooth_frame(c, scale)), v.object_depth, v.depth)
            for v, c in zip(views, codes, strict=True)]


def test_noisy_turntable_plate_knows_more_of_the_band_smoothed():
    """Noise of 3 steps: the robust mode's clean samples stop agreeing to MODE_TOL, and the band falls to the
    lines' estimate; the smoothed frames give back at least half of what the clean frames knew, more exactly
    than the noisy ones, on a room of sharp-edged 6-pixel blocks (a Gaussian blur failed here: 0.012 -> 0.028)."""
    views, room, _, _ = ps.turntable_capture(n=12, width=128, height=96)
    truth = [room] * len(views)
    res = {}
    for name, sigma, smooth in (("clean", 0.0, False), ("noisy", 3.0, False), ("smoothed", 3.0, True)):
        plates, rec = background_plates(_frames_8bit(views, sigma, smooth), PlateConfig())
        assert rec["mode"] == "fixed", name
        seen = [p.known & ~(p.estimated if p.estimated is not None else False) for p in plates]
        band = [ps.depth_trimap(v.object_depth) == ps.UNKNOWN for v in views]
        share = float(np.mean([(s & b).sum() / b.sum() for s, b in zip(seen, band, strict=True)]))
        res[name] = (ps.band_error(views, plates, truth)[0], share)
    assert res["smoothed"][1] >= res["noisy"][1] + 0.5 * (res["clean"][1] - res["noisy"][1]), res
    assert res["smoothed"][0] <= res["noisy"][0], res


def test_noisy_orbit_plate_is_no_worse_smoothed():
    """The camera moving (the panorama path) reads the smoothed frames too: on the orbit scene with noise of 3 steps
    the plate's band error against the true background is no larger than from the noisy frames, and stays within
    ORBIT_NOISY_TOL (linear) of the clean frames' plate."""
    views, truth = ps.orbit_capture()
    plane = np.array([0.0, 0.0, 1.0, -ps.TABLE_Z])
    err = {}
    for name, sigma, smooth in (("clean", 0.0, False), ("noisy", 3.0, False), ("smoothed", 3.0, True)):
        plates, rec = background_plates(_frames_8bit(views, sigma, smooth), PlateConfig(), plane)
        assert rec["mode"] == "panorama", name
        err[name] = ps.band_error(views, plates, truth)[0]
    assert err["smoothed"] <= err["noisy"] and err["smoothed"] <= err["clean"] + ORBIT_NOISY_TOL, err


def test_noise_note_says_when_the_measurement_cannot_be_trusted():
    """The record's note (capture.noise.noise_note): not measured (NaN) says so; JPEG frames measured under
    NOISE_MIN_SIGMA say they may read low (the finest level reads noise of 3 steps through JPEG quality 90 under 1);
    a PNG capture, or JPEG frames measured noisy, need no note."""
    assert "not measured" in noise.noise_note(float("nan"), ["images/a.png"])
    said = noise.noise_note(0.4, ["images/a.JPG", "images/b.jpeg", "images/c.png"])
    assert said is not None and "JPEG frames (2 of 3)" in said and "read low" in said
    assert noise.noise_note(0.4, ["images/a.png"]) is None
    assert noise.noise_note(2.5, ["images/a.jpg"]) is None


def test_jpeg_and_demosaiced_noise_are_read_at_the_next_scale():
    """Noise of 3 steps saved as JPEG quality 90, or correlated as a demosaicing correlates it (blurred 1 px, scaled
    back to 3 a pixel), reads under a step at the finest level alone, which is why the next level (the 2 x 2 means'
    detail, times 2) is read too: JPEG at least 1.5, the correlated noise within 10 % of 3.  Independent noise reads
    alike at both levels (within 5 %, under COARSE_RATIO), so frame_noise gives the finest as before."""
    import cv2

    rng = np.random.default_rng(3)
    img = _smooth_image()
    noisy = np.clip(np.round(img + rng.normal(0, 3.0, img.shape)), 0, 255).astype(np.uint8)
    ok, buf = cv2.imencode(".jpg", noisy, [cv2.IMWRITE_JPEG_QUALITY, 90])
    assert ok
    jpeg = cv2.imdecode(buf, cv2.IMREAD_UNCHANGED)
    n = cv2.GaussianBlur(rng.normal(0, 3.0, img.shape), (0, 0), 1.0)
    corr = np.clip(np.round(img + n * 3.0 / n.std()), 0, 255).astype(np.uint8)
    for x in (jpeg, corr):
        assert noise._level(x.astype(np.int16), [None], 2) < noise.NOISE_MIN_SIGMA
    assert noise.frame_noise(jpeg) >= 1.5
    assert abs(noise.frame_noise(corr) - 3.0) <= 0.3
    fine, coarse = (noise._level(noisy.astype(np.int16), [None], k) for k in (2, 4))
    assert abs(coarse / fine - 1.0) <= MEASURE_TOL < noise.COARSE_RATIO - 1.0 and noise.frame_noise(noisy) == fine


def test_grouped_median_interpolates_inside_the_integer():
    """Bin k spans k - 0.5 to k + 0.5 (bin 0 from 0): [0, 1, 1, 2] reaches half its count half way into bin 1."""
    assert noise.grouped_median(np.array([0, 1, 1, 2])) == pytest.approx(1.0)
    assert noise.grouped_median(np.array([0, 0, 0, 5])) == pytest.approx(1 / 3)
    assert np.isnan(noise.grouped_median(np.array([], np.int64)))


def _textured_turntable(grain: float = 0.05):
    """The plate scenes' turntable before a room with a per-pixel grain (a multiplicative normal of sd ``grain``):
    texture at the noise's own scale, the same in every frame (the camera does not move)."""
    w, h = 128, 96
    g = np.random.default_rng(7).standard_normal((h, w, 1)).astype(np.float32)
    room = np.clip(ps.room_image(w, h) * (1 + grain * g), 0.02, 0.95).astype(np.float32)
    return ps.turntable_capture(n=12, width=w, height=h, room=room)


def test_a_rooms_texture_is_not_read_as_noise():
    """A fixed camera before a room with pixel-scale grain (no noise): the frames' own fine detail reads like noise
    of more than 3 steps, the noise between frames (pair_noise) under a step, and the capture's noise is the latter,
    so the plate is made from the frames as they are (before: smoothed, its band error 5 x the clean plate's, 0.0023
    -> 0.0112).  With noise of 3 steps added, the capture's noise is measured within 10 % of it."""
    views, room, _, _ = _textured_turntable()
    codes = [_noisy(linear_to_srgb(v.linear) * 255.0, 0.0, seed=0) for v in views]
    picks = noise.noise_frames(len(codes))
    chosen, detail, between = noise.noise_parts([codes[i] for i in picks], [views[i].object_depth for i in picks])
    assert detail > 3.0 and between < noise.NOISE_MIN_SIGMA and chosen == between, (chosen, detail, between)
    assert noise.smoothing(chosen) == 0.0
    noisy = [_noisy(linear_to_srgb(v.linear) * 255.0, 3.0, seed=100 + i) for i, v in enumerate(views)]
    got = noise.capture_noise([noisy[i] for i in picks], [views[i].object_depth for i in picks])
    assert abs(got - 3.0) <= 0.3, got


def test_noise_between_frames_reads_as_the_frames_own_without_texture():
    """Independent noise and no texture: pair_noise and frame_noise agree within 10 % (so the frames' own detail is
    kept as the capture's noise, TEXTURE_RATIO far below)."""
    img = _smooth_image()
    a, b = _noisy(img, 2.5, seed=1), _noisy(img, 2.5, seed=2)
    assert abs(noise.pair_noise(a, b) / noise.frame_noise(a) - 1.0) <= 0.1
    assert np.isnan(noise.pair_noise(a, b[:-2]))

"""Background plates at a working resolution (capture.plate_scale) against the full-size plates and
the true background of the synthetic orbit capture (tests/plate_scenes.py).

Tolerances: the orbit (here at 192x144) has a full-size band error of 0.0003 (tests/capture/
test_plate.py allows 0.004 at 96x72). At half size detail is lost to the resampling alone: the true
background shrunk by area and grown back bilinearly is 0.0021 off in the band. The working plate
must be within the full-size tolerance of that floor (measured 0.0038); its known share may fall by
about a working pixel around the object (measured 0.743 against 0.785).
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from capture.matting import UNKNOWN, depth_trimap
from capture.plate import Plate, PlateConfig, background_plates
from capture.plate_scale import PLATE_BYTES_PER_PIXEL, PLATE_MIN_SCALE, grow_plate, plate_scale, shrink_view
from tests import plate_scenes as ps

#: Band error (median over views of the median largest-channel |plate - truth|, linear) allowed over
#: the resampling floor at half size (the full-size plate's tolerance in tests/capture/test_plate.py).
WORKING_TOL = 0.004
#: The known share of the band at half size may fall by at most this against full size.
KNOWN_LOSS_MAX = 0.15


def _resampling_floor(views, truths, scale: float) -> float:
    """The band error of the true background shrunk by area to ``scale`` and grown back bilinearly."""
    errs = []
    for v, t in zip(views, truths, strict=True):
        H, W = t.shape[:2]
        band = depth_trimap(v.object_depth) == UNKNOWN
        small = cv2.resize(t.astype(np.float32), (round(W * scale), round(H * scale)), interpolation=cv2.INTER_AREA)
        back = cv2.resize(small, (W, H), interpolation=cv2.INTER_LINEAR)
        errs.append(float(np.median(np.abs(back - t).max(axis=-1)[band])))
    return float(np.median(errs))




def test_scale_follows_the_memory_budget():
    assert plate_scale(18, 480, 640) == 1.0
    s = plate_scale(200, 1440, 1920)
    assert s == pytest.approx(np.sqrt((1 << 30) / (200 * 1440 * 1920 * PLATE_BYTES_PER_PIXEL)))
    assert 200 * (1440 * s) * (1920 * s) * PLATE_BYTES_PER_PIXEL <= (1 << 30) * 1.001
    assert plate_scale(10 ** 6, 1440, 1920) == PLATE_MIN_SCALE


def test_a_view_shrunk_by_less_than_the_full_scale_level_stays_full_size(monkeypatch):
    """PLATE_FULL_SCALE: 72 views at 1280x960 need 0.93 by the budget and get 1; just below the level (views whose
    budget scale is 0.89) the budget's scale stands; with the level at 1 the budget alone (the rule before)."""
    import capture.plate_scale as psc

    budget_72 = np.sqrt((1 << 30) / (72 * 960 * 1280 * PLATE_BYTES_PER_PIXEL))
    assert 0.9 < budget_72 < 0.95 and plate_scale(72, 960, 1280) == 1.0
    n = int(np.ceil((1 << 30) / (0.89 ** 2 * 960 * 1280 * PLATE_BYTES_PER_PIXEL)))
    s = plate_scale(n, 960, 1280)
    assert s < psc.PLATE_FULL_SCALE
    assert s == pytest.approx(np.sqrt((1 << 30) / (n * 960 * 1280 * PLATE_BYTES_PER_PIXEL)))
    monkeypatch.setattr(psc, "PLATE_FULL_SCALE", 1.0)
    assert plate_scale(72, 960, 1280) == pytest.approx(budget_72)


def test_half_size_plates_match_the_room_behind_the_object():
    views, truth = ps.orbit_capture(12, 192, 144)
    plane = np.array([0.0, 0.0, 1.0, -ps.TABLE_Z])
    full, rec_full = background_plates(views, PlateConfig(), plane)
    small, rec = background_plates([shrink_view(v, 0.5) for v in views], PlateConfig(), plane)
    assert rec["mode"] == rec_full["mode"] == "panorama"
    H, W = views[0].object_depth.shape
    grown = [grow_plate(p.cropped(), H, W) for p in small]
    err, known = ps.band_error(views, grown, truth)
    err_full, known_full = ps.band_error(views, full, truth)
    floor = _resampling_floor(views, truth, 0.5)
    assert err <= floor + WORKING_TOL, (err, floor, err_full)
    assert known >= known_full - KNOWN_LOSS_MAX, (known, known_full)
    # a known pixel of the grown plate is known at full size too (never borrowed from the object)
    assert all(not (g.known & ~f.known).any() or (g.known & ~f.known).mean() < 0.01 for g, f in zip(grown, full))


def test_grow_plate_keeps_a_smooth_background_and_never_extends_what_is_known():
    y, x = np.mgrid[0:40, 0:60].astype(np.float32)
    bg = np.stack([x / 60, y / 40, 0.5 + 0 * x], -1).astype(np.float32)
    known = np.ones((40, 60), bool)
    known[15:25, 20:40] = False
    p = Plate(np.where(known[..., None], bg, 0), known, 0.01, "fixed", 0.5, 0.0, 0.0)
    g = grow_plate(p, 80, 120)
    yy, xx = np.mgrid[0:80, 0:120].astype(np.float32)
    # the same ramp, sampled at the full-size pixel centres ((i + 0.5) / 2 - 0.5 in working pixels)
    want = np.stack([((xx + 0.5) / 2 - 0.5) / 60, ((yy + 0.5) / 2 - 0.5) / 40, 0.5 + 0 * xx], -1)
    inner = g.known.copy()
    inner[[0, -1], :] = False
    inner[:, [0, -1]] = False
    assert np.abs(g.background - want)[inner].max() < 1e-5
    hole = np.zeros((80, 120), bool)
    hole[28:52, 38:82] = True  # the unknown box at full size, grown by one working pixel
    assert not (g.known & hole).any()
    assert grow_plate(p, 40, 60).known.sum() == known.sum()


@pytest.mark.parametrize("scale", [0.93, 0.74, 0.5, 0.31, PLATE_MIN_SCALE])
def test_the_fast_shrink_equals_shrink_view(scale, monkeypatch):
    """shrink_scan (SHRINK_FAST) gives shrink_view's view of the float16 colour bit for bit: colour
    (dark pixels whose area means are float16 subnormals included), the object's depth grown (an
    object on the borders and corners, single pixels, odd and even windows) and the capture's depth;
    8-bit colour at scale 1 and float colour go to the reference.  Without the maximum filter the
    depth differs (the test can fail)."""
    from capture import plate_scale
    from capture.camera import Camera, make_K
    from capture.scan import linear16

    rng = np.random.default_rng(int(scale * 100))
    H, W = 97, 131
    rgb = rng.integers(0, 256, (H, W, 3), dtype=np.uint8)
    rgb[:20, :30] = rng.random((20, 30, 3)) < 0.08  # dark: code 0 and a few 1s, subnormal float16 means
    obj = np.where(rng.random((H, W)) < 0.05, rng.uniform(0.5, 2.0, (H, W)), 0.0).astype(np.float32)
    obj[:3, :4] = 1.7
    obj[-2:, -5:] = 0.9
    obj[40:60, 0] = 1.2
    depth = rng.uniform(0.3, 3.0, (H, W)).astype(np.float32)
    cam = Camera(make_K(100.0, 100.0, W / 2, H / 2), np.eye(4), W, H)
    want = shrink_view(ps.PlateView(cam, linear16(rgb), obj, depth), scale)
    got = plate_scale.shrink_scan(cam, rgb, obj, depth, scale)
    assert np.array_equal(got.camera.K, want.camera.K) and (got.camera.width, got.camera.height) == \
        (want.camera.width, want.camera.height)
    for a, b in ((got.linear, want.linear), (got.object_depth, want.object_depth), (got.depth, want.depth)):
        assert a.dtype == b.dtype and a.shape == b.shape
        assert np.array_equal(a.view(np.uint8), b.view(np.uint8))
    assert (want.linear < np.float16(6.1e-5)).any() and (want.linear > 0).any()
    monkeypatch.setattr(plate_scale.cv2, "dilate", lambda a, k: a)
    assert not np.array_equal(plate_scale.shrink_scan(cam, rgb, obj, depth, scale).object_depth, want.object_depth)
    same = plate_scale.shrink_scan(cam, rgb, obj, depth, 1.0)  # scale 1: the view as it is
    assert np.array_equal(same.linear, linear16(rgb)) and same.object_depth is obj


def test_opencvs_float16_cast_is_numpys():
    """The float16 cast shrink_scan takes (cv2.multiply by 1 to CV_16F) equals numpy's astype bit for
    bit over float32 values from 0 to above the float16 range: every 61st bit pattern, the subnormal
    range's ties, and exact halfway points between float16 neighbours (round to nearest even)."""
    x = np.arange(0, 0x47800000 + 1000, 61, dtype=np.uint32).view(np.float32)
    h = np.arange(0, 0x7BFF, dtype=np.uint16).view(np.float16).astype(np.float32)
    mid = ((h[:-1].astype(np.float64) + h[1:]) / 2).astype(np.float32)  # exact in float32
    for v in (x, mid, np.nextafter(mid, np.float32(0)), np.nextafter(mid, np.float32(1))):
        v = np.ascontiguousarray(v.reshape(-1, 1))
        got = cv2.multiply(v, 1.0, dtype=cv2.CV_16F)
        with np.errstate(over="ignore"):  # beyond the float16 range: inf both
            want = v.astype(np.float16)
        assert got.dtype == np.float16 and np.array_equal(got.view(np.uint16), want.view(np.uint16))

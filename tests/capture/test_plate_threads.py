"""The background plate stage on several threads (capture/plate_threads.py, issue 32 round 6): the same
plates bit for bit as one thread, whatever the chunks; the map keeps order, reads lazily and runs no
threads within threads; the leave-one-out median of the exposure check equals numpy's."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from capture import plate_fixed, plate_lines, plate_threads
from capture.plate import PlateConfig, background_plates
from tests import plate_scenes as ps
from tests.capture.test_plate import _same_plate


def _turntable(seed: int):
    """A turntable with auto exposure and a window most frames clip (every part of the fixed path:
    the robust mode, the censored samples, the frames' lines and their held-back check)."""
    W, H = 96, 72
    room = ps.room_image(W, H, seed).copy()
    room[:, 30:40] = 1.3
    rng = np.random.default_rng(seed + 10)
    gains = 2.0 ** rng.normal(0.0, 0.35, (12, 1)) * np.exp(rng.normal(0.0, 0.06, (12, 3)))
    views, _, _, _ = ps.turntable_capture(gains=gains, seed=seed, room=room)
    return views


@pytest.mark.parametrize("seed", [1])
def test_plates_on_threads_and_small_chunks_equal_one_thread(seed, monkeypatch):
    views = _turntable(seed)
    monkeypatch.setattr(plate_threads, "PLATE_THREADS", 1)
    want, rec_want = background_plates(views, PlateConfig(), crop=True)
    assert rec_want["mode"] == "fixed" and rec_want["band_estimated_mean"] > 0  # the lines filled some
    monkeypatch.setattr(plate_threads, "PLATE_THREADS", 3)
    monkeypatch.setattr(plate_fixed, "DRAW_CHUNK", 101)
    monkeypatch.setattr(plate_fixed, "MODE_CHUNK", 37)
    monkeypatch.setattr(plate_lines, "LINE_CHUNK", 53)
    monkeypatch.setattr(plate_fixed, "FILL_CHUNK", 29)
    got, rec = background_plates((v for v in views), PlateConfig(), crop=True)
    assert rec == rec_want
    for a, b in zip(got, want, strict=True):
        _same_plate(a, b)


def test_thread_map_keeps_order_reads_lazily_and_nests_in_its_worker():
    read = []

    def items():
        for i in range(20):
            read.append(i)
            yield i

    def inner(i):  # a map inside a worker runs in that worker, on no other thread
        here = threading.current_thread().name
        return [threading.current_thread().name == here for _ in range(1)] + \
            list(plate_threads.thread_map(lambda k: threading.current_thread().name == here, range(3))), \
            plate_threads.plate_threads()

    it = plate_threads.thread_map(lambda i: i * i, items(), threads=2)
    assert next(it) == 0 and len(read) <= 5  # at most twice the threads ahead
    assert list(it) == [i * i for i in range(1, 20)]
    out = list(plate_threads.thread_map(inner, range(4), threads=2))
    assert all(n == 1 and all(same) for same, n in out)
    assert plate_threads.chunks(10, 4) == [(0, 4), (4, 8), (8, 10)] and plate_threads.chunks(0, 4) == []

    def fail(i):
        if i == 3:
            raise ValueError("view 3")
        return i

    with pytest.raises(ValueError, match="view 3"):
        list(plate_threads.thread_map(fail, range(8), threads=2))


@pytest.mark.parametrize("V", [2, 3, 8, 13])
def test_leave_one_out_median_equals_numpys(V):
    rng = np.random.default_rng(V)
    a = rng.normal(size=(V, 300, 3))
    a[:, :100] = np.round(a[:, :100])  # ties
    for got, want in zip(plate_fixed.others_median(a), plate_fixed.others_median(a, fast=False), strict=True):
        assert np.array_equal(got, want)


def test_moving_camera_plates_on_threads_equal_one_thread(monkeypatch):
    """The panorama path's ring predictions and plates per view side by side: the same plates."""
    views, _ = ps.orbit_capture(n=8)
    plane = np.array([0.0, 0.0, 1.0, -ps.TABLE_Z])
    monkeypatch.setattr(plate_threads, "PLATE_THREADS", 1)
    want, rec_want = background_plates(views, PlateConfig(), plane, crop=True)
    monkeypatch.setattr(plate_threads, "PLATE_THREADS", 3)
    got, rec = background_plates((v for v in views), PlateConfig(), plane, crop=True)
    assert rec == rec_want and rec["mode"] == "panorama"
    for a, b in zip(got, want, strict=True):
        _same_plate(a, b)


def test_chunked_draw_and_fill_equal_one_call(monkeypatch):
    """fixed_draw's chunks (plate_fixed._draw_prediction, _unseen_chunks) against one call of what
    they split (fixed_prediction over every pixel; unseen_background over every unknown pixel): the
    same plate, bounds, fill and uncertainty, bit for bit."""
    from capture.plate import plate_set
    from capture.plate_lines import unseen_background

    views = _turntable(1)
    ps_ = plate_set(views, None, None, PlateConfig()).for_path("fixed")
    gains = np.exp(np.random.default_rng(2).normal(0.0, 0.1, (len(views), 3)))
    y, x = np.nonzero(np.logical_or.reduce([p.need for p in ps_.views]))
    pix = np.stack([x, y], axis=1)
    args = ([p.view for p in ps_.views], pix, gains, [p.weight for p in ps_.views], list(range(len(views))))
    monkeypatch.setattr(plate_threads, "PLATE_THREADS", 3)
    monkeypatch.setattr(plate_fixed, "DRAW_CHUNK", 37)
    monkeypatch.setattr(plate_fixed, "FILL_CHUNK", 29)
    med, bound = plate_fixed._draw_prediction(*args)
    want = plate_fixed.fixed_prediction(args[0], pix, None, gains, args[3], args[4])
    assert np.array_equal(med, want[0], equal_nan=True) and np.array_equal(bound, want[1])
    runs = []
    for chunked in (True, False):
        if not chunked:
            monkeypatch.setattr(plate_fixed, "_unseen_chunks", unseen_background)
        m, b, s = med.copy(), bound.copy(), np.full(len(y), np.nan)
        est = plate_fixed.unseen_fill(ps_, gains, y, x, m, b, s)
        runs.append((est, m, b, s))
    # the lines filled some pixels, over several chunks of the unknown ones
    assert runs[0][0].sum() >= 10 and (~np.isfinite(med[:, 0])).sum() > 3 * 29
    for a, b in zip(*runs, strict=True):
        assert np.array_equal(a, b, equal_nan=True)

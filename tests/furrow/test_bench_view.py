"""``furrow bench view``'s arithmetic on a frame log and on the page's counters (no GL, no browser):
drags found from the log, fps, lines and stage medians per drag, the stop -> full frame delay, the
page's rates between two snapshots."""

from __future__ import annotations

import numpy as np
import pytest

from furrow.bench import _browser as B
from furrow.bench import view as V

SIZE = (960, 720)


def frame_log(drags=2, fps=10.0, lines=400, drag_s=4.0, gap_s=3.0, full_after_s=0.5):
    """A synthetic --stats log: ``drags`` drags of moving frames at ``fps`` and ``lines``, each
    followed by a full frame ``full_after_s`` after its last moving frame."""
    frames, t = [], 1.0
    for _ in range(drags):
        n = int(drag_s * fps)
        for i in range(n):
            frames.append({"t": t + i / fps, "moving": True, "width": round(lines * 4 / 3), "height": lines,
                           "total_ms": 80.0, "cpu_ms": 30.0, "wait_ms": 0.1, "render_ms": 70.0, "convert_ms": 2.0,
                           "send_ms": 1.0})
        end = t + (n - 1) / fps
        frames.append({"t": end + full_after_s, "moving": False, "width": SIZE[0], "height": SIZE[1],
                       "total_ms": 250.0, "cpu_ms": 90.0, "since_change_s": full_after_s, "refined": False})
        t = end + gap_s
    return frames


def test_summarise_finds_the_drags_and_their_figures():
    res = V.summarise(frame_log(), SIZE)
    assert len(res["drags"]) == 2
    m = res["median"]
    assert m["fps"] == pytest.approx(10.0, rel=1e-6) and m["lines"] == 400
    assert m["render_ms"] == 70.0 and m["convert_ms"] == 2.0 and m["send_ms"] == 1.0 and m["wait_ms"] == 0.1
    assert m["full_s"] == 0.5 and np.isnan(m["refined_s"])
    # a full frame of another size (the max-lines cap) is not the drag's full frame
    assert np.isnan(V.summarise(frame_log(), (640, 480))["median"]["full_s"])


def test_summarise_of_an_older_log_and_with_the_page_rates():
    old = [{k: v for k, v in f.items() if k not in V.STAGE_KEYS} for f in frame_log()]
    m = V.summarise(old, SIZE)["median"]
    assert np.isnan(m["render_ms"]) and m["fps"] == pytest.approx(10.0, rel=1e-6)
    page = [{"received_fps": 9.0, "decoded_fps": 8.0, "drawn_fps": 20.0, "decode_ms": 12.0},
            {"received_fps": 11.0, "decoded_fps": 10.0, "drawn_fps": 22.0, "decode_ms": float("nan")}]
    m = V.summarise(frame_log(), SIZE, page)["median"]
    assert m["decoded_fps"] == 9.0 and m["decode_ms"] == 12.0
    with pytest.raises(RuntimeError):
        V.summarise([f for f in frame_log() if not f["moving"]], SIZE)


def test_counter_rates():
    a = {"t": 10.0, "received": 5, "decoded": 4, "drawn": 10, "decode_ms": [9.0, 9.0, 9.0, 9.0],
         "cpu": {"t": 100.0, "viewer": 1.0, "browser": 2.0}}
    b = {"t": 12.0, "received": 25, "decoded": 22, "drawn": 50, "decode_ms": [9.0] * 4 + [10.0, 30.0, 20.0],
         "cpu": {"t": 102.0, "viewer": 2.5, "browser": 3.0}}
    r = B.counter_rates(a, b)
    assert (r["received_fps"], r["decoded_fps"], r["drawn_fps"], r["decode_ms"]) == (10.0, 9.0, 20.0, 20.0)
    assert r["viewer_cores"] == pytest.approx(0.75) and r["browser_cores"] == pytest.approx(0.5)
    assert r["browser_cpu_ms_per_drawn"] == pytest.approx(25.0)
    assert "viewer_cores" not in B.counter_rates({**a, "cpu": {}}, b)


def test_cost_rows_and_size_argument():
    rows = V.cost_rows(SIZE)
    assert [r[0] for r in rows[:-2]] == [180, 360, 400, 720] and rows[-1] == (720, 2, None)
    assert V.parse_size("640x480") == (640, 480)
    import argparse

    with pytest.raises(argparse.ArgumentTypeError):
        V.parse_size("640")

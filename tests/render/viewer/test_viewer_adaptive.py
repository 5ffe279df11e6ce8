"""The viewer's adaptive resolution and frame scheduling (pure functions, render.viewer.adaptive)."""

from __future__ import annotations

import numpy as np
import pytest

from render.viewer.adaptive import (
    Action,
    AdaptiveConfig,
    choose_scale,
    fit_cost,
    frame_size,
    is_stale,
    next_action,
    quantise,
)

FULL = (640, 480)
FULL_PX = FULL[0] * FULL[1]


def test_fit_cost_recovers_a_line():
    p = np.array([1e4, 4e4, 9e4, 2e5])
    a, b = fit_cost(p, 12.0 + 3e-4 * p)
    assert a == pytest.approx(12.0, rel=1e-9) and b == pytest.approx(3e-4, rel=1e-9)
    # one size only: proportional model through the origin (median of ms / pixels)
    a, b = fit_cost([5e4, 5e4, 5e4], [20.0, 22.0, 90.0])
    assert a == 0.0 and b == pytest.approx(22.0 / 5e4)
    with pytest.raises(ValueError):
        fit_cost([], [])


def simulate(a, b, n, cfg=None, noise=0.0, seed=0):
    """Run the controller against a renderer costing a + b * pixels ms (times +- noise share)."""
    cfg = cfg or AdaptiveConfig()
    rng = np.random.default_rng(seed)
    hist, scale, scales = [], None, []
    for _ in range(n):
        scale = choose_scale(hist, FULL_PX, cfg, previous=scale)
        w, h = frame_size(FULL, scale)
        hist.append((w * h, (a + b * w * h) * (1 + noise * rng.uniform(-1, 1))))
        scales.append(scale)
    return scales


@pytest.mark.parametrize("a, b", [(15.0, 300.0 / FULL_PX), (5.0, 80.0 / FULL_PX), (30.0, 1500.0 / FULL_PX)])
def test_scale_converges_to_the_budget(a, b):
    cfg = AdaptiveConfig(target_fps=12.0)
    ideal = np.sqrt((cfg.budget_ms - a) / b / FULL_PX)   # exact scale filling the budget
    scales = simulate(a, b, 12, cfg, noise=0.1)
    last = scales[-4:]
    for s in last:
        w, h = frame_size(FULL, s)
        # within the budget up to the 10 % timing noise and the size rounding, and not wastefully small:
        assert a + b * w * h <= cfg.budget_ms * 1.12
        assert s >= min(ideal, 1.0) - 4 * cfg.scale_step   # 50 seeds: worst -0.115 (3.7 steps) at 10 % noise
    # settled: the last sizes differ by at most 4 steps (50 seeds at 10 % noise: at most 4, at a = 5 ms)
    assert max(last) - min(last) <= 4 * cfg.scale_step


def test_scale_limits():
    cfg = AdaptiveConfig()
    # a fixed cost above the budget: the smallest size
    assert simulate(120.0, 1e-6, 4, cfg)[-1] == cfg.min_scale
    # a cheap renderer: the full size
    assert simulate(1.0, 1e-6, 12, cfg)[-1] == 1.0
    # growth from one frame to the next is limited; shrinking is immediate
    assert choose_scale([(1000, 0.1)], FULL_PX, cfg, previous=0.25) <= 0.25 * cfg.max_growth
    assert choose_scale([(FULL_PX, 1000.0)], FULL_PX, cfg, previous=1.0) < 0.3


def test_quantise_and_frame_size():
    cfg = AdaptiveConfig(scale_step=0.25, min_scale=0.25)
    assert quantise(0.74, cfg) == 0.5 and quantise(0.01, cfg) == 0.25 and quantise(3.0, cfg) == 1.0
    assert frame_size((640, 480), 0.5) == (320, 240)
    assert frame_size((641, 479), 1.0) == (640, 478)    # multiples of 2, never larger than full
    assert frame_size((640, 480), 0.001) == (2, 2)


def test_next_action_sequence():
    cfg = AdaptiveConfig(still_s=0.2)
    nxt = lambda now, moving, full, refined, refine=True: next_action(now, 5, 1.0, moving, full, refined, refine, cfg)
    # camera moved at t=1.0 (version 5), nothing rendered: a moving frame
    assert nxt(1.01, 4, 3, 3) == Action("moving")
    # moving frame sent, still moving window: wait the rest of the stillness delay
    act = nxt(1.05, 5, 3, 3)
    assert act.kind == "wait" and act.wait_s == pytest.approx(0.15)
    # still for 0.2 s: the full frame, even when the moving frame never went out
    assert nxt(1.2, 5, 3, 3) == Action("full")
    assert nxt(1.3, 4, 3, 3) == Action("full")
    # full frame sent: the supersampled one, then wait for the next change
    assert nxt(1.4, 5, 5, 3) == Action("refine")
    assert nxt(9.0, 5, 5, 5) == Action("wait", None)
    # no supersampling asked for: nothing after the full frame
    assert nxt(1.4, 5, 5, 3, refine=False) == Action("wait", None)


def test_stale_work_is_dropped():
    assert is_stale(4, 5) and not is_stale(5, 5)


def test_config_validation():
    with pytest.raises(ValueError):
        AdaptiveConfig(target_fps=0)
    with pytest.raises(ValueError):
        AdaptiveConfig(min_scale=0)


def test_grows_back_from_the_smallest_size():
    """After a slow frame (e.g. shader compilation) the size shrinks to the minimum; cheap frames
    afterwards grow it back (the hysteresis holds only near the budget)."""
    cfg = AdaptiveConfig()
    a, b = 8.0, 60.0 / FULL_PX
    hist = [(FULL_PX // 4, 800.0)]
    scale = choose_scale(hist, FULL_PX, cfg, previous=0.5)
    assert scale <= 0.2
    for _ in range(30):
        w, h = frame_size(FULL, scale)
        hist.append((w * h, a + b * w * h))
        scale = choose_scale(hist, FULL_PX, cfg, previous=scale)
    assert scale == 1.0

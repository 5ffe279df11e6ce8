"""The viewer's adaptive resolution and frame scheduling (pure functions, render.viewer.adaptive)."""

from __future__ import annotations

import numpy as np
import pytest

from render.viewer.adaptive import (
    FULL_HISTORY,
    HISTORY,
    MAX_FPS_FACTOR,
    MAX_STRETCH,
    Action,
    AdaptiveConfig,
    Sample,
    add_sample,
    choose_scale,
    cost_model,
    cpu_bound,
    fit_cost,
    fixed_costs,
    frame_size,
    is_stale,
    next_action,
    quantise,
    slowdown,
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


#: How a simulated frame's per-pixel cost splits over the stages (render, convert, send), and what
#: a full frame's send stage costs per pixel relative to a moving one's (PNG against JPEG).
STAGE_SHARE = (0.7, 0.2, 0.1)
FULL_SEND_FACTOR = 8.0


def sample(a, b, pixels, moving=True, jitter=1.0, contention=1.0):
    """A frame of a renderer costing a + b * pixels CPU ms (the fixed cost in the render stage),
    taking ``contention`` times that in wall time."""
    cpu = [a + STAGE_SHARE[0] * b * pixels, STAGE_SHARE[1] * b * pixels, STAGE_SHARE[2] * b * pixels]
    if not moving:
        cpu[2] *= FULL_SEND_FACTOR
    cpu = tuple(c * jitter for c in cpu)
    return Sample(pixels, tuple(c * contention for c in cpu), moving, cpu)


def simulate(a, b, n, cfg=None, noise=0.0, seed=0, full_first=True, contention=1.0):
    """Run the controller against a renderer costing a + b * pixels ms (times +- noise share),
    after one full-size still frame (as a session has drawn when the first drag starts) unless
    ``full_first`` is false; moving frames take ``contention`` times their CPU time in wall time,
    the still frame its CPU time (the browser idle)."""
    cfg = cfg or AdaptiveConfig()
    rng = np.random.default_rng(seed)
    hist = [sample(a, b, FULL_PX, moving=False)] if full_first else []
    scale, scales, fixed = None, [], fixed_costs(hist)
    for _ in range(n):
        scale = choose_scale(hist, FULL_PX, cfg, previous=scale, fixed=fixed)
        w, h = frame_size(FULL, scale)
        hist = add_sample(hist, sample(a, b, w * h, jitter=1 + noise * rng.uniform(-1, 1), contention=contention))
        fixed = fixed_costs(hist, fixed)
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
    # a cheap renderer: the full size
    assert simulate(1.0, 1e-6, 12, cfg)[-1] == 1.0
    # growth from one frame to the next is limited; shrinking is immediate
    assert choose_scale([Sample(1000, (0.1, 0.0, 0.0))], FULL_PX, cfg, previous=0.25) <= 0.25 * cfg.max_growth
    assert choose_scale([Sample(FULL_PX, (1000.0, 0.0, 0.0), False)], FULL_PX, cfg, previous=1.0) < 0.3
    # the smallest size when even that overruns by far (a per-pixel cost of 20 s a full frame)
    assert simulate(10.0, 20000.0 / FULL_PX, 12, cfg)[-1] == cfg.min_scale


def test_fixed_cost_near_the_budget_keeps_the_picture():
    """A fixed cost (gather's point splats) near the budget: shrinking cannot reach the budget and
    would only blur, so the pixels get min_pixel_share of the frame: the scale converges to the one
    filling a / (1 - share) ms (0.32 here), not to the smallest size, to which the old
    proportional model through the origin spiralled down (0.125 on the same renderer).  With the
    full-size still frame that precedes a drag in the cost model, at 10 % timing noise.  A fixed
    cost too large for MAX_STRETCH x the budget shrinks the frame to the smallest size."""
    cfg = AdaptiveConfig()
    a, b = 60.0, 300.0 / FULL_PX
    frame = a / (1 - cfg.min_pixel_share)
    assert cfg.budget_ms < frame < MAX_STRETCH * cfg.budget_ms
    ideal = np.sqrt((frame - a) / b / FULL_PX)
    for seed in range(5):
        last = simulate(a, b, 30, cfg, noise=0.1, seed=seed)[-4:]
        for s in last:
            w, h = frame_size(FULL, s)
            assert a + b * w * h <= frame * 1.12
            assert s >= ideal - 2 * cfg.scale_step
    # without a full frame first (a drag right after a settings change) the line is found from the
    # moving frames' own sizes, less exactly, but the picture does not collapse either
    for seed in range(5):
        last = simulate(a, b, 30, cfg, noise=0.1, seed=seed, full_first=False)[-4:]
        assert min(last) >= ideal - 4 * cfg.scale_step > 1.5 * cfg.min_scale
    assert simulate(130.0, b, 12, cfg)[-1] == cfg.min_scale       # past the stretch: the budget rules


@pytest.mark.parametrize("contention", [1.5, 0.7])
def test_moving_frames_in_another_contention_than_the_still_frame(contention):
    """The still frame is drawn while the browser idles, a drag while it draws every frame too:
    the same CPU work takes ``contention`` times as long in wall time while moving (0.7: a
    multithreaded rasteriser with the cores to itself).  Fitted to wall times, the full frame
    would bend the line (at 1.5 it made full-size moving frames look nearly free, measured: 98 ms
    frames for an 83 ms budget); the model is fitted to CPU time and scaled by the moving frames'
    wall / CPU, so moving frames keep to the budget in wall time."""
    cfg = AdaptiveConfig()
    a, b = 20.0, 90.0 / FULL_PX
    ideal = min(np.sqrt((cfg.budget_ms / contention - a) / b / FULL_PX), 1.0)
    for seed in range(5):
        for s in simulate(a, b, 20, cfg, noise=0.1, seed=seed, contention=contention)[-4:]:
            w, h = frame_size(FULL, s)
            assert contention * (a + b * w * h) <= cfg.budget_ms * 1.12
            assert s >= ideal - 3 * cfg.scale_step


def test_gpu_frames_are_modelled_in_wall_time():
    """A GPU renderer: the CPU only issues the frame, the wall time grows with the pixels; its
    samples carry no CPU times (the session records them for a software rasteriser only), so the
    model is the wall-time one and meets the budget (in CPU time everything would look like a
    fixed cost)."""
    cfg = AdaptiveConfig()
    a, b = 5.0, 200.0 / FULL_PX
    gpu = lambda px, moving=True: Sample(px, (a + b * px, 0.0, 0.0), moving)
    hist = [gpu(FULL_PX, False), gpu(FULL_PX // 4), gpu(FULL_PX // 8)]
    assert not cpu_bound(hist) and cpu_bound([sample(a, b, FULL_PX)])
    s = choose_scale(hist, FULL_PX, cfg)
    assert abs(s - np.sqrt((cfg.budget_ms - a) / b / FULL_PX)) <= cfg.scale_step


def test_slowdown():
    assert slowdown([]) == 1.0
    assert slowdown([Sample(100, (3.0, 1.0, 0.0))]) == 1.0                         # no CPU times
    hist = [Sample(100, (20.0, 0.0, 0.0), False, (20.0, 0.0, 0.0)),
            Sample(50, (15.0, 0.0, 0.0), True, (10.0, 0.0, 0.0)), Sample(50, (16.0, 2.0, 2.0), True, (10.0, 0.0, 0.0))]
    assert slowdown(hist) == pytest.approx((1.5 + 2.0) / 2)                       # the moving ones
    assert slowdown(hist[:1]) == 1.0


def test_an_unpinned_fixed_cost_does_not_stretch_the_budget():
    """Frames of 660-960 columns only (a drag near full size, measured): the line through them
    puts the fixed cost near the frame time itself (69 of ~85 ms), which would stretch the budget to
    1.5 x that and keep 90-100 ms full-size frames (9 fps).  Unpinned (no frame at a quarter of
    the pixels or less), it stretches nothing: the frame shrinks to the budget; pinned at 26 ms
    (gather's point splats), the same."""
    cfg = AdaptiveConfig()
    P = FULL_PX
    rows = [(P, 86.0), (P, 88.0), (int(0.88 * P), 84.0), (int(0.47 * P), 76.0), (int(0.52 * P), 78.0), (P, 91.0)]
    hist = [Sample(px, (ms, 5.0, 2.0), True, (ms, 5.0, 2.0)) for px, ms in rows]
    assert cost_model(hist)[0] > 60.0                             # the noisy line's fixed cost
    assert fixed_costs(hist)[0] is None                           # not pinned
    assert choose_scale(hist, P, cfg, previous=1.0) <= 0.94
    assert choose_scale(hist, P, cfg, previous=1.0, fixed=(26.0, 0.0, 0.0)) <= 0.94


def test_cost_model_per_stage():
    """Full-size frames teach the render and convert stages (so the fixed cost is found at once)
    but not the send stage, which encodes them otherwise (PNG)."""
    a, b = 30.0, 100.0 / FULL_PX
    hist = [sample(a, b, FULL_PX, moving=False), sample(a, b, FULL_PX // 4), sample(a, b, FULL_PX // 4)]
    fa, fb = cost_model(hist)
    assert fa == pytest.approx(a, rel=1e-6) and fb == pytest.approx(b, rel=1e-6)
    assert cost_model([]) == (0.0, 0.0)


def test_add_sample_keeps_the_recent_moving_and_full_frames():
    hist = []
    for i in range(3 * HISTORY):
        hist = add_sample(hist, Sample(100 + i, (1.0, 0.0, 0.0), moving=i % 3 != 0))
    moving = [s.pixels for s in hist if s.moving]
    full = [s.pixels for s in hist if not s.moving]
    assert len(moving) == HISTORY and len(full) == FULL_HISTORY
    assert moving[-1] == 100 + 3 * HISTORY - 1 and full[-1] == 100 + 3 * HISTORY - 3
    assert [s.pixels for s in hist] == sorted(s.pixels for s in hist)      # order kept


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


def test_moving_frames_are_paced():
    """A moving frame starts at most 1 / max_fps (default: MAX_FPS_FACTOR x target_fps) after the
    previous one: the rest of the slot is waited (never past the stillness delay); the full frame
    is not paced."""
    assert AdaptiveConfig(target_fps=10.0).min_interval_s == pytest.approx(1 / (MAX_FPS_FACTOR * 10.0))
    cfg = AdaptiveConfig(target_fps=10.0, max_fps=10.0, still_s=0.2)
    act = next_action(1.03, 5, 1.0, 4, 3, 3, True, cfg, last_moving_t=1.0)
    assert act.kind == "wait" and act.wait_s == pytest.approx(0.07)
    assert next_action(1.101, 5, 1.0, 4, 3, 3, True, cfg, last_moving_t=1.0) == Action("moving")
    assert next_action(1.03, 5, 1.0, 4, 3, 3, True, cfg, last_moving_t=None) == Action("moving")
    act = next_action(1.19, 5, 1.0, 4, 3, 3, True, cfg, last_moving_t=1.18)
    assert act.kind == "wait" and act.wait_s == pytest.approx(0.01)    # the still frame comes first
    assert next_action(1.2, 5, 1.0, 4, 3, 3, True, cfg, last_moving_t=1.19) == Action("full")
    fast = AdaptiveConfig(target_fps=10.0, max_fps=50.0)
    assert next_action(1.03, 5, 1.0, 4, 3, 3, True, fast, last_moving_t=1.0) == Action("moving")


def test_stale_work_is_dropped():
    assert is_stale(4, 5) and not is_stale(5, 5)


def test_config_validation():
    with pytest.raises(ValueError):
        AdaptiveConfig(target_fps=0)
    with pytest.raises(ValueError):
        AdaptiveConfig(min_scale=0)
    with pytest.raises(ValueError):
        AdaptiveConfig(max_fps=0)
    with pytest.raises(ValueError):
        AdaptiveConfig(min_pixel_share=1.0)


def test_grows_back_from_the_smallest_size():
    """After a slow frame (e.g. shader compilation) the size shrinks to the minimum; cheap frames
    afterwards grow it back (the hysteresis holds only near the budget)."""
    cfg = AdaptiveConfig()
    a, b = 8.0, 60.0 / FULL_PX
    hist = [Sample(FULL_PX // 4, (800.0, 0.0, 0.0))]
    scale = choose_scale(hist, FULL_PX, cfg, previous=0.5)
    assert scale <= 0.2
    for _ in range(30):
        w, h = frame_size(FULL, scale)
        hist = add_sample(hist, sample(a, b, w * h))
        scale = choose_scale(hist, FULL_PX, cfg, previous=scale)
    assert scale == 1.0

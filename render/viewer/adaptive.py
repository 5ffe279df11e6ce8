"""Fluid on a CPU: the frame size while the camera moves, and what to render next.

Pure functions over numbers (no GL, no threads), used by render.viewer.session:

* :func:`choose_scale`: from the measured stages of recent frames (a per-stage cost model
  ``cpu ms = a + b * pixels``: each stage of :data:`STAGES` fitted to the frames that share its
  cost, full-size frames included, so that the fixed cost ``a`` -- e.g. gather's point splats,
  the same at any size -- is told apart from the per-pixel one; turned into wall time by the wall
  / CPU ratio of the recent moving frames, :func:`slowdown`), the largest share of the full frame size
  whose predicted time fits the frame budget (``1000 / target_fps`` ms); when the fixed cost
  alone nearly fills the budget, the pixels still get :attr:`AdaptiveConfig.min_pixel_share` of
  the frame (shrinking further would blur the picture and win almost no speed); quantised so that
  the size does not jitter from frame to frame;
* :func:`next_action`: render a moving frame (the camera changed since the last frame, and the
  last moving frame started at least ``1 / max_fps`` ago: frames the client could not show are
  not drawn), the full-size frame then its supersampled refinement (the camera has been still for
  ``still_s``), or wait;
* :func:`is_stale`: a frame whose camera/settings version is no longer the latest is dropped.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

#: Frames per second held while the camera moves (the issue asks for about 10-15 here).
TARGET_FPS = 12.0
#: Seconds the camera must stay still before the full-resolution, supersampled frame.
STILL_S = 0.2
#: Smallest share of the full size (per axis) drawn while moving.
MIN_SCALE = 0.125
#: Moving frame sizes are multiples of this share of the full size (no jitter between frames).
SCALE_STEP = 1.0 / 32.0
#: Most a moving frame may grow per axis from one frame to the next (shrinking is immediate).
MAX_GROWTH = 1.25
#: Share of a moving frame's time the per-pixel work gets at least: when the fixed cost ``a`` of a
#: frame is above ``(1 - MIN_PIXEL_SHARE)`` of the budget, the frame is allowed
#: ``a / (1 - MIN_PIXEL_SHARE)`` ms instead of being shrunk towards nothing (gather's point splats
#: cost the same at 60 lines as at 720: shrinking below that buys a few percent of frame rate for
#: a picture 10x blurrier; measured in docs/viewer.md).
MIN_PIXEL_SHARE = 1.0 / 3.0
#: ... but never more than MAX_STRETCH x the budget (at the default 12 fps: 10 fps at the least by
#: the model's own account, issue 32's floor): under a load of 10 the fixed cost read from the frames drifted from 26
#: to 51 ms of CPU, and an unbounded stretch then sized 3.5 fps full-size frames (measured).  Above
#: it the frames shrink to the budget as they always did.  1.5 (8 fps) until stop 75: on a quiet machine its third
#: drags grew to 540-630 lines at 7.8-10.5 fps (browser bench medians 10.2 / 11.5 / 9.5 / 11.3 fps over four runs, 3
#: of 12 drags under 10); 1.2: 11.4 / 10.5 / 10.3 / 11.2 fps at 450-472 lines, 1 of 12 under 10 (docs/viewer.md).
MAX_STRETCH = 1.2
#: Recent moving frames the cost model is fitted to, and recent full-size one-sample frames kept
#: beside them (same renderer and settings: they pin the per-pixel slope).
HISTORY = 8
FULL_HISTORY = 2
#: The fixed cost a is fitted only when the frames' pixel counts differ by this ratio or more (closer
#: sizes make the line fit noise-sensitive: at 1.15, 10 % timing noise cost up to 0.2 in scale).
MIN_SPREAD = 1.5
#: The fixed cost is trusted beyond the fit (kept for later frames of one size, and allowed to
#: stretch the frame time, MIN_PIXEL_SHARE) only when pinned by frames whose pixel counts differ by
#: this ratio or more (a frame at half the size or less beside the full one): a line through
#: frames of 660-960 columns only put gather's fixed cost at 69 ms where it is about 30 (measured),
#: and the stretched budget then let full-size moving frames run at 9 fps.
PIN_SPREAD = 4.0
#: Scale used before any frame was measured.
FIRST_SCALE = 0.5
#: Hysteresis: the previous moving scale is kept when the new choice is within this many steps
#: of it and the previous size's predicted time is within HOLD_SLACK (share) of the frame time.
HOLD_STEPS = 2
HOLD_SLACK = 0.1
#: Moving frames start at most MAX_FPS_FACTOR x target_fps times per second by default: well above
#: the target, so that frames drawn faster than the budget (noise) make up for slower ones, but no
#: runaway rate of tiny frames that a browser decoding in software cannot show.
MAX_FPS_FACTOR = 1.5
#: Timing tolerance (s) of the stillness test.
TIME_EPS = 1e-6
#: The stages of a frame's time the cost model sees (wall ms each, render.viewer.session): the
#: renderer's (draw and read back), the conversion to the picture sent (8-bit sRGB, debug
#: colourings, environment compositing), and the encoding + hand-off to the client.  Time a frame
#: spent queued behind another client's frame is no cost of its size and is not modelled.
STAGES = ("render", "convert", "send")
#: Stages a full-size one-sample frame shares with a moving frame (same renderer, same
#: conversion); its send stage encodes another way (PNG, or JPEG at a higher quality), so only
#: moving frames teach the model that one.
SHARED_STAGES = ("render", "convert")


@dataclass(frozen=True)
class AdaptiveConfig:
    """Knobs of the adaptive resolution."""

    #: Frames per second to hold while moving (budget = 1000 / target_fps ms per frame, the whole
    #: frame: drawing, read-back, conversion, encoding).
    target_fps: float = TARGET_FPS
    #: Most moving frames started per second (None: MAX_FPS_FACTOR x target_fps): a frame drawn
    #: faster waits for its slot instead of going out at once, so that the client (a browser
    #: decoding and drawing in software on the same cores) is not sent frames it cannot show.
    max_fps: float | None = None
    #: Seconds of stillness before the full frame.
    still_s: float = STILL_S
    #: Smallest share of the full size per axis while moving, in (0, 1].
    min_scale: float = MIN_SCALE
    #: Moving sizes are multiples of this share of the full size.
    scale_step: float = SCALE_STEP
    #: Largest growth per axis from one moving frame to the next (>= 1).
    max_growth: float = MAX_GROWTH
    #: Least share of a moving frame's time given to per-pixel work, in (0, 1) (MIN_PIXEL_SHARE).
    min_pixel_share: float = MIN_PIXEL_SHARE

    def __post_init__(self) -> None:
        if not self.target_fps > 0:
            raise ValueError(f"target_fps must be > 0, got {self.target_fps}")
        if self.max_fps is not None and not self.max_fps > 0:
            raise ValueError(f"max_fps must be > 0 or None, got {self.max_fps}")
        if not self.still_s >= 0:
            raise ValueError(f"still_s must be >= 0 seconds, got {self.still_s}")
        if not 0 < self.min_scale <= 1:
            raise ValueError(f"min_scale must be in (0, 1], got {self.min_scale}")
        if not 0 < self.scale_step <= 1:
            raise ValueError(f"scale_step must be in (0, 1], got {self.scale_step}")
        if not self.max_growth >= 1:
            raise ValueError(f"max_growth must be >= 1, got {self.max_growth}")
        if not 0 < self.min_pixel_share < 1:
            raise ValueError(f"min_pixel_share must be in (0, 1), got {self.min_pixel_share}")

    @property
    def budget_ms(self) -> float:
        """Milliseconds per moving frame."""
        return 1000.0 / self.target_fps

    @property
    def min_interval_s(self) -> float:
        """Seconds between the starts of two moving frames, at least (1 / max_fps)."""
        return 1.0 / (self.max_fps if self.max_fps is not None else MAX_FPS_FACTOR * self.target_fps)


class Sample(NamedTuple):
    """One frame as the cost model sees it: ``pixels`` drawn, the wall milliseconds of each of
    :data:`STAGES` (``ms``, in that order), whether it was a ``moving`` frame (else a full-size
    frame with one sample per pixel), and the process CPU milliseconds of each stage (``cpu``;
    None for a GPU renderer: the wall time is the cost, :func:`cpu_bound`)."""

    pixels: int
    ms: tuple
    moving: bool = True
    cpu: tuple | None = None


def cpu_bound(history) -> bool:
    """Whether the model is fitted to CPU time: every sample carries CPU times, which the session
    records only for a software rasteriser (Mesa llvmpipe; render.viewer.gl_worker.GLWorker
    ``software``).  Its cost is its CPU time, the same whatever else runs, and the wall time it
    takes follows from the moving frames' :func:`slowdown`; a GPU's frames take wall time the
    CPU does not see and are modelled in wall time."""
    return bool(history) and all(s.cpu is not None for s in history)


def _cost(s: Sample, use_cpu: bool) -> tuple:
    """The stage costs the model is fitted to: CPU ms when ``use_cpu`` (and measured), else wall ms."""
    return s.cpu if use_cpu and s.cpu is not None else s.ms


def slowdown(history) -> float:
    """Wall milliseconds one CPU millisecond of frame work takes now: the median wall / CPU of the
    recent moving samples (of all samples when none moved yet); 1 without CPU times.  A drag
    shares the cores with the browser drawing it, a still frame mostly does not: the same CPU
    work takes longer in wall time while moving, so a CPU-bound renderer's model takes its shape
    from CPU time and its scale from the moving frames."""
    timed = [s for s in history if s.cpu is not None and sum(s.cpu) > 0]
    moving = [s for s in timed if s.moving] or timed
    return float(np.median([sum(s.ms) / sum(s.cpu) for s in moving])) if moving else 1.0


def add_sample(history, sample: Sample) -> list:
    """``history`` with ``sample`` appended, trimmed to the last HISTORY moving and the last
    FULL_HISTORY full-size samples (order kept)."""
    out, moving, full = [], 0, 0
    for smp in reversed([*history, sample]):
        if smp.moving and moving < HISTORY:
            out.append(smp)
            moving += 1
        elif not smp.moving and full < FULL_HISTORY:
            out.append(smp)
            full += 1
    return list(reversed(out))  # back to oldest first (a list of samples, not image rows)


def fit_cost(pixels, ms, fixed: float | None = None) -> tuple[float, float]:
    """(a ms, b ms per pixel) of ``ms = a + b * pixels`` over recent frames.

    With sizes spread by MIN_SPREAD or more: a least-squares line, with a clamped to [0, min(ms)]
    and b > 0.  With one size only (or sizes closer than MIN_SPREAD) the fixed cost cannot be
    told from the frames: a = ``fixed`` (the last one a spread-out fit found, see
    :func:`fixed_costs`; clamped to [0, min(ms)]) and b the median of (ms - a) / pixels, or,
    without one, a = 0 and b the median of ms / pixels (a proportional model: it over-estimates
    small frames, so the controller errs on the fluid side).
    """
    p = np.asarray(pixels, dtype=np.float64)
    t = np.asarray(ms, dtype=np.float64)
    if p.size == 0 or p.shape != t.shape or np.any(p <= 0):
        raise ValueError("fit_cost needs matching, non-empty pixel counts > 0 and times")
    if p.max() < MIN_SPREAD * p.min():
        a = 0.0 if fixed is None else float(np.clip(fixed, 0.0, t.min()))
        b = float(np.median((t - a) / p))
        return (a, b) if b > 0 else (0.0, float(np.median(t / p)))
    A = np.stack([np.ones_like(p), p], axis=1)
    a, b = np.linalg.lstsq(A, t, rcond=None)[0]
    a = float(np.clip(a, 0.0, t.min()))
    b = float(np.median((t - a) / p)) if not b > 0 else float(b)
    if not b > 0:
        return 0.0, float(np.median(t / p))
    return a, b


def quantise(scale: float, cfg: AdaptiveConfig) -> float:
    """``scale`` rounded down to a multiple of ``cfg.scale_step``, within [min_scale, 1]."""
    q = np.floor(scale / cfg.scale_step + 1e-9) * cfg.scale_step
    return float(np.clip(q, cfg.min_scale, 1.0))


def _stage_rows(history, k: int, use_cpu: bool) -> list[tuple[int, float]]:
    """(pixels, ms) of stage ``STAGES[k]`` over the samples that share its cost with a moving
    frame (every sample for SHARED_STAGES, the moving ones for the others), CPU ms if ``use_cpu``."""
    shared = STAGES[k] in SHARED_STAGES
    return [(s.pixels, _cost(s, use_cpu)[k]) for s in history if s.moving or shared]


def fixed_costs(history, previous: tuple | None = None) -> tuple:
    """Per stage of :data:`STAGES`, the fixed cost ``a`` of the line fitted to ``history`` where
    its sizes are spread by PIN_SPREAD or more, else the stage's entry of ``previous`` (None:
    none known yet): what :func:`fit_cost` assumes while a drag holds one size, and what may
    stretch the frame time (:func:`frame_ms`).  In CPU ms for a :func:`cpu_bound` renderer, else
    wall ms."""
    out, use_cpu = [], cpu_bound(history)
    for k in range(len(STAGES)):
        rows = _stage_rows(history, k, use_cpu)
        px = [r[0] for r in rows]
        if rows and max(px) >= PIN_SPREAD * min(px):
            out.append(fit_cost(*zip(*rows))[0])
        else:
            out.append(None if previous is None else previous[k])
    return tuple(out)


def cost_model(history, fixed: tuple | None = None) -> tuple[float, float]:
    """(a ms, b ms per pixel) of a moving frame in wall time: the sum over :data:`STAGES` of each
    stage's :func:`fit_cost` over the samples that share that stage's cost (every sample for
    SHARED_STAGES, the moving ones for the others; a stage no sample teaches costs nothing), with
    ``fixed`` (:func:`fixed_costs`) as the fixed costs of stages whose sizes are not spread.  For a
    :func:`cpu_bound` renderer fitted to CPU ms and times the moving frames' :func:`slowdown`."""
    a_sum = b_sum = 0.0
    use_cpu = cpu_bound(history)
    for k in range(len(STAGES)):
        rows = _stage_rows(history, k, use_cpu)
        if rows:
            a, b = fit_cost(*zip(*rows), fixed=None if fixed is None else fixed[k])
            a_sum, b_sum = a_sum + a, b_sum + b
    k = slowdown(history) if use_cpu else 1.0
    return k * a_sum, k * b_sum


def frame_ms(a: float, cfg: AdaptiveConfig) -> float:
    """Milliseconds a moving frame with fixed cost ``a`` is sized to: the budget, or
    ``a / (1 - min_pixel_share)`` when the fixed cost leaves the pixels less than that share, at
    most MAX_STRETCH x the budget."""
    return max(cfg.budget_ms, min(a / (1.0 - cfg.min_pixel_share), MAX_STRETCH * cfg.budget_ms))


def choose_scale(history, full_pixels: int, cfg: AdaptiveConfig = AdaptiveConfig(),
                 previous: float | None = None, fixed: tuple | None = None) -> float:
    """Share of the full size (per axis) for the next moving frame.

    Args:
        history: recent frames as :class:`Sample` s, oldest first (:func:`add_sample` keeps
            HISTORY moving and FULL_HISTORY full-size ones).
        full_pixels: pixel count of the full-resolution frame.
        cfg: the budget and limits.
        previous: the last moving frame's scale (growth is limited to cfg.max_growth per frame).
        fixed: the stages' fixed costs pinned earlier (:func:`fixed_costs`), used while the
            history's sizes are not spread enough to find them; only a pinned fixed cost
            stretches the frame time beyond the budget (:func:`frame_ms`).
    Returns:
        a multiple of cfg.scale_step in [cfg.min_scale, 1].
    """
    if full_pixels <= 0:
        raise ValueError(f"full_pixels must be > 0, got {full_pixels}")
    history = list(history)
    if not history:
        return quantise(FIRST_SCALE if previous is None else previous, cfg)
    a, b = cost_model(history, fixed)
    pinned = fixed_costs(history, fixed)
    if pinned[0] is None:
        target = cfg.budget_ms  # no pinned fixed cost: no stretching the budget
    else:
        target = frame_ms((slowdown(history) if cpu_bound(history) else 1.0) * sum(x or 0.0 for x in pinned), cfg)
    if b <= 0:
        scale = 1.0
    else:
        scale = float(np.sqrt(max(target - a, 0.0) / b / full_pixels))
    if previous is not None:
        scale = min(scale, previous * cfg.max_growth)
        predicted = a + b * previous * previous * full_pixels
        near_target = abs(predicted - target) <= HOLD_SLACK * target
        if near_target and abs(scale - previous) <= HOLD_STEPS * cfg.scale_step:
            scale = previous
    return quantise(scale, cfg)


def frame_size(full_size: tuple[int, int], scale: float, multiple: int = 2) -> tuple[int, int]:
    """(width, height) of a frame drawn at ``scale`` of ``full_size`` (both a multiple of
    ``multiple`` pixels, at least that)."""
    W, H = full_size
    w = max(multiple, int(round(W * scale / multiple)) * multiple)
    h = max(multiple, int(round(H * scale / multiple)) * multiple)
    return min(w, max(multiple, W - W % multiple)), min(h, max(multiple, H - H % multiple))


class Action(NamedTuple):
    """What a session does next: ``kind`` is "moving" (a reduced frame of the latest camera),
    "full" (the full-size frame, one sample per pixel), "refine" (the full-size supersampled frame)
    or "wait" (for ``wait_s`` seconds or the next update, whichever comes first; None = until the
    next update)."""

    kind: str
    wait_s: float | None = None


def next_action(now: float, version: int, last_change_t: float, moving_done: int, full_done: int,
                refined_done: int, refine: bool, cfg: AdaptiveConfig = AdaptiveConfig(),
                last_moving_t: float | None = None) -> Action:
    """The next step of a client session.

    Once the camera has been still for ``cfg.still_s``, the full-size frame goes out first with one
    sample per pixel (fast: the view sharpens to full size right after the stop), then, when
    ``refine`` (supersampling asked for), the supersampled frame replaces it.  While it moves, a
    moving frame starts at most every ``cfg.min_interval_s`` seconds.

    Args:
        now: current time (s, monotonic).
        version: counter of the latest camera / settings (bumped on every change).
        last_change_t: time of that change.
        moving_done, full_done, refined_done: versions of the last moving, full and supersampled
            frames sent (-1: none).
        refine: whether a supersampled frame follows the full one.
        cfg: the stillness delay and the pace of moving frames.
        last_moving_t: when the last moving frame started (s, monotonic; None: never).
    """
    if refined_done == version or (full_done == version and not refine):
        return Action("wait", None)
    still_for = now - last_change_t
    if still_for >= cfg.still_s - TIME_EPS:
        return Action("full" if full_done != version else "refine")
    if moving_done != version:
        early = 0.0 if last_moving_t is None else cfg.min_interval_s - (now - last_moving_t)
        if early <= TIME_EPS:
            return Action("moving")
        return Action("wait", min(early, cfg.still_s - still_for))
    return Action("wait", cfg.still_s - still_for)


def is_stale(job_version: int, latest_version: int) -> bool:
    """A frame rendered for ``job_version`` is dropped once a newer camera/settings exist."""
    return job_version != latest_version

"""The frames' smoothing checked against doing nothing (issue 30; capture.noise).

capture.noise measures the frames' noise from their fine detail and the plate stage smooths its copy of the frames
when that is at least a step.  The measurement cannot tell noise from a room's own texture at the pixel scale where
the camera moves (capture.noise.pair_noise tells them apart only for a camera that stays), and smoothing a textured
room blurs it into the plate (the test orbit with a 10 % grain: band error 0.0022 -> 0.0037; docs/matting.md).  So
before the plate stage smooths, :func:`smoothing_check` makes the plate of CHECK_VIEWS views both ways and asks which
predicts the views' held-back background (capture.plate's rings) better, against the frames *as they are*: the
noise of those pixels adds the same to both errors, a lost texture only to the smoothed one.  Where the smoothed
plate's error (median or RMS) is above CHECK_TOL times the other's, the stage reads the frames as they are and
says so.

Measured (the plate stage's 12 views, `/work/notes/s61/selfcheck.py`): the path-traced conifers and fur with noise
of 3 steps 0.72-0.92 (smoothing better), 1.5 steps 0.95-1.01; the clean captures, smoothed as if noisy, 1.02-1.66.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

#: Views the check makes its two plates of (evenly spaced, capture.plate_fixed.mode_frames).
CHECK_VIEWS = 12
#: The smoothed plate is refused where its held-back error, the views' median error or their RMS (each the median
#: over the views), is above this times the plate's from the frames as they are.  The median sees a typical
#: background pixel (a texture lost), the RMS the tails (needles the depth misses swamp it on the test scenes).
#: Ties go to the measured noise: the noisy orbit at 1.5 steps read RMS 1.008, median 0.91, and smoothing gained it
#: +0.15 dB held out.
CHECK_TOL = 1.02


def check_frames(n: int) -> list[int]:
    """The views of ``n`` the check reads: CHECK_VIEWS evenly spaced (all of them when fewer)."""
    from capture.plate_fixed import mode_frames

    return mode_frames(n, None, CHECK_VIEWS)


def smoothing_check(raw_views: list, smoothed_views: list, plane, focus, cfg) -> dict:
    """Whether the plate from ``smoothed_views`` predicts the held-back rings of ``raw_views`` (the same views as
    read; capture.plate.PlateView lists) no worse than CHECK_TOL times the plate from ``raw_views`` itself, on the
    path the raw views choose (``plane``, ``focus``, ``cfg``: as capture.plate.background_plates), by the median and
    the RMS of the views' held-back errors (both no worse than CHECK_TOL times).  Record: mode, rms_raw,
    rms_smoothed, median_raw, median_smoothed, views, smoothed (bool; an unknown error is not held against it)."""
    from capture.plate import choose_mode, plate_set, refit, ring_trial, tried_paths

    if len(raw_views) < 2:  # nothing to hold back against: not checked
        return {"mode": None, "rms_raw": None, "rms_smoothed": None, "median_raw": None, "median_smoothed": None,
                "views": len(raw_views), "smoothed": True}
    raw = plate_set(raw_views, plane, focus, cfg)
    sm = plate_set(smoothed_views, plane, focus, cfg)
    sm = replace(sm, views=tuple(replace(p, observed=q.observed) for p, q in zip(sm.views, raw.views, strict=True)))
    trials = {path: ring_trial(raw, path) for path in tried_paths(cfg)}
    mode = choose_mode({p: t.errors for p, t in trials.items()})
    errs = [_errors(refit(ps, mode, t)) for ps, t in ((raw, trials[mode]), (sm, ring_trial(sm, mode)))]
    (med_r, rms_r), (med_s, rms_s) = errs
    ok = not any(np.isfinite(r) and np.isfinite(m) and m > CHECK_TOL * r for r, m in ((med_r, med_s), (rms_r, rms_s)))
    def r5(x):
        return round(x, 5) if np.isfinite(x) else None  # None: no held-back pixel predicted

    return {"mode": mode, "rms_raw": r5(rms_r), "rms_smoothed": r5(rms_s), "median_raw": r5(med_r),
            "median_smoothed": r5(med_s), "views": len(raw_views), "smoothed": bool(ok)}


def _errors(trial) -> tuple[float, float]:
    """(median over views of their median error, of their RMS) of a capture.plate Trial; NaN when none."""
    e = np.asarray(trial.errors, np.float64).reshape(-1, 2)
    return tuple(float(np.nanmedian(e[:, k])) if np.isfinite(e[:, k]).any() else float("nan") for k in (0, 1))

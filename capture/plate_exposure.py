"""Whether the background plate's exposure gains beat none, on background pixels the gains were not fitted
on (capture.plate.background_plates), for either path.

Both plate paths fit each view's exposure gain to their predictions of the views' held-back background
rings (capture.plate.refit).  Such gains are each frame's exposure only when they predict *other*
background pixels better than no gains at all; a capture at one exposure gives gains that fit noise, a
background the path does not explain gives gains that fit the wrong background.  Where the check accepts
them, the photometric stage takes them as the views' exposure (volume/photometric.py), instead of the
object's own pairs.

* ``fixed``: capture.plate_fixed.fixed_exposure_check, on the grid of background pixels every frame sees
  (the fixed camera's own test); refused gains are set to 1 and the plates drawn without them.
* ``panorama`` (:func:`panorama_exposure_check`): each ring is split into two halves (its even and odd
  samples); gains are fitted on the first half as the path fits them (from pairs of views at once:
  capture.plate_pairs; with capture.plate_pairs.PANORAMA_PAIR_GAINS off, one pass of capture.plate.fit_gains from
  the predictions without gains), the rings predicted again with them, and the second half's error (per view,
  the mean largest-channel |log prediction - log colour| over the pixels neither dark nor blown out)
  compared with the error without gains.  The gains win a view when theirs is smaller; accepted, as the
  fixed camera's, when they win at least V / 2 + sqrt(V) of the V views and cut the median error by
  capture.plate_fixed.FIXED_GAIN_MIN_CUT.  Accepted, the plates are drawn with the fitted gains and the
  photometric stage takes them; refused, the plates are drawn at gain 1 as the fixed camera's
  (:data:`PANORAMA_REFUSED_AT_ONE`; before, they were drawn with the refused gains).

Both rules then look at the views one by one (:data:`VIEW_GAINS`, :func:`explained_views`).  The sign test
counts views, so an exposure that moved in a few frames only is refused: the other frames' gains are 1 within
noise and win half the time, and the median error is theirs.  A view whose error without gains stood
VIEW_GAIN_OUTLIER times above the views' median, and whose own gain cuts it by VIEW_GAIN_MIN_CUT, is taken
alone (its gain against the median of the others'); the others stay at 1, and the record's ``taken`` lists them.
Gains that fit noise cut nothing, and gains that do not fit the frames make errors grow, so neither passes.

Measured (docs/matting.md, "The panorama's exposure"): the demo's room capture (furrow synth, auto
exposure, a moving camera) is accepted; the path-traced orbits and the phone captures at one exposure
are refused.
"""

from __future__ import annotations

import numpy as np

#: The panorama's exposure check: the photometric stage may take the panorama's gains (True), else only the
#: fixed camera's (False: the rule before).
PANORAMA_EXPOSURE = True
#: Refused panorama gains are not used for the plates either: they are drawn at gain 1 (True), else with the
#: gains the check refused (False: the rule before; docs/matting.md "The panorama's exposure").
PANORAMA_REFUSED_AT_ONE = True
#: Where the sign test refuses the gains, a view's own gain is still taken when it explains that view (the others
#: kept at 1): its held-back error cut by VIEW_GAIN_MIN_CUT, where without it the view stood out at
#: VIEW_GAIN_OUTLIER times the views' median error (:func:`explained_views`).  False: all or none (the rule
#: before).  A fixed camera whose exposure jumped in 1-4 of 12 frames had every gain refused there (7-9 wins of
#: 10 needed, the median error not cut), and those frames stayed 0.5 EV off (docs/matting.md "Exposure that
#: changes in a few frames").
VIEW_GAINS = True
#: A view's gain must not spoil its far background (:func:`far_checked`; False: the ring alone, the rule before).
#: The ring lies beside the object; a shade there (a cloud's shadow on the wall behind, the operator's) passes for
#: an exposure on it: the path-traced orbit whose room was shaded to a quarter behind the crown in 3 of 18 frames
#: had two of them taken alone (+1.05 and +1.00 EV), and their object brightened by 1 EV.
FAR_CHECK = True
#: The far background: the pixels at least this fraction of the width from the object's depth.
FAR_FRACTION = 1 / 8
#: A view's gain is dropped where, on its far background, its error with the gain exceeds that without it by more
#: than this (mean largest-channel |log| difference; 0.03 EV): a frame's exposure cuts that error, a shade near
#: the object adds its own size to it, and gains of noise (checked only above FAR_MIN_EV) do neither.
FAR_MARGIN = 0.02
FAR_MIN_EV = 0.1
#: The held-back error a view's gain must cut, as a share of the error without it (VIEW_GAINS).
VIEW_GAIN_MIN_CUT = 0.5
#: How far a view's error without gains must stand above the views' median for its gain to be taken alone.
VIEW_GAIN_OUTLIER = 4.0


def plate_exposure(ps, mode: str, start, fit, samples=None):
    """(the plate stage's ``exposure`` record or None, the trial the plates are drawn with) for the chosen
    ``mode`` (module docstring): ``start`` the path's first trial (capture.plate.Trial, its first gains),
    ``fit`` its fitted one; ``samples``: the panorama's pair samples (capture.plate_pairs) when its gains
    came from them.  Refused gains give the trial at gain 1, except the views whose own gain is taken
    (VIEW_GAINS: the record's ``taken``)."""
    from capture.plate import ring_trial

    if mode == "fixed":  # the gains against none on held-back pixels: none unless they beat it
        from capture.plate_fixed import fixed_exposure_check

        exposure = fixed_exposure_check(ps, fit.gains)
        refused_at_one = True
    elif mode == "panorama" and PANORAMA_EXPOSURE:
        exposure = panorama_exposure_check(ps, start, samples)
        refused_at_one = PANORAMA_REFUSED_AT_ONE
    else:
        return None, fit
    if FAR_CHECK and exposure["chosen"] == "plate":  # a gain near the object only is the background's light
        exposure, fit = far_checked(ps, mode, fit, exposure)
    if exposure.get("taken"):  # the views' own gains, the others' at 1
        fit = ring_trial(ps, mode, some_gains(fit.gains, exposure["taken"]))
    elif exposure["chosen"] != "plate" and refused_at_one and not np.all(fit.gains == 1.0):
        fit = start if mode == "panorama" else ring_trial(ps, mode, np.ones_like(fit.gains))
    if exposure["chosen"] == "plate":
        exposure["gains"] = [[float(x) for x in g] for g in fit.gains]
    return exposure, fit


def some_gains(gains: np.ndarray, taken) -> np.ndarray:
    """``gains`` (V, 3) of the views ``taken`` against the median of the others' (which become 1)."""
    gains, taken = np.asarray(gains, np.float64), np.asarray(taken, np.int64)
    rest = np.ones(len(gains), bool)
    rest[taken] = False
    out = np.ones_like(gains)
    out[taken] = gains[taken] / (np.median(gains[rest], axis=0) if rest.any() else 1.0)
    return out


def explained_views(fit: np.ndarray, none: np.ndarray) -> np.ndarray:
    """The views (indices into ``fit`` / ``none``, the per-view held-back errors with the gains and without)
    whose own gain explains them (VIEW_GAINS): without it the view's error stood at VIEW_GAIN_OUTLIER times
    the views' median or more, and the gain cuts it by VIEW_GAIN_MIN_CUT.  A capture at one exposure has no
    such view (its gains fit noise: nothing cut); nor have gains that do not fit the frames (errors grow)."""
    fit, none = np.asarray(fit, np.float64), np.asarray(none, np.float64)
    if not VIEW_GAINS or len(none) == 0:
        return np.zeros(0, np.int64)
    out = none >= VIEW_GAIN_OUTLIER * np.median(none)
    out &= fit <= (1.0 - VIEW_GAIN_MIN_CUT) * none
    return np.flatnonzero(out & (none > 0))


def _log_error(observed: np.ndarray, predicted: np.ndarray, ok: np.ndarray) -> float:
    """Mean over ``ok`` of the largest channel's |log predicted - log observed| (NaN without any)."""
    if not ok.any():
        return float("nan")
    return float(np.abs(np.log(predicted[ok]) - np.log(observed[ok])).max(-1).mean())


def panorama_exposure_check(ps, start, samples=None) -> dict:
    """The panorama's gains against none on the second half of every ring (module docstring); ``start``:
    the path's trial without gains (capture.plate.Trial); ``samples``: the pair samples its gains were solved
    from (capture.plate_pairs; then the half's gains are solved from them the same way), or None (one pass of
    capture.plate.fit_gains, the rule before).  A record as fixed_exposure_check's."""
    from capture.plate import _usable, fit_gains
    from capture.plate_reproject import panorama_predict

    V = len(ps.views)
    obs = [p.observed for p in ps.views]
    if not np.all(start.gains == 1.0):  # pragma: no cover - the panorama starts without gains
        raise ValueError("panorama_exposure_check needs the trial without gains")
    if samples is not None:
        from capture.plate_pairs import pair_gains

        gains = pair_gains(ps, [np.arange(len(o)) % 2 == 0 for o in obs], samples)[0]
    else:
        gains = fit_gains([o[0::2] for o in obs], [np.asarray(p)[0::2] for p in start.predicted])
    with_g = panorama_predict(ps, gains)
    fit, none, pixels, ring = np.full(V, np.nan), np.full(V, np.nan), 0, [None] * V
    for i in range(V):
        o, p0, p1 = obs[i][1::2], start.predicted[i][1::2], with_g[i][1::2]
        ok = _usable(o) & np.isfinite(p0).all(-1) & np.isfinite(p1).all(-1)
        ok &= _usable(np.nan_to_num(p0)) & _usable(np.nan_to_num(p1))
        fit[i], none[i], pixels = _log_error(o, p1, ok), _log_error(o, p0, ok), pixels + int(ok.sum())
        ring[i] = ring_log2(o, p0, ok)
    have = np.isfinite(fit) & np.isfinite(none)
    need = int(np.ceil(V / 2 + np.sqrt(V)))
    rec = {"chosen": "none", "views": V, "wins": 0, "needed": need, "pixels": pixels, "path": "panorama",
           "ring_log2": ring}
    if not have.any():
        return {**rec, "reason": "no held-back background pixels the panorama predicts"}
    got, verdict = gain_verdict(fit[have], none[have], need)
    if "taken" in got:
        got["taken"] = [int(i) for i in np.flatnonzero(have)[got["taken"]]]
    return {**rec, **got, "reason": f"the panorama's gains (fitted on half of each ring) beat none in {got['wins']} of "
                                    f"{V} views on the other half ({verdict})"}


def ring_log2(observed: np.ndarray, predicted: np.ndarray, ok: np.ndarray) -> list | None:
    """Per channel the median log2 of the ``observed`` ring colours (N, 3) over the others' prediction at gain 1
    (``predicted``) where ``ok``: the view's exposure against the others' (capture.photometric_background); None
    with fewer than capture.photometric_background.BG_MIN_PIXELS."""
    from capture.photometric_background import BG_MIN_PIXELS

    if int(np.count_nonzero(ok)) < BG_MIN_PIXELS:
        return None
    r = np.log2(np.asarray(observed, np.float64)[ok] / np.asarray(predicted, np.float64)[ok])
    return [round(float(x), 5) for x in np.median(r, axis=0)]


def gain_verdict(fit: np.ndarray, none: np.ndarray, need: int) -> tuple[dict, str]:
    """The exposure checks' rule (capture.plate_fixed.fixed_exposure_check, panorama_exposure_check):
    per-view errors with the gains ``fit`` and without ``none`` (the same views); the gains win a view
    when theirs is smaller and are taken when they win at least ``need`` views and cut the median error
    by capture.plate_fixed.FIXED_GAIN_MIN_CUT.  (The record's chosen / wins / error_fitted / error_none,
    the verdict's words)."""
    from capture.plate_fixed import FIXED_GAIN_MIN_CUT

    wins = int((fit < none).sum())
    e_fit, e_none = float(np.median(fit)), float(np.median(none))
    cut = 1.0 - e_fit / e_none if e_none > 0 else 0.0
    ok = wins >= need and cut >= FIXED_GAIN_MIN_CUT
    why = "" if ok or wins < need else f" (at least {100 * FIXED_GAIN_MIN_CUT:.0f} % needed)"
    verdict = f"{'at least' if wins >= need else 'fewer than'} {need}, the median error cut by {100 * cut:.1f} %{why}"
    got = {"chosen": "plate" if ok else "none", "wins": wins, "error_fitted": round(e_fit, 5),
           "error_none": round(e_none, 5)}
    taken = np.zeros(0, np.int64) if ok else explained_views(fit, none)
    if len(taken):
        got.update(chosen="plate", taken=[int(i) for i in taken])
        verdict += (f"; {len(taken)} view(s) taken alone, each one's error cut by at least "
                    f"{100 * VIEW_GAIN_MIN_CUT:.0f} % where it stood at {VIEW_GAIN_OUTLIER:g}x the views' median "
                    f"or more: their own gains, the others kept as they are")
    else:
        verdict += ": taken" if ok else ": kept the views as they are"
    return got, verdict


def far_ring(object_depth: np.ndarray) -> np.ndarray:
    """(N, 2) int (x, y): the view's far background (pixels at least FAR_FRACTION of the width from the object's
    depth), at most capture.plate.RING_SAMPLES of them, evenly."""
    import cv2

    from capture.plate import even_sample

    m = np.asarray(object_depth) > 0
    dist = cv2.distanceTransform((~m).view(np.uint8), cv2.DIST_L2, 3)
    return even_sample(*np.nonzero(dist >= FAR_FRACTION * m.shape[1]))


def far_checked(ps, mode: str, fit, exposure: dict):
    """(the exposure record, the trial) with the views whose gain spoils their far background (:func:`far_ring`,
    predicted by the chosen path from the other views as the ring is; FAR_MARGIN) at 1: dropped from ``taken``
    (VIEW_GAINS; none left: nothing chosen), else, for gains taken for all views, set to 1 and the trial made
    again.  The record's ``not_taken_far`` lists them.  Only gains above FAR_MIN_EV in some channel are checked."""
    from capture.plate import ring_trial

    taken = exposure.get("taken") or []
    g = some_gains(fit.gains, taken) if taken else np.asarray(fit.gains, np.float64)
    check = list(taken) or [i for i in range(len(g)) if np.abs(np.log2(g[i])).max() > FAR_MIN_EV]
    gone = far_fails(ps, mode, g, check) if check else []
    if not gone:
        return exposure, fit
    out = {**exposure, "not_taken_far": gone,
           "reason": exposure.get("reason", "") + f"; views {', '.join(map(str, gone))} kept at gain 1: their gain "
                     "does not explain their background away from the object (the light changed near it)"}
    if taken:
        out["taken"] = [i for i in taken if i not in gone]
        out["chosen"] = "plate" if out["taken"] else "none"
        return out, fit
    g = np.array(fit.gains, np.float64)
    g[gone] = 1.0
    if np.all(g == 1.0):  # no gain left: the photometric stage aligns the views itself
        out["chosen"] = "none"
    return out, ring_trial(ps, mode, g)


def far_fails(ps, mode: str, gains: np.ndarray, check) -> list[int]:
    """The views of ``check`` whose far background (:func:`far_ring`) the path predicts worse with ``gains`` than
    with theirs at 1, by more than FAR_MARGIN (views without far pixels it predicts pass: nothing measured)."""
    from dataclasses import replace

    from capture.plate import _usable, path_functions

    far = []
    for i, p in enumerate(ps.views):  # the views not checked predict nothing (an empty ring)
        r = far_ring(p.view.object_depth) if i in check else np.zeros((0, 2), np.int64)
        far.append(replace(p, ring=r, observed=np.asarray(p.view.linear[r[:, 1], r[:, 0]], np.float64)))
    far_ps = replace(ps, views=tuple(far))
    g0 = np.array(gains, np.float64)
    g0[list(check)] = 1.0
    predict = path_functions(mode)[1]
    with_g, without = predict(far_ps, gains), predict(far_ps, g0)
    gone = []
    for i in check:
        o, p1, p0 = far[i].observed, np.asarray(with_g[i]), np.asarray(without[i])
        ok = _usable(o) & np.isfinite(p1).all(-1) & np.isfinite(p0).all(-1)
        ok &= _usable(np.nan_to_num(p1)) & _usable(np.nan_to_num(p0))
        if ok.any() and _log_error(o, p1, ok) > _log_error(o, p0, ok) + FAR_MARGIN:
            gone.append(int(i))
    return gone

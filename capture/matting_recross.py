"""The cubes re-crossed in each view's tint (issue 30, eleventh round).

capture.matting_global.cross_cells crosses the lines B -> C of every cube across the views, then finds
each view's brightness k of the object (view_brightness) and its tint t about it
(capture.matting_contrast.view_chroma) from the same lines through the cubes' colours.  The cubes were
crossed as if every view saw the needles in one colour: where the views see them at different
brightness (an orbit's lit and shadowed sides), a cube's lines are those of k_v F, not of F, and its
crossing is not the needles' hue (ninth round: on seeded views of one tint and brightness 0.7-1.4 the
tint then costs up to 0.0065 of the worst view's error).

:func:`recross` crosses once more with every view's lines divided by its factors K_v = k_v t_v (C / K,
B / K, the matte's colour / K: in each view's own tint, C = a F + (1 - a) B becomes C / K = a F / K +
(1 - a) B / K, so that every view's lines point at the one colour F / K), then finds the views'
brightness and tint again in that space (K2, near 1 where the first pass held them) and gives each
view K K2.  The lines' weights, the matte's alpha and each pixel's filled flag are the first pass's.

It does nothing (the record ``cells.global.recross`` says why) when off, when the first pass found no
view's brightness or tint (all K 1: views of one brightness are left bit for bit as they were), or
when the second pass's object colour fails where the first's passed (the first pass is kept).

Held out (gather, `scripts/issue30_table.py` over the eight captures, docs/matting.md eleventh round): the
orbits +0.015 / +0.016 / +0.047, the turntables -0.013 (made-on) / -0.008 / +0.022, the room + table + AE +
lens and the fur the same digits (no view's factor found; no view measures its alpha error), the black
twins the same digits; mean +0.010 dB.  On seeded views of one tint and brightness 0.7-1.4 the worst
view's median error 0.013-0.033 -> 0.003-0.010 (tests/capture/test_matting_recross.py).

RECROSS_MEAN_ONE (after the eleventh round, off: its docstring; docs/matting.md) holds the views' factors at a
geometric mean of 1 a channel before the lines are divided by them and in the product returned.
"""

from __future__ import annotations

import numpy as np

#: Cross the cubes once more in each view's tint (module docstring; on: the eleventh round's rule, a mean
#: held-out gain over the eight captures with no capture losing more than 0.03 dB, was met: +0.010, worst -0.013).
RECROSS = True
#: At most how many times the cubes are re-crossed, each pass in the factors of the passes before it (1: once);
#: the passes stop where one finds no factor (its views' brightness scatters no more than its noise).
RECROSS_PASSES = 1
#: Hold the views' factors at a geometric mean of 1 a channel (over all the views) before the lines are divided
#: by them, and each pass's factors likewise before they multiply the product returned.  A factor shared by all
#: the views is not in the lines (it trades against the object's colour: F s with K / s gives the same colours),
#: so only the views' differences are removed and the passes cannot drift by it (the turntables' passes found
#: 0.983 in every view, every pass).  The geometric mean because the factors multiply: it is the one mean that a
#: common scale s moves by exactly s, and a view at 2x and one at 0.5x balance.  Off: the eleventh round as it was.
RECROSS_MEAN_ONE = False  # off: held out mean -0.0091 dB, made-on turntable -0.0304 (docs/matting.md)


def view_factors(k, n_views: int) -> np.ndarray:
    """(n_views, 3) each view's factors: ``k`` a scalar brightness a view (n_views,) repeated over the
    channels, or the brightness times the tint (n_views, 3) as it is."""
    K = np.asarray(k, np.float64)
    return np.repeat(K.reshape(n_views, 1), 3, 1) if K.ndim == 1 else K.reshape(n_views, 3).copy()


def mean_one(K: np.ndarray) -> np.ndarray:
    """(n_views, 3) the factors ``K`` over their geometric mean a channel across the views (RECROSS_MEAN_ONE),
    ``K`` as it is when off."""
    if not RECROSS_MEAN_ONE:
        return K
    return K / np.exp(np.log(np.maximum(K, 1e-12)).mean(0))


#: Where the first pass's crossing gave way to the matte's mean colour (capture.matting_global.mean_checked), the
#: later passes take their own mean too: they cross the same lines.
STICKY_MEAN = True


def _summary(rec: dict) -> dict:
    """The parts of a pass's record that say what it found: its object colour, brightness and tint."""
    return {key: rec[key] for key in ("colour", "mean", "brightness", "chroma", "reason") if key in rec}


def recross(cross_once, first: tuple, C, B, w, alpha, colour, fill, gsum, group, view, n_views: int) -> tuple:
    """capture.matting_global.cross_cells' result ``first`` (F, sigma^2, the object's colour, each view's
    factors, the record) for its inputs (``C``, ``B``, ``w``, ``alpha``, ``colour``, ``fill``, ``gsum``,
    ``group``, ``view``, ``n_views``), crossed again by ``cross_once`` (one pass, the same arguments) with
    every view's lines in its own factors (module docstring; RECROSS_PASSES times, each in the factors found
    so far, stopping at a pass whose object colour fails); the same five, each view's factors (n_views, 3)
    the product of the passes'.  ``first`` as it is, its record saying why, where it does nothing."""
    F, sig2, F_obj, k, rec = first
    if not RECROSS:
        return F, sig2, F_obj, k, {**rec, "recross": {"reason": "off"}}
    K = view_factors(k, n_views)
    if np.all(K == 1.0):
        return F, sig2, F_obj, k, {**rec, "recross": {"reason": "no view's brightness or tint found"}}
    K = mean_one(K)
    vi, last, fail = np.asarray(view, np.int64), None, None
    sticky = {"mean": True} if STICKY_MEAN and (rec.get("mean") or {}).get("taken") else {}
    for _ in range(RECROSS_PASSES):  # each pass in the factors found so far
        t = K[vi]
        C2, B2, colour2 = (np.asarray(x, np.float64) / t for x in (C, B, colour))
        F2, s2, Fo2, k2, rec2 = cross_once(C2, B2, w, alpha, colour2, fill, gsum, group, view, n_views, **sticky)
        if Fo2 is None:
            fail = rec2
            break
        K2 = mean_one(view_factors(k2, n_views))
        K = K * K2
        last = (F2, s2, Fo2, rec2, K2, (last[5] if last else 0) + 1)
        if np.all(view_factors(k2, n_views) == 1.0):  # the factors stopped moving: another pass would repeat this one
            break
    if last is None:
        why = "the object's colour fails in the views' tint: the first pass kept"
        return F, sig2, F_obj, k, {**rec, "recross": {"reason": why, "second": _summary(fail)}}
    F2, s2, Fo2, rec2, K2, passes = last
    rng = [[round(float(x), 3) for x in K.min(0)], [round(float(x), 3) for x in K.max(0)]]
    second = [round(float(K2.min()), 4), round(float(K2.max()), 4)]
    out = {"first": _summary(rec), "range": rng, "second_range": second}
    if RECROSS_PASSES > 1:
        out.update(passes=passes, stopped=None if fail is None else _summary(fail))
    return F2, s2, Fo2, K, {**rec2, "recross": out}

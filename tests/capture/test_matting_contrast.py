"""The object's lines where the two alphas agree, by their lever, and each view's tint
(capture.matting_contrast; issue 30, ninth round), against the exact truth of seeded samples.

The agreeing lines: 6,000 lines of one needle colour (each needle's own within sd 0.01) before
backgrounds 0.1-0.6, 5 % of them false: background pixels the matte calls faintly partial (alpha
0.05-0.15) behind a plate error that puts their line 0.6 of the way to a redder colour.  All lines
crossed: 0.0042-0.0047 from the truth (seeds 0-2); the agreeing ones 0.0001-0.0004, as the true lines alone.

The lever (off by default, tried and not kept): lines of one needle colour (sd 0.01), 80 % before dark
backgrounds near it (short lines) and 20 % before bright ones; the short lines' backgrounds carry a
shared error (read 0.02 too dark in red, as a plate's): the plain crossing is pulled by 0.006
(measured 0.0061-0.0063, seeds 0-2), the lines weighted by their lever miss by 0.0004-0.0022.
Without the error both are near the truth (plain 0.0002-0.0004, weighted 0.0005-0.0023: the weights
cost some efficiency).
"""

from __future__ import annotations

import numpy as np

from capture import matting_contrast as mk
from capture import matting_lines as ml
from capture import matting_recross as mr

NEEDLE = np.array([0.045, 0.065, 0.023])
#: The weighted crossing's error, with or without the short lines' error (measured 0.0004-0.0023).
LEVER_TOL = 0.003
#: ... and at most this share of the plain crossing's where the short lines carry an error (0.07-0.35).
LEVER_SHARE = 0.5


def _lines(seed: int, n: int = 6000):
    rng = np.random.default_rng(seed)
    dark = rng.random(n) < 0.8
    B = np.where(dark[:, None], np.array([0.14, 0.08, 0.06]) + rng.normal(0, 0.02, (n, 3)),
                 rng.uniform(0.3, 0.9, (n, 3)))
    a = rng.uniform(0.3, 0.85, n)
    C = a[:, None] * (NEEDLE + rng.normal(0, 0.01, (n, 3))) + (1 - a[:, None]) * B + rng.normal(0, 0.002, (n, 3))
    return C, B, a, dark


def _cross(C, B, w, a):
    F, _ = mk._one_group(C, B, w, a)
    return np.linalg.norm(F - NEEDLE)


#: The agreeing lines' crossing: its error at most this (measured 0.0001-0.0004) ...
AGREE_ERR = 0.001
#: ... and all lines' at least this (measured 0.0042-0.0047: the test can fail).
PULLED = 0.003


def _false_lines(seed: int, n: int = 6000):
    rng = np.random.default_rng(seed)
    false = rng.random(n) < 0.05
    B = rng.uniform(0.1, 0.6, (n, 3))
    A = rng.uniform(0.3, 0.9, n)
    C = A[:, None] * (NEEDLE + rng.normal(0, 0.01, (n, 3))) + (1 - A[:, None]) * B + rng.normal(0, 0.002, (n, 3))
    C = np.where(false[:, None], B + 0.6 * (NEEDLE + np.array([0.1, 0.0, 0.0]) - B), C)  # the plate B is wrong there
    a = np.where(false, rng.uniform(0.05, 0.15, n), np.clip(A + rng.normal(0, 0.05, n), 0.01, 0.99))
    return C, B, a, false


def test_the_lines_the_two_alphas_agree_on_are_not_pulled_by_false_lines(monkeypatch):
    fill = np.broadcast_to(np.array([0.06, 0.055, 0.026]), (6000, 3))  # the matte's colour: the olive fill
    for seed in range(3):
        C, B, a, false = _false_lines(seed)
        w = np.ones(len(a))
        w2, rec = mk.agreeing_lines(C, B, w, a, fill)
        assert not (w2[false] > 0).any() and (w2[~false] > 0).mean() > 0.99 and 0.9 < rec["share"] < 0.97
        assert _cross(C, B, w2, a) <= AGREE_ERR and _cross(C, B, w, a) >= PULLED
        monkeypatch.setattr(mk, "AGREEING", False)
        assert mk.agreeing_lines(C, B, w, a, fill) == (w, {"reason": "off"})
        monkeypatch.setattr(mk, "AGREEING", True)
    w2, rec = mk.agreeing_lines(C[:8], B[:8], np.ones(8), a[:8], fill[:8])
    assert rec["reason"].endswith("lines agree") and np.all(w2 == 1)


def test_the_lines_by_their_lever_are_not_pulled_by_the_short_lines(monkeypatch):
    monkeypatch.setattr(mk, "CONTRAST", True)
    for seed in range(3):
        C, B, a, dark = _lines(seed)
        Bm = B - dark[:, None] * np.array([0.02, 0.0, 0.0])  # the short lines' backgrounds read too dark in red
        w = np.ones(len(a))
        w2, rec = mk.contrast_weights(C, Bm, w, a)
        plain, lever = _cross(C, Bm, w, a), _cross(C, Bm, w2, a)
        assert "plain" in rec and lever <= LEVER_TOL and lever <= LEVER_SHARE * plain
        assert np.isclose(np.median(w2), 1.0)  # the weights' scale is kept
        w2, _ = mk.contrast_weights(C, B, w, a)
        assert _cross(C, B, w, a) <= LEVER_TOL and _cross(C, B, w2, a) <= LEVER_TOL


def test_the_weights_fall_back_and_say_why(monkeypatch):
    monkeypatch.setattr(mk, "CONTRAST", True)
    C, B, a, _ = _lines(0, n=8)  # too few lines to cross
    w = np.ones(len(a))
    w2, rec = mk.contrast_weights(C, B, w, a)
    assert w2 is w and rec == {"reason": "the plain lines do not cross"}
    monkeypatch.setattr(mk, "CONTRAST", False)
    C, B, a, _ = _lines(0)
    w2, rec = mk.contrast_weights(C, B, np.ones(len(a)), a)
    assert rec == {"reason": "off"} and np.all(w2 == 1.0)


def _tinted_views(seed: int, tints, per: int = 400):
    """One view's samples a camera (``tints`` (V, 3): each view's needles' colour is NEEDLE times its tint),
    8 cells each before every view's own background; the matte's colour the trunk's fill."""
    rng = np.random.default_rng(seed)
    views, truth = [], []
    for t in np.asarray(tints, np.float64):
        cell = np.repeat(np.arange(8), per)
        pts = np.stack([cell % 2, cell // 2 % 2, cell // 4], 1) + rng.uniform(0.05, 0.95, (len(cell), 3))
        B = rng.uniform(0.3, 0.9, (8, 3))[cell] + rng.uniform(-0.02, 0.02, (len(cell), 3))
        A = rng.uniform(0.5, 0.84, len(cell))
        F = np.broadcast_to(NEEDLE * t, B.shape)
        C = np.clip(A[:, None] * F + (1 - A[:, None]) * B + rng.normal(0, 0.002, B.shape), 0, 1)
        a = np.clip(A + rng.normal(0, 0.05, A.shape), 0.01, 0.84)
        views.append({"index": np.arange(len(cell)), "pts": pts, "C": C, "B": B, "a": a,
                      "F0": np.broadcast_to(np.array([0.3, 0.2, 0.08]), F.shape), "usable": np.ones(len(cell), bool),
                      "sb": np.zeros(len(cell))})
        truth.append(F)
    return views, truth


def _worst(views, truth, colours):
    err = []
    for c, v, t in zip(colours, views, truth, strict=True):
        F = np.array(v["F0"], np.float64)
        if c is not None:
            F[c[0]] = c[1]
        err.append(np.median(np.linalg.norm(F - t, axis=-1)))
    return max(err)


#: Each view's colours with its tint: the worst view's median error at most this (measured 0.0044-0.0126,
#: without the tint 0.0149-0.0166).
TINT_TOL = 0.015
#: Views of one tint and different brightness: the tint costs at most this (measured 0-0.0024: a known
#: weakness, the cubes crossed across views of different brightness are not quite the needles' hue).
TINT_COST = 0.003
TINTS = ((1.0, 1.0, 1.0), (1.3, 1.1, 0.8), (0.8, 0.9, 1.3), (1.2, 1.2, 1.2), (0.7, 0.8, 0.9))


def test_each_views_tint_is_found_and_its_colours_follow_it(monkeypatch):
    """Views whose needles differ in colour, not only in brightness (an orbit's sunlit and sky-lit sides):
    with the tint each view's colours within TINT_TOL of its truth, and nearer than without it."""
    for seed in range(3):
        views, truth = _tinted_views(seed, TINTS)
        errs = []
        for on in (True, False):
            monkeypatch.setattr(mk, "VIEW_CHROMA", on)
            colours, rec = ml.cell_colours(views, [0.05] * len(views), cells=2)
            errs.append(_worst(views, truth, colours))
        assert errs[0] <= TINT_TOL and errs[0] < errs[1]
        assert rec["global"]["chroma"] == {"reason": "off"}


def test_views_of_one_tint_lose_little_and_one_brightness_has_none(monkeypatch):
    """The tint's own cost on views of one tint, the cubes crossed once (capture.matting_recross off).  Re-crossed
    in each view's factors the worst view errs 0.0042-0.0087 with the tint, 0.0011-0.0066 without (seeds 0-2): the
    tint costs 0.0021-0.0033 there, a stated weakness; crossed once, with the tint, 0.012-0.019
    (tests/capture/test_matting_recross.py)."""
    monkeypatch.setattr(mr, "RECROSS", False)
    for seed in range(3):
        views, truth = _tinted_views(seed, [(k, k, k) for k in (0.7, 1.0, 1.4, 1.0, 0.85)])
        errs = []
        for on in (True, False):
            monkeypatch.setattr(mk, "VIEW_CHROMA", on)
            colours, _ = ml.cell_colours(views, [0.05] * len(views), cells=2)
            errs.append(_worst(views, truth, colours))
        assert errs[0] <= errs[1] + TINT_COST
    monkeypatch.setattr(mk, "VIEW_CHROMA", True)
    views, truth = _tinted_views(0, np.ones((5, 3)))
    _, rec = ml.cell_colours(views, [0.05] * len(views), cells=2)
    assert "chroma" not in rec["global"] and rec["global"]["brightness"]["reason"].startswith("the views' brightness")


def test_the_two_passes_give_the_references_tinted_colours():
    """The pipeline's two passes (capture.matting_cells: the fit's table, each view applying its own brightness
    and tint) give cell_colours' colours bit for bit on tinted views."""
    from capture import matting_cells as mc

    views, _ = _tinted_views(0, TINTS)
    views = [{**v, **{k: np.asarray(v[k], np.float32) for k in ("pts", "C", "B", "a", "F0", "sb")}} for v in views]
    ref, rrec = ml.cell_colours(views, [0.05] * len(views), cells=2)
    assert "tau" in rrec["global"]["chroma"]
    table, rec = mc.fit_cells([mc.fit_sample(v, 10 ** 6, k) for k, v in enumerate(views)], cells=2)
    assert np.asarray(table["brightness"]).shape == (len(views), 3)
    for k, (v, r) in enumerate(zip(views, ref, strict=True)):
        got, _ = mc.apply_cells(v, table, 0.05, view=k)
        assert all(np.array_equal(x, y) for x, y in zip(r, got, strict=True))


def test_a_view_without_an_alpha_error_borrows_the_views_median_where_most_measured_one(monkeypatch):
    sa, rec = mk.pooled_alpha_errors([0.05, None, 0.07, 0.06])
    assert sa == [0.05, 0.06, 0.07, 0.06] and rec == {"borrowed": 1, "sigma_alpha": 0.06}
    sa, rec = mk.pooled_alpha_errors([0.05, None, None, 0.06], [True, True, True, False])  # 1 of 3 with samples
    assert sa == [0.05, None, None, 0.06] and rec["reason"] == "only 1 of 3 views measured one"
    assert mk.pooled_alpha_errors([None] * 3)[0] == [None] * 3  # the fur: none measured
    views, truth = _tinted_views(1, TINTS)
    errs = []
    for on in (True, False):
        monkeypatch.setattr(mk, "POOL_ALPHA_ERROR", on)
        colours, rec = ml.cell_colours(views, [0.05, 0.05, None, 0.05, 0.05], cells=2)
        errs.append(_worst([views[2]], [truth[2]], [colours[2]]))
    assert colours[2] is None and rec["views_without_alpha_error"] == 1
    assert errs[0] <= TINT_TOL < errs[1]  # the trunk's fill kept: 0.29 off


def test_the_stages_two_passes_pool_the_alpha_errors_as_the_reference(monkeypatch):
    from capture import matting_cells as mc
    from capture.matting_lines import line_samples
    from capture.view_map import serial_map
    from tests.capture.test_matting_cells import _scene
    from volume.surroundings import cell_colour_passes, cell_colour_stage

    monkeypatch.setattr(mc, "SIGMA_GATE", False)  # the seeded scene's lines scatter more than the shipped bar
    photos, plates, matted = _scene()
    sa, gains = [0.1, 0.08, None], np.array([[1.0, 1.0, 1.0], [1.2, 1.1, 1.0], [1.0, 0.9, 1.1]])
    whole = [line_samples(s.camera, photos[k].linear_rgb, plates[k].background, plates[k].known, s.alpha, s.rgb,
                          s.depth, plates[k].estimated, plates[k].sigma) for k, s in enumerate(matted)]
    ref, rrec = cell_colour_stage(tuple(matted), whole, sa, gains, lambda s: s)
    fits = [mc.fit_sample(s, 10 ** 6, k) for k, s in enumerate(whole)]
    got, rec = cell_colour_passes(matted, (plates, photos), fits, sa, gains, serial_map)
    assert rec["alpha_error_pooled"] == rrec["alpha_error_pooled"] == {"borrowed": 1, "sigma_alpha": 0.09}
    assert "views_without_alpha_error" not in rec and rec["coloured"] == rrec["coloured"] > 0
    for r, g in zip(ref, got, strict=True):
        assert np.array_equal(r.rgb, g.rgb) and np.array_equal(r.alpha, g.alpha)
    assert not np.array_equal(got[2].rgb, matted[2].rgb)


def test_two_views_one_blind_keep_the_blind_ones_colour():
    assert mk.pooled_alpha_errors([None, 0.05]) == ([None, 0.05], {"borrowed": 0,
                                                                    "reason": "only 1 of 2 views measured one"})

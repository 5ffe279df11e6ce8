"""What teaches capture.matting_blind's coverage table (stop 82): MIN_CONFIDENCE, the data weight a pixel needs to
teach it (1.0: the surest pixels only; the depth's own coverage stands in elsewhere), and MIN_R2_VARIANCE, the guard
that refuses a table held back on alphas that do not vary.  The table's own mechanism:
tests/capture/test_matting_blind.py (at TABLE_CONFIDENCE, the value before)."""

from __future__ import annotations

import numpy as np
import pytest

from capture import matting_blind as mb
from tests.capture.test_matting_blind import TABLE_CONFIDENCE, _prior_given, _scene, _solve


def test_a_table_held_back_on_opaque_pixels_alone_is_refused(monkeypatch):
    """Where the only pixels confident enough to train the coverage table are opaque (MIN_CONFIDENCE raised so that
    only the depth's opaque pixels, target 1, reach it), its held-back R^2 has nothing to explain: it is 0
    (MIN_R2_VARIANCE) and the table is refused, where a table that predicts 1 everywhere had scored R^2 = 1 and given
    its alpha to every blind pixel; _weighted_r2 of constant targets is 0, of varying ones their R^2."""
    rng = np.random.default_rng(2)
    y = rng.random(500)
    w = np.ones(500)
    assert mb._weighted_r2(np.ones(500), np.ones(500), w) == 0.0
    assert mb._weighted_r2(y, y, w) == 1.0 and mb._weighted_r2(np.full(500, y.mean()), y, w) == pytest.approx(0.0)
    C, plate, A, F, D = _scene(1, 3.0)
    noise = np.random.default_rng(5).random(D.shape) < 0.5
    monkeypatch.setattr(mb, "MIN_CONFIDENCE", 1.0)
    rec = _solve(C, plate, D, mask=noise).notes["blind_prior"]
    assert rec["train"] >= 2 * mb.MIN_TRAIN and not rec["used"] and rec["r2"] == 0.0, rec
    monkeypatch.setattr(mb, "MIN_R2_VARIANCE", 0.0)  # the check before: the degenerate table was taken
    rec = _solve(C, plate, D, mask=noise).notes["blind_prior"]
    assert rec["used"] and rec["r2"] == 1.0, rec


def test_colour_data_biased_towards_opaque_do_not_teach_the_blind_pixels(monkeypatch):
    """MIN_CONFIDENCE 1.0 (stop 82): where the colour data of the pixels confident enough to teach the table are biased
    (+0.15 alpha, as a 320 x 240 conifer's are before a bright room, its colour sources holding some of the room), a
    table taught at 0.25 hands the bias on to the pixels without data; at the default the table is not taught by them
    and the depth's own coverage (unbiased here) is their prior."""
    monkeypatch.setattr(mb, "HIT_DETAIL", 0.0)
    rng = np.random.default_rng(11)
    h, w = 64, 64
    mask = np.zeros((h, w), bool)
    mask[:, :40] = rng.random((h, 40)) < 0.95
    mask[:, 24:48] &= rng.random((h, 24)) < 0.5  # a fringe: coverage between 0 and 1
    cov = mb.coverage(mask)
    truth = cov
    image = np.full((h, w, 3), 0.3)
    blind = rng.random((h, w)) < 0.3
    image[blind] = 1.0  # blown out: no data term
    weight = np.where(blind, 0.0, 0.8)
    target = np.where(blind, 0.0, np.clip(truth + 0.15, 0.0, 1.0))
    unknown = np.ones((h, w), bool)
    errs = {}
    for mc in (TABLE_CONFIDENCE, mb.MIN_CONFIDENCE):
        monkeypatch.setattr(mb, "MIN_CONFIDENCE", mc)
        t, _, rec = mb.blind_prior(image, unknown, target, weight, mask)
        assert _prior_given(rec), rec
        errs[mc] = float(np.mean(t[blind] - truth[blind]))
    assert mb.MIN_CONFIDENCE > TABLE_CONFIDENCE
    assert errs[TABLE_CONFIDENCE] > 0.1 and abs(errs[mb.MIN_CONFIDENCE]) < 0.03, errs

"""The panorama's exposure check (capture.plate_exposure.panorama_exposure_check) on the orbit scene of
tests/plate_scenes.py: a moving camera with auto exposure gets its gains accepted (and they are the true
exposures within GAIN_TOL_EV / GAIN_RMS_EV); the same capture at one exposure gets them refused.  Measured
here with the gains from pairs of views (capture.plate_pairs, stop 48): 12 of 12 views won, the error cut 98.8 %;
the gains against the truth at most 0.0007 EV, RMS 0.0004 EV (the true exposures spread 0.25 EV a channel);
at one exposure 0 of 12 views won, the error not cut.  (With the gains fitted to the panorama's predictions,
the rule before: 12 of 12, cut 64.5 %, at most 0.081 EV, RMS 0.039; at one exposure 5 of 12, cut 0.0 %.)"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import capture.plate_exposure as pe
from capture.plate import PlateConfig, background_plates
from tests import plate_scenes as ps

#: The accepted gains against the true exposures (EV): largest and RMS over views and channels.
GAIN_TOL_EV = 0.12
GAIN_RMS_EV = 0.05
#: Views large enough for rings of GAIN_MIN_SAMPLES (capture.plate) in each half.
WIDTH, HEIGHT = 320, 240
#: A camera's noise (linear, standard deviation) in the test of refused gains.
NOISE = 0.02


def _orbit(gains=None):
    views, _ = ps.orbit_capture(width=WIDTH, height=HEIGHT)
    if gains is not None:  # the camera's exposure: colour = true colour / g
        views = [replace(v, linear=(v.linear / g).astype(np.float32)) for v, g in zip(views, gains, strict=True)]
    return views, np.array([0.0, 0.0, 1.0, -ps.TABLE_Z])


def test_auto_exposure_of_a_moving_camera_is_taken_from_its_panorama():
    gains = np.exp(np.random.default_rng(5).normal(0.0, 0.25, (12, 3)))
    views, plane = _orbit(gains)
    _, rec = background_plates(views, PlateConfig(), plane)
    assert rec["mode"] == "panorama"
    ex = rec["exposure"]
    assert ex["chosen"] == "plate", ex
    want = np.log2(gains / np.median(gains, axis=0))
    got = np.log2(np.asarray(ex["gains"]))
    err = got - want
    assert np.abs(err).max() <= GAIN_TOL_EV and np.sqrt(np.mean(err ** 2)) <= GAIN_RMS_EV, err
    assert np.sqrt(np.mean(err ** 2)) < 0.25 * np.std(want)  # far closer than doing nothing


def test_one_exposure_is_kept_as_it_is():
    views, plane = _orbit()
    _, rec = background_plates(views, PlateConfig(), plane)
    assert rec["mode"] == "panorama" and rec["exposure"]["chosen"] == "none", rec["exposure"]
    assert "gains" not in rec["exposure"]


@pytest.mark.parametrize("on", [True, False])
def test_the_switch_leaves_the_plates_as_they_were(monkeypatch, on):
    """The check only tells the photometric stage; the plates are drawn with the fitted gains either way."""
    monkeypatch.setattr(pe, "PANORAMA_EXPOSURE", on)
    gains = np.exp(np.random.default_rng(5).normal(0.0, 0.25, (12, 3)))
    views, plane = _orbit(gains)
    plates, rec = background_plates(views, PlateConfig(), plane)
    assert ("exposure" in rec) == on
    monkeypatch.setattr(pe, "PANORAMA_EXPOSURE", not on)
    other, _ = background_plates(views, PlateConfig(), plane)
    for a, b in zip(plates, other, strict=True):
        np.testing.assert_array_equal(a.background, b.background)


@pytest.mark.parametrize("at_one", [True, False])
def test_refused_gains_are_not_drawn_into_the_plates(monkeypatch, at_one):
    """At one exposure the check refuses the panorama's gains; the plates are then drawn at gain 1
    (PANORAMA_REFUSED_AT_ONE), and are at least as close to the true background as the ones drawn with the
    refused gains (the rule before, param False: its gains are not all 1, so the first assert fails it).
    The views carry a camera's noise (NOISE, seeded), which the refused gains fit.  Measured: median
    RMS against the true background 0.01434 at gain 1, 0.01436 with the refused gains."""
    monkeypatch.setattr(pe, "PANORAMA_REFUSED_AT_ONE", at_one)
    views, truth = ps.orbit_capture(width=WIDTH, height=HEIGHT)
    rng = np.random.default_rng(11)
    views = [replace(v, linear=np.clip(v.linear + rng.normal(0.0, NOISE, v.linear.shape), 0.0, 1.0).astype(np.float32))
             for v in views]
    plane = np.array([0.0, 0.0, 1.0, -ps.TABLE_Z])
    plates, rec = background_plates(views, PlateConfig(), plane)
    assert rec["exposure"]["chosen"] == "none"
    drawn_at_one = np.all(np.asarray(rec["gains_ev"]) == 0.0)
    if not at_one:
        assert not drawn_at_one
        return
    assert drawn_at_one, rec["gains_ev"]
    monkeypatch.setattr(pe, "PANORAMA_REFUSED_AT_ONE", False)
    before, _ = background_plates(views, PlateConfig(), plane)

    def rmse(ps_):
        e = [np.sqrt(np.nanmean((p.background[p.known] - t[p.known]) ** 2)) for p, t in zip(ps_, truth, strict=True)]
        return float(np.median(e))

    assert rmse(plates) <= rmse(before) * 1.001, (rmse(plates), rmse(before))


@pytest.mark.parametrize("view_gains", [True, False])
def test_one_view_brighter_is_taken_alone(monkeypatch, view_gains):
    """One view of the orbit 0.5 EV brighter than the other eleven: the sign test refuses the gains (5 wins of 10
    needed: the other views need none).  With VIEW_GAINS the views whose gains explain their held-back error are
    taken (the bright view and the two neighbours its light spoiled, whose own gains stay within GAIN_RMS_EV of
    1), and the bright view's gain is the truth within GAIN_TOL_EV; the rule before left it at gain 1."""
    monkeypatch.setattr(pe, "VIEW_GAINS", view_gains)
    gains = np.ones((12, 3))
    gains[5] = 2.0 ** 0.5
    views, plane = _orbit(gains)
    _, rec = background_plates(views, PlateConfig(), plane)
    ex, ev = rec["exposure"], np.asarray(rec["gains_ev"])
    assert ex["wins"] < ex["needed"], ex
    if not view_gains:
        assert ex["chosen"] == "none" and np.all(ev == 0.0), ex
        return
    assert ex["chosen"] == "plate" and 5 in ex["taken"] and len(ex["taken"]) <= 3, ex
    assert np.abs(ev[5] - 0.5).max() <= GAIN_TOL_EV, ev[5]
    assert np.abs(np.delete(ev, 5, axis=0)).max() <= GAIN_RMS_EV, ev

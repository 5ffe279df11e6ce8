"""Whether the fitted relighting transfer can be trusted for a new light (render.relight.trust).  The capture
colours and the truth under the new light come from the independent reference of test_calibrate (the
transfer integrated by brute force over the analytic maps), not from render.shading.transfer."""

from __future__ import annotations

import numpy as np

from render.relight import calibrate as cb
from render.relight import trust
from render.shading import transfer as rl
from render.shading.envmap import EnvMap
from tests import scenes as scene
from tests.render.relight.test_calibrate import SUN, _capture, _fit, _radiance, reference_transfer

#: The new light of the fallback cases: a small sharp sun low in another direction, little sky.
NEW_SUN = dict(sun=(-0.5, 0.4, 0.3), ambient=0.05, sky=0.1, power=60.0, sharpness=200.0)
UP = (0.0, 0.0, 1.0)


def _errors(fit, samples, a_env, a_light, b_env, b_light, truth) -> dict:
    """RMS log error against the reference's true B / A luminance gain at capture points, per transfer:
    the fitted one, the default, the single gain."""
    sub = trust._subsample(samples, 2000)
    basis = tuple(rl.MIX_BASIS)
    a = cb.basis_transfers(sub, a_env, UP, None, basis)[:3]
    b = cb.basis_transfers(sub, b_env, UP, None, basis)[:3]
    want = np.log(reference_transfer(sub.normals, sub.views, *truth, b_light)) \
        - np.log(reference_transfer(sub.normals, sub.views, *truth, a_light))
    lg = trust._log_gains([fit.candidate, cb.key(*cb.DEFAULT_TRANSFER), cb.key(*cb.GAIN_TRANSFER)], a, b, 0.0)
    return {k: float(np.sqrt(np.mean((x - want) ** 2))) for k, x in zip(("fitted", "default", "gain"), lg)}


def test_a_capture_under_flat_light_is_not_trusted_for_a_sun():
    """Made to defeat the estimator: under light of one radiance from everywhere the capture cannot tell a
    lit side from an unlit one, so every kernel fits; a sun then asks what it never showed.  The fallback (the
    single gain) fires whatever the material, and its worst error over three materials is below the fit's."""
    flat = EnvMap(np.full((32, 64, 3), 0.5, np.float32), "flat")
    flat_light = lambda d: np.full((len(d), 3), 0.5)
    sun, sun_light = scene.sun_sky_env(128, **NEW_SUN), (lambda d: _radiance(d, **NEW_SUN))
    worst = {"fitted": 0.0, "gain": 0.0}
    for truth in (([0, 0, 0.5, 0.5], 0.0, 0.8), ([0, 1, 0, 0], 0.0, 0.8), ([0, 0, 0, 1], 1.0, 0.5)):
        samples = _capture(*truth, flat_light, seed=2)
        fit = _fit(samples, flat)
        choice = trust.choose_transfer(fit, samples, flat, sun, UP, regularise=0.0)
        assert choice.source == "gain" and choice.spread > trust.SPREAD_MAX, choice.reason
        assert choice.reason.startswith("the single global gain instead of")
        assert (choice.kernel, choice.forward) == cb.GAIN_TRANSFER[:2]
        err = _errors(fit, samples, flat, flat_light, sun, sun_light, truth)
        worst = {k: max(worst[k], err[k]) for k in worst}
    assert worst["gain"] < worst["fitted"] - 0.1, worst


def test_a_capture_under_a_sun_keeps_its_fit():
    """A capture whose light shows the material (sun and sky): the transfers within noise agree under a sun
    from elsewhere and under a small low sun, the fit is kept, and it is far nearer the truth than the gain."""
    light = lambda d: _radiance(d, **SUN)
    env = scene.sun_sky_env(128, **SUN)
    truth = ([0.0, 0.25, 0.5, 0.25], 1.0, 0.5)
    samples = _capture(*truth, light)
    fit = _fit(samples, env)
    turned = {**SUN, "sun": (-0.3, 0.6, 0.5)}
    for params in (turned, NEW_SUN):
        b_env, b_light = scene.sun_sky_env(128, **params), (lambda d, p=params: _radiance(d, **p))
        choice = trust.choose_transfer(fit, samples, env, b_env, UP, regularise=0.0)
        assert choice.source == "fitted" and choice.spread <= trust.SPREAD_MAX, choice.reason
        err = _errors(fit, samples, env, light, b_env, b_light, truth)
        assert err["fitted"] < 0.5 * err["gain"], err


def test_decision_is_minimax():
    fit = cb.TransferFit(cb.rl.mix_kernel([0, 0.5, 0.5, 0]), 2.0, 0.5, 0.1, {}, 100,
                         plausible=((cb.rl.mix_kernel([0, 0.5, 0.5, 0]), 2.0, 0.5),))
    assert trust._decide(fit, 0.05, {"default": 0.01, "gain": 0.01}, {}).source == "fitted"   # they agree
    assert trust._decide(fit, 0.3, {"default": 0.4, "gain": 0.5}, {}).source == "fitted"      # the safest
    d = trust._decide(fit, 0.3, {"default": 0.2, "gain": 0.5}, {"top": 0.1, "side +x": 0.6})
    assert d.source == "default" and (d.kernel, d.forward, d.forward_g) == cb.DEFAULT_TRANSFER
    assert "60% of the new light, on the side +x" in d.reason
    assert trust._decide(fit, 0.3, {"default": 0.4, "gain": 0.3}, {}).source == "gain"        # a tie: do nothing
    default = cb.TransferFit(*cb.DEFAULT_TRANSFER, 0.1, {}, 100, plausible=(cb.key(*cb.DEFAULT_TRANSFER),))
    d = trust._decide(default, 0.3, {"default": 0.3, "gain": 0.5}, {})
    assert d.source == "default" and d.reason.startswith("the default transfer: the capture shows none better")
    assert trust._decide(default, 0.3, {"default": 0.3, "gain": 0.2}, {}).source == "gain"


def test_dark_shares():
    """Light only from above in the capture: a new light from everywhere reaches the underside mostly from
    directions the capture left dark, the top hardly; the same light again asks nothing beyond it.  Exact
    shares of the wrap kernel max(c + 1/2, 0) under uniform light: the top 1/9 (c in -1/2..0 of -1/2..1), the
    bottom 8/9, a side 1/2; to the 16-row maps' resolution."""
    d = EnvMap(np.zeros((32, 64, 3), np.float32)).pixel_directions()
    sky = EnvMap(np.where(d[..., 2:3] > 0, 1.0, 0.0).repeat(3, -1).astype(np.float32), "sky")
    flat = EnvMap(np.full((32, 64, 3), 1.0, np.float32), "flat")
    n = np.array([[0, 0, 1.0], [0, 0, -1.0], [1.0, 0, 0], [0, -1.0, 0]])
    shares = trust.dark_shares(sky, flat, UP, n)
    assert abs(shares["top"] - 1 / 9) < 0.01 and abs(shares["bottom"] - 8 / 9) < 0.01, shares
    assert abs(shares["side +x"] - 0.5) < 0.01 and abs(shares["side -y"] - 0.5) < 0.01
    assert max(trust.dark_shares(sky, sky, UP, n).values()) == 0.0

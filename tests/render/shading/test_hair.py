"""The hair lobes (render/shading/hair.py) against energy conservation and brute-force integration."""

from __future__ import annotations

import numpy as np
import pytest

from render.shading.hair import (
    HairParams,
    attenuation,
    back_albedo,
    fibre_angles,
    fibre_radiance,
    fibre_scattering,
    log_i0e,
    scattering,
    sigma_a_from_colour,
)

#: Furnace / normalisation tolerance of the midpoint quadrature below (measured ~1e-6).
FURNACE_TOL = 1e-4
#: Width average (WIDTH_NODES = 16) against a 4000-node midpoint integral over h: max error as a
#: fraction of the largest value (measured 0.3 %).
WIDTH_TOL_OF_PEAK = 0.01


def _sphere_integral(sin_o, h, sigma_a, prm, nt=900, nphi=1080):
    """integral of S(wo, wi, h) d omega_i on a midpoint grid in (theta_i, phi)."""
    th = (np.arange(nt) + 0.5) / nt * np.pi - np.pi / 2
    ph = (np.arange(nphi) + 0.5) / nphi * 2 * np.pi - np.pi
    T, P = np.meshgrid(th, ph, indexing="ij")
    S = scattering(sin_o, np.sin(T), P, h, sigma_a, prm)
    return (S * np.cos(T)[..., None]).sum((0, 1)) * (np.pi / nt) * (2 * np.pi / nphi)


@pytest.mark.parametrize("beta", [0.15, 0.3, 0.7])
@pytest.mark.parametrize("sin_o, h", [(0.0, 0.0), (0.5, 0.3), (-0.8, -0.9), (0.95, 0.99)])
def test_white_furnace(beta, sin_o, h):
    """No absorption: a fibre scatters all the light it receives, for every wo and h."""
    prm = HairParams(beta_m=beta, beta_n=beta)
    got = _sphere_integral(sin_o, h, np.zeros(3), prm)
    np.testing.assert_allclose(got, 1.0, atol=FURNACE_TOL)


def test_absorbing_fibre_scatters_the_sum_of_its_attenuations():
    """With absorption each lobe still integrates to its A_p: M_p and N_p are normalised."""
    prm = HairParams()
    sa = sigma_a_from_colour([0.5, 0.2, 0.06])
    for sin_o, h in ((0.3, 0.2), (-0.6, 0.8)):
        got = _sphere_integral(sin_o, h, sa, prm)
        want = attenuation(np.sqrt(1 - sin_o**2), h, sa, prm.eta).sum(0)
        np.testing.assert_allclose(got, want, rtol=FURNACE_TOL)
        assert np.all(want < 1)


def test_width_average_matches_brute_force():
    prm = HairParams()
    sa = sigma_a_from_colour([0.5, 0.2, 0.06])
    rng = np.random.default_rng(0)
    so, si, ph = rng.uniform(-0.9, 0.9, 150), rng.uniform(-0.9, 0.9, 150), rng.uniform(0, np.pi, 150)
    h = (np.arange(4000) + 0.5) / 4000 * 2 - 1
    ref = scattering(so[:, None], si[:, None], ph[:, None], h[None], sa, prm).mean(1)
    got = fibre_scattering(so, si, ph, sa, prm)
    assert np.abs(got - ref).max() < WIDTH_TOL_OF_PEAK * ref.max(), np.abs(got - ref).max() / ref.max()
    # the width average depends on |phi| only
    np.testing.assert_allclose(fibre_scattering(so, si, -ph, sa, prm), got, rtol=1e-9)


def test_r_lobe_is_shifted_by_twice_the_scale_tilt():
    """Marschner's shift: the reflection peak sits at theta_i = -theta_o + 2 alpha (towards the root)."""
    prm = HairParams(beta_m=0.1, alpha_deg=4.0)
    opaque = np.full(3, 50.0)  # no TT / TRT: only R remains
    th_o = np.radians(30)
    th = np.radians(np.linspace(-89, 89, 3561))
    S = fibre_scattering(np.sin(th_o), np.sin(th), 0.0, opaque, prm)[:, 0] * np.cos(th)
    peak = np.degrees(th[np.argmax(S)])
    assert abs(peak - (-30 + 2 * 4.0)) < 0.5, peak


def test_tt_lobe_sends_light_forward():
    """A light fibre lit from behind: TT dominates in the forward direction (phi = pi)."""
    prm = HairParams()
    sa = sigma_a_from_colour([0.8, 0.8, 0.8])
    fwd = fibre_scattering(0.0, 0.0, np.pi, sa, prm)
    back = fibre_scattering(0.0, 0.0, 0.0, sa, prm)
    assert np.all(fwd > 5 * back)


def test_fast_radiance_equals_the_reference_sum():
    rng = np.random.default_rng(1)
    N, L = 400, 6
    unit = lambda a: a / np.linalg.norm(a, axis=-1, keepdims=True)
    T, wo, d = unit(rng.normal(size=(N, 3))), unit(rng.normal(size=(N, 3))), unit(rng.normal(size=(L, 3)))
    P, vis = rng.uniform(0.1, 2, (L, 3)), rng.uniform(0, 1, (N, L))
    sa = sigma_a_from_colour(rng.uniform(0.03, 0.8, (N, 3)))
    ref = np.zeros((N, 3))
    for k in range(L):
        so, si, ph = fibre_angles(T, wo, np.broadcast_to(d[k], (N, 3)))
        ref += fibre_scattering(so, si, ph, sa) * P[k] * vis[:, k:k + 1]
    got = fibre_radiance(T, wo, d, P, vis, sa)
    assert np.abs(got - ref).max() < 1e-4 * ref.max()  # float32 in the fast path


def test_log_i0e_matches_scipy():
    from scipy.special import i0e

    x = np.linspace(0, 300, 30001)
    np.testing.assert_allclose(np.exp(log_i0e(x)), i0e(x), rtol=1e-6)


def test_colour_inversion_and_back_albedo():
    c = np.array([[0.05, 0.3, 0.9]])
    sa = sigma_a_from_colour(c)
    assert np.all(np.diff(sa[0]) < 0) and np.all(sa > 0)  # lighter colour, less absorption
    rb = back_albedo(sa)
    assert rb.shape == (1, 3) and np.all((rb > 0.04) & (rb < 1))
    assert np.all(np.diff(rb[0]) > 0)
    with pytest.raises(ValueError, match="beta_m"):
        HairParams(beta_m=0.0)

"""Matting with a known background (capture.matting_known) against the true alpha and colour.

The scene (tests/plate_scenes.needle_composite): thin needles, mostly partial pixels, over a textured
room, the photo quantised to 8-bit sRGB.  Measured (seeds 0 and 1): alpha MSE 0.0029 / 0.0042 with
the known background against 0.087 for the estimate without it and 0.051 for the binary depth mask;
premultiplied colour error 0.0097 / 0.0112 against 0.027 / 0.024; over black 0.0095 / 0.0124 and the
premultiplied colour equal to the photo's 8-bit codes within 1 near the depth.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from capture.camera import Camera, make_K
from capture.fill import push_pull
from capture.matting import MatteConfig, depth_trimap, matte_scan, solve_known, solve_matte
from capture.matting_known import (
    alpha_lower_bound,
    known_background_matte,
    known_background_matte_reference,
)
from capture.plate import Plate
from capture.scan import Scan, srgb_to_linear, to_uint8_srgb
from tests import plate_scenes as ps

ALPHA_MSE_TOL = 0.006
#: The known background must cut the estimate's alpha MSE to this fraction, its premultiplied error to this.
BEAT_ESTIMATE = 0.15
BEAT_ESTIMATE_PREMUL = 0.5
#: Mean |F - true F| where the true alpha is above 0.3.
F_TOL = 0.03
BLACK_ALPHA_MSE_TOL = 0.02
#: Fast path against the slow reference (alpha).
TWIN_TOL = 1e-3
#: The round-5 preconditioner and CG tolerance against the solve before them and a tight solve (largest
#: alpha difference; measured on phone views 1-3e-4, docs/speed.md round 5).
PRECOND_TOL = 1e-3
NOISE_8BIT_BLACK = 1.0 / 255 / 12.92


def _q(x):
    """8-bit sRGB round trip of a linear image (the photo as written)."""
    return srgb_to_linear(to_uint8_srgb(x) / np.float32(255.0))


@pytest.mark.parametrize("seed", [0, 1])
def test_known_background_gives_the_needles_their_alpha_and_colour(seed):
    C, B, A, F, D = ps.needle_composite(seed=seed)
    C = _q(C)
    tri = depth_trimap(D)
    region = (A > 0) | (tri > 0)
    m = solve_known(C, tri, B, np.ones(A.shape, bool), 0.004, "plate", D > 0)
    e = solve_matte(C, tri, "estimate")
    mse, mse_e = (float(np.mean((x.alpha - A)[region] ** 2)) for x in (m, e))
    assert mse <= ALPHA_MSE_TOL and mse <= BEAT_ESTIMATE * mse_e, (mse, mse_e)
    want = A[..., None] * F
    prem, prem_e = (float(np.abs(x.alpha[..., None] * x.foreground - want)[region].mean()) for x in (m, e))
    assert prem <= BEAT_ESTIMATE_PREMUL * prem_e, (prem, prem_e)
    assert np.abs(m.foreground - F)[A > 0.3].mean() <= F_TOL
    assert m.method == "plate"


@pytest.mark.parametrize("seed", [0, 1])
def test_over_black_the_premultiplied_colour_is_the_photo(seed):
    C, B, A, F, D = ps.needle_composite(seed=seed, background=np.zeros(3))
    C = _q(C)
    tri = depth_trimap(D)
    m = solve_known(C, tri, B, np.ones(A.shape, bool), NOISE_8BIT_BLACK, "backdrop", D > 0)
    near = ndimage.binary_dilation(D > 0, iterations=2)  # where a renderer draws
    diff = np.abs(to_uint8_srgb(C).astype(int) - to_uint8_srgb(m.alpha[..., None] * m.foreground).astype(int))
    assert diff.max(axis=-1)[near].max() <= 1
    region = (A > 0) | (tri > 0)
    assert np.mean((m.alpha - A)[region] ** 2) <= BLACK_ALPHA_MSE_TOL


def test_fast_path_matches_the_slow_reference():
    C, B, A, F, D = ps.needle_composite(seed=0)
    sl = (slice(30, 54), slice(40, 64))
    tri = depth_trimap(D)[sl]
    known = np.ones(tri.shape, bool)
    known[:4] = False  # part of the crop without a plate: the Laplacian alone there
    a, Fa, _, ok = known_background_matte(_q(C)[sl], tri, B[sl], known)
    r, Fr = known_background_matte_reference(_q(C)[sl], tri, B[sl], known)
    assert ok and np.abs(a - r).max() <= TWIN_TOL
    exact = known & (a > 0)
    assert np.abs(Fa - Fr)[exact].max() <= 1e-2


def test_the_preconditioner_and_tolerance_against_pymattings_default(monkeypatch):
    """capture.matting_known.ICHOL_DISCARD with CG_RTOL (round 5) against the solve before it (pymatting's
    discard threshold 1e-4, CG_RTOL 1e-5) and against a tight solve (1e-4, 1e-10), on the whole needle
    scene: alpha within PRECOND_TOL of both, and no further from the tight solve than the old one plus
    PRECOND_TOL / 4."""
    from capture import matting_known as mk

    C, B, A, F, D = ps.needle_composite(seed=1)
    C, tri, known = _q(C), depth_trimap(D), np.ones(A.shape, bool)
    known[:10] = False
    runs = {}
    for name, disc, rtol in (("new", mk.ICHOL_DISCARD, mk.CG_RTOL), ("old", 1e-4, 1e-5), ("tight", 1e-4, 1e-10)):
        monkeypatch.setattr(mk, "ICHOL_DISCARD", disc)
        monkeypatch.setattr(mk, "CG_RTOL", rtol)
        runs[name] = known_background_matte(C, tri, B, known, 0.004, D > 0)
        assert runs[name][3]
    new, old, tight = (runs[k][0] for k in ("new", "old", "tight"))
    assert np.abs(new - old).max() <= PRECOND_TOL and np.abs(new - tight).max() <= PRECOND_TOL
    assert np.abs(new - tight).max() <= np.abs(old - tight).max() + PRECOND_TOL / 4
    assert np.abs(new - old).max() > 0  # the two solves differ: the test compares something


def test_pymatting_warnings_stay_off_stdout(monkeypatch, capsys):
    """pymatting prints its preconditioner's warnings on stdout (the path-traced conifer's
    Laplacian triggers one per view), which holds `furrow model --json`."""
    import pymatting

    real = pymatting.ichol

    def loud(A, *args, **kwargs):
        print("PERFORMANCE WARNING: Thresholded incomplete Cholesky decomposition failed")
        return real(A, *args, **kwargs)

    monkeypatch.setattr(pymatting, "ichol", loud)
    C, B, A, F, D = ps.needle_composite(seed=0)
    sl = (slice(30, 54), slice(40, 64))
    known_background_matte(_q(C)[sl], depth_trimap(D)[sl], B[sl], np.ones((24, 24), bool))
    assert capsys.readouterr().out == ""


def test_alpha_bound_keeps_the_colour_in_range(monkeypatch):
    import capture.matting_known as mk

    monkeypatch.setattr(mk, "NOISE_REL", 0.0)  # the exact bound; the noise allowance only lowers it
    rng = np.random.default_rng(0)
    F = rng.uniform(0, 1, (500, 3))
    B = rng.uniform(0, 1, (500, 3))
    a = rng.uniform(0, 1, (500, 1))
    C = a * F + (1 - a) * B
    lo = alpha_lower_bound(C, B, 0.0)
    assert np.all(lo <= a[:, 0] + 1e-9)  # the truth is never ruled out
    Fl = B + (C - B) / np.maximum(lo, 1e-9)[:, None]
    assert np.all((Fl >= -1e-6) & (Fl <= 1 + 1e-6))  # and at the bound F is still a colour
    assert np.all(alpha_lower_bound(C, B, 0.01) <= lo)


def test_push_pull_fills_and_keeps():
    v = np.zeros((9, 13, 3))
    w = np.zeros((9, 13))
    v[2, 3], w[2, 3] = (0.5, 0.2, 0.1), 1.0
    out = push_pull(v, w)
    assert np.allclose(out, (0.5, 0.2, 0.1))  # one source: everything gets its colour
    v[7, 11], w[7, 11] = (0.1, 0.1, 0.9), 1.0
    out = push_pull(v, w)
    assert np.allclose(out[2, 3], (0.5, 0.2, 0.1)) and np.allclose(out[7, 11], (0.1, 0.1, 0.9))
    assert out[1, 2, 0] > out[8, 12, 0]  # nearer the first source, more of its colour
    assert not push_pull(v, np.zeros((9, 13))).any()


def _scan(C, D, alpha=None):
    h, w = D.shape
    cam = Camera(make_K(100, 100, (w - 1) / 2, (h - 1) / 2), np.eye(4), w, h)
    return Scan(np.asarray(C, np.float32), D, cam, "v", alpha)


def test_matte_scan_paths_with_a_plate():
    C, B, A, F, D = ps.needle_composite(seed=0)
    plate = Plate(B, np.ones(A.shape, bool), 0.004, "fixed", 1.0, 0.0, 0.0)
    s = _scan(_q(C), D)
    assert matte_scan(s, cfg=MatteConfig(), plate=plate).method == "plate"
    assert matte_scan(s, cfg=MatteConfig()).method == "estimate"  # no plate, a room: estimated
    with pytest.raises(ValueError, match="plate"):
        matte_scan(s, cfg=MatteConfig(mode="plate"))
    # the given matte keeps its alpha and, with a plate, takes the room out of the colour exactly
    g = matte_scan(_scan(_q(C), D, A), plate=plate)
    part = (A > 0.2) & (A < 0.9)
    assert g.method == "given" and np.array_equal(g.alpha, A)
    assert np.abs(g.foreground - F)[part].mean() <= F_TOL
    # over a black backdrop, detected: the backdrop path
    Cb, _, _, _, _ = ps.needle_composite(seed=0, background=np.zeros(3))
    assert matte_scan(_scan(_q(Cb), D)).method == "backdrop"


def test_an_opaque_disc_whose_depth_misses_its_edge_stays_opaque():
    """A flat opaque disc over a plain backdrop on a 64 x 48 image, its depth two rows short at the
    bottom (as the extent stage cut a sphere): the widening reaches the disc's rows without depth
    (WIDEN_MIN_PX), so no pixel of the disc is held at alpha 0 and the Laplacian keeps the disc
    opaque (at a 1 px widening its alpha fell to 0.53 next to them); outside the disc the straight
    colour is the disc's (a bilinear lookup across the edge mixes in no backdrop)."""
    H, W = 48, 64
    yy, xx = np.mgrid[0:H, 0:W]
    disc = (xx - 32) ** 2 + (yy - 22) ** 2 <= 15 ** 2
    Bc = np.array([0.24, 0.15, 0.09], np.float32)
    Fc = np.array([0.64, 0.40, 0.24], np.float32)
    C = _q(np.where(disc[..., None], Fc, Bc).astype(np.float32))
    depth = np.where(disc & (yy <= 22 + 15 - 3), 0.5, 0.0).astype(np.float32)
    B = np.broadcast_to(Bc, C.shape)
    a, F, _, ok = known_background_matte(C, depth_trimap(depth), B, np.ones((H, W), bool), NOISE_8BIT_BLACK)
    assert ok
    assert a[disc].min() >= 0.99, np.percentile(a[disc], [0, 1, 5])
    assert a[~ndimage.binary_dilation(disc)].max() <= 0.01
    ring = ndimage.binary_dilation(disc, iterations=2) & ~disc & (a <= 0)
    assert ring.sum() > 50 and np.abs(F[ring] - Fc).max() <= 0.01


def _fringe_before_a_blown_wall():
    """A fur-like object: opaque rows 0-19 of colour F0 (the background behind them unknown), a fringe of alpha
    0.5 and colour F0 in rows 20-25 before a wall of linear 1.6 that the plate holds clipped at 1 (blown out,
    the photo not clipped), the wall alone below; a column block of the opaque rows is clipped white in the photo."""
    f0 = np.array([0.3, 0.15, 0.05])
    a = np.zeros((40, 40))
    a[:20], a[20:26] = 1.0, 0.5
    C = a[..., None] * f0 + (1.0 - a[..., None]) * 1.6
    C[:12, 30:] = 1.0  # a highlight the photo clipped: no colour source
    B = np.where(a[..., None] >= 1.0, 0.2, 1.0) * np.ones(3)
    known = np.zeros((40, 40), bool)
    known[20:] = True
    return np.clip(C, 0.0, 1.0), a, B, known, f0


def test_too_few_sure_colours_before_a_blown_wall_take_the_opaque_pixels(monkeypatch):
    """capture.matting_known.OPAQUE_SOURCES: a fringe before a blown-out plate takes the nearest sure colour (step 4);
    where the known background gives fewer than MIN_SOURCES (a fur ball on a turntable: no frame saw behind its
    body), the opaque pixels whose photo is not clipped are the sources, so the fringe keeps the object's colour
    exactly, not the fallback's (pymatting's estimate, here the photo: the wall's white in it; s19fur90 held out
    20.375 -> 20.728 dB, docs/matting.md)."""
    import capture.matting_known as mk

    C, a, B, known, f0 = _fringe_before_a_blown_wall()
    fringe = a == 0.5

    def fallback(image, alpha, need):
        return image

    rec = {}
    F = mk.foreground_colour(C, a, B, known, fallback, rec)
    np.testing.assert_allclose(F[fringe], np.broadcast_to(f0, F[fringe].shape), atol=1e-9)
    assert rec == {"opaque_sources": int(fringe.sum())}  # the record says so (furrow model prints it)
    monkeypatch.setattr(mk, "OPAQUE_SOURCES", False)
    rec_off = {}
    F_off = mk.foreground_colour(C, a, B, known, fallback, rec_off)
    assert rec_off == {}
    from capture.matting_cap import blown_cap

    np.testing.assert_allclose(F_off[fringe], blown_cap(C, C, a, B, known)[fringe], atol=1e-12)  # the fallback's
    assert np.abs(F_off[fringe] - f0).mean() > 0.4


def test_a_colour_before_a_blown_plate_stays_within_what_the_photo_allows(monkeypatch):
    """capture.matting_cap.blown_cap: before a blown-out plate (held at 1, the true wall 1.6) the premultiplied colour
    is at most the photo + the noise in every channel the photo did not clip, whatever the alpha; a fill far brighter
    than the object (the nearest sure colours before a sunlit wall) comes down to that bound, the true colour is kept
    even where the matte's alpha is too low, and a clipped channel is left alone."""
    import capture.matting_cap as mc

    f_true, a_true = np.array([0.2, 0.1, 0.04]), 0.97
    C = np.broadcast_to(a_true * f_true + (1.0 - a_true) * 1.6, (4, 4, 3)).copy()
    B = np.ones((4, 4, 3))
    blown = np.ones((4, 4), bool)
    bright = np.broadcast_to([0.5, 0.26, 0.1], (4, 4, 3)).copy()
    for a_model in (0.99, 0.97, 0.8):  # the matte's alpha above, at and below the truth
        a = np.full((4, 4), a_model)
        capped = mc.blown_cap(bright, C, a, B, blown)
        assert np.all(capped * a[..., None] <= C + mk_noise(C) + 1e-12)  # the photo's own noise
        assert np.all(capped * a[..., None] <= bright * a[..., None] + 1e-12)
        kept = mc.blown_cap(np.broadcast_to(f_true * a_true / a_model, (4, 4, 3)), C, a, B, blown)
        np.testing.assert_allclose(kept, f_true * a_true / a_model * np.ones((4, 4, 1)), atol=1e-12)  # the truth
    a = np.full((4, 4), 0.99)
    assert np.abs(mc.blown_cap(bright, C, a, B, blown) * 0.99 - a_true * f_true).max() < \
        np.abs(bright * 0.99 - a_true * f_true).max() / 2  # the fill's error at least halved here
    C_clip = C.copy()
    C_clip[..., 0] = 1.0
    assert np.all(mc.blown_cap(bright, C_clip, a, B, blown)[..., 0] == 0.5)
    monkeypatch.setattr(mc, "BLOWN_CAP", False)
    assert mc.blown_cap(bright, C, a, B, blown) is bright


def mk_noise(level):
    """capture.matting_known's noise at a linear level (NOISE_ABS + NOISE_REL level): of C - B at the plate's, of the
    photo at its own."""
    from capture.matting_known import NOISE_ABS, NOISE_REL

    return NOISE_ABS + NOISE_REL * level


def test_a_dark_opaque_body_before_a_blown_plate_keeps_the_photos_brightness(monkeypatch):
    """capture.matting_cap.CAP_SLACK_OF_PHOTO: a truly opaque dark body (alpha 1, the photo its own colour) before a
    blown-out plate whose fill is far brighter comes down to the photo within the photo's own noise (NOISE_ABS +
    NOISE_REL C); with the plate's slack (NOISE_REL B, B about 1: the rule before) it stays 0.034 above the photo,
    which a furry bunny's orbit showed as 0.073 too bright in 8-bit sRGB (docs/matting.md)."""
    import capture.matting_cap as mc
    from capture.matting_known import NOISE_ABS, NOISE_REL

    body = np.broadcast_to([0.05, 0.03, 0.015], (4, 4, 3)).copy()  # the photo = the true colour (alpha 1)
    B = np.ones((4, 4, 3))
    a = np.ones((4, 4))
    blown = np.ones((4, 4), bool)
    fill = np.broadcast_to([0.3, 0.2, 0.1], (4, 4, 3)).copy()  # the nearest sure colours, far brighter
    capped = mc.blown_cap(fill, body, a, B, blown)
    np.testing.assert_allclose(capped, body + NOISE_ABS + NOISE_REL * body, atol=1e-12)
    assert np.abs(capped - body).max() <= NOISE_ABS + NOISE_REL * 0.05 + 1e-12
    monkeypatch.setattr(mc, "CAP_SLACK_OF_PHOTO", False)
    before = mc.blown_cap(fill, body, a, B, blown)
    np.testing.assert_allclose(before - body, NOISE_ABS + NOISE_REL, atol=1e-12)  # the plate's slack: 0.034 above

"""Matting at the working resolution (capture.matting_scale) against the full-size closed-form solve,
on a seeded image with an exact matte: thin strands (partial pixels, coverage integrated exactly by
supersampling) and a body over a textured background, C = a F + (1 - a) B."""

from __future__ import annotations

import numpy as np
import pytest

from capture import matting_scale
from capture.matting import BG, FG, UNKNOWN, MatteConfig, depth_trimap, matte_scan, solve_matte
from capture.matting_scale import (
    FULL_SIZE_ABOVE,
    OBJECT_WORK_PX,
    SOLID_BAND_SHARE,
    SOLID_WORK_PX,
    band_share,
    downscale_trimap,
    guided_upsample,
    guided_upsample_at,
    matte_at_scale,
    working_scale,
)
from capture.scan import Scan

#: Image size and supersampling of the exact coverage.
W, H, SS = 320, 240, 4
#: The working-resolution alpha against the full-size solve at scale 0.5: alpha MSE over the frame
#: at most issue 32's bar (measured 0.00082) and over the trimap's unknown pixels (measured 0.0066).
MSE_FRAME_TOL = 0.002
MSE_UNKNOWN_TOL = 0.01
#: Against the true matte the working-resolution alpha may not be worse than the full-size solve
#: (measured: 0.00055 against 0.00105; the guided filter follows the strands' colour edges).
TRUTH_LOSS = 1.0


def _scene(seed: int = 0):
    """(image (H, W, 3) linear, true alpha (H, W), object depth (H, W): the body and the thicker strands)."""
    rng = np.random.default_rng(seed)
    ys, xs = (np.mgrid[0:H * SS, 0:W * SS] + 0.5) / SS - 0.5
    cov = ((xs - 160) ** 2 / 60 ** 2 + (ys - 150) ** 2 / 45 ** 2 <= 1).astype(np.float32)
    for _ in range(60):  # strands from the body outwards: widths 0.3-2.5 px
        a0 = rng.uniform(0, 2 * np.pi)
        x0, y0 = 160 + 55 * np.cos(a0), 150 + 40 * np.sin(a0)
        x1, y1 = x0 + rng.uniform(25, 70) * np.cos(a0 + rng.normal(0, 0.3)), y0 + rng.uniform(25, 70) * np.sin(a0)
        w = rng.uniform(0.3, 2.5)
        t = np.clip(((xs - x0) * (x1 - x0) + (ys - y0) * (y1 - y0)) / ((x1 - x0) ** 2 + (y1 - y0) ** 2), 0, 1)
        d = np.hypot(xs - (x0 + t * (x1 - x0)), ys - (y0 + t * (y1 - y0)))
        cov = np.maximum(cov, (d <= w / 2).astype(np.float32))
    alpha = cov.reshape(H, SS, W, SS).mean(axis=(1, 3))
    yy, xx = np.mgrid[0:H, 0:W] / np.array([H, W])[:, None, None]
    bg = np.stack([0.3 + 0.2 * np.sin(7 * xx + 3 * yy), 0.25 + 0.2 * np.cos(5 * yy),
                   0.35 + 0.15 * np.sin(9 * xx * yy)], -1)
    bg += rng.normal(0, 0.01, bg.shape)
    fg = np.stack([0.55 + 0.1 * yy, 0.35 + 0.05 * xx, 0.12 + 0 * xx], -1)
    img = np.clip(alpha[..., None] * fg + (1 - alpha[..., None]) * bg, 0, 1).astype(np.float32)
    depth = np.where(alpha >= 0.5, 0.8, 0.0).astype(np.float32)
    return img, alpha, depth


def _solve(img, tri, background, known):
    return solve_matte(img, tri, "estimate")


@pytest.fixture(scope="module")
def case():
    img, alpha, depth = _scene()
    tri = depth_trimap(depth)
    return img, alpha, tri, solve_matte(img, tri, "estimate")


def test_working_resolution_matte_against_the_full_size_solve(case):
    img, truth, tri, full = case
    a, f, m = matte_at_scale(img, tri, _solve, 0.5)
    assert m.alpha.shape[1] < W * 0.6  # solved small
    band = tri == UNKNOWN
    assert np.mean((a - full.alpha) ** 2) <= MSE_FRAME_TOL
    assert np.mean((a - full.alpha)[band] ** 2) <= MSE_UNKNOWN_TOL
    assert np.mean((a - truth) ** 2) <= TRUTH_LOSS * np.mean((full.alpha - truth) ** 2)
    assert np.all(a[tri == FG] == 1) and np.all(a[tri == BG] == 0)
    opaque = a >= 1
    np.testing.assert_array_equal(f[opaque], img[opaque])  # an opaque pixel's colour is its own


def test_scale_one_is_the_solve_itself(case):
    img, _, tri, full = case
    a, f, _ = matte_at_scale(img, tri, _solve, 1.0)
    np.testing.assert_array_equal(a, full.alpha)
    np.testing.assert_array_equal(f, full.foreground)


def test_guided_upsampling_is_exact_for_a_linear_function_of_the_guide():
    rng = np.random.default_rng(1)
    guide = rng.random((96, 128, 3)).astype(np.float32)
    import cv2

    lo = cv2.resize(guide, (32, 24), interpolation=cv2.INTER_AREA)
    A, c = np.array([0.5, -0.25, 0.8]), 0.1
    got = guided_upsample(lo, (lo @ A + c)[..., None], guide, r=2, eps=1e-12)[..., 0]
    np.testing.assert_allclose(got, guide @ A + c, atol=1e-4)


@pytest.mark.parametrize("kind", ["random", "flat", "edges"])
def test_the_compiled_3x3_solves_are_lapacks(kind):
    """capture.guided_kernel.solve_spd3 against np.linalg.solve (guided_coefficients(fast=False)),
    within SOLVE_RTOL of the largest coefficient: noise, a flat guide (the epsilon alone keeps the
    covariance invertible) and hard colour edges."""
    from capture.guided_kernel import SOLVE_RTOL, solve_spd3

    rng = np.random.default_rng(7)
    guide = rng.random((60, 80, 3))
    if kind == "flat":
        guide = np.full((60, 80, 3), 0.3) + 1e-4 * guide
    elif kind == "edges":
        guide = np.where((np.arange(80) // 9 % 2)[None, :, None] == 1, [0.9, 0.1, 0.4], [0.05, 0.6, 0.2]) \
            * (1 + 0.01 * guide)
    target = rng.random((60, 80, 4))
    for eps in (1e-4, 1e-7):
        a, b = matting_scale.guided_coefficients(guide, target, eps=eps)
        a_ref, b_ref = matting_scale.guided_coefficients(guide, target, eps=eps, fast=False)
        scale = np.abs(a_ref).max()
        assert np.abs(a - a_ref).max() <= SOLVE_RTOL * scale
        assert np.abs(b - b_ref).max() <= SOLVE_RTOL * max(scale, np.abs(b_ref).max())
    cov = rng.random((5, 6, 3, 3))
    cov = cov @ cov.transpose(0, 1, 3, 2) + 0.1 * np.eye(3)
    rhs = rng.normal(size=(5, 6, 2, 3))
    ref = np.linalg.solve(cov[:, :, None], rhs[..., None])[..., 0]
    np.testing.assert_allclose(solve_spd3(cov, rhs), ref, rtol=0, atol=SOLVE_RTOL * np.abs(ref).max())


def test_guided_upsampling_at_some_pixels_is_the_same():
    rng = np.random.default_rng(2)
    guide = rng.random((48, 64, 3)).astype(np.float32)
    lo, target = guide[::2, ::2], rng.random((24, 32, 2)).astype(np.float32)
    where = rng.random((48, 64)) < 0.3
    np.testing.assert_allclose(guided_upsample_at(lo, target, guide, where),
                               guided_upsample(lo, target, guide)[where], atol=1e-5)


def test_downscaled_trimap_is_sure_only_where_the_whole_footprint_is():
    tri = np.full((8, 8), BG)
    tri[2:6, 2:6] = UNKNOWN
    tri[3:5, 3:5] = FG
    lo = downscale_trimap(tri, 4, 4)
    assert lo[0, 0] == BG and lo[1, 1] == UNKNOWN and lo[3, 3] == BG
    assert not np.any(lo == FG)  # no 2x2 footprint is wholly opaque
    tri[2:6, 2:6] = FG
    assert downscale_trimap(tri, 4, 4)[1, 1] == FG


def test_working_scale_rule():
    tri = np.zeros((1440, 1920))
    assert working_scale(tri) == 1.0  # nothing to matte
    tri[200:1200, 500:1300] = UNKNOWN  # a 1000-pixel object
    assert working_scale(tri, object_px=640) == pytest.approx(0.64)
    assert working_scale(tri, depth_width=256, object_px=200) == pytest.approx(2 * 256 / 1920)  # the depth binds
    assert working_scale(tri, depth_width=256, object_px=400) == pytest.approx(0.4)  # the object binds
    assert working_scale(tri, object_px=0) == 1.0  # the reference
    assert working_scale(tri, object_px=int(1000 * FULL_SIZE_ABOVE) + 1) == 1.0


def test_working_scale_solid_rule():
    """An object whose trimap is mostly opaque (a band share at most SOLID_BAND_SHARE) keeps only
    SOLID_WORK_PX; one that is nearly all band (needles) keeps OBJECT_WORK_PX; the depth still binds."""
    tri = np.zeros((960, 1280))
    tri[100:900, 200:1000] = UNKNOWN  # an 800-pixel object, all band
    assert band_share(tri) == 1.0
    assert working_scale(tri) == pytest.approx(OBJECT_WORK_PX / 800)
    tri[150:850, 250:950] = FG  # an opaque core: band share 1 - 700^2 / 800^2 = 0.23
    assert band_share(tri) == pytest.approx(1 - 700 ** 2 / 800 ** 2)
    assert band_share(tri) <= SOLID_BAND_SHARE
    assert working_scale(tri) == pytest.approx(SOLID_WORK_PX / 800)
    assert working_scale(tri, depth_width=512) == pytest.approx(2 * 512 / 1280)  # the depth binds
    assert working_scale(tri, solid_px=0) == pytest.approx(OBJECT_WORK_PX / 800)  # the rule off
    assert working_scale(tri, object_px=0) == 1.0  # the reference
    tri[150:850, 250:950] = UNKNOWN
    tri[400:600, 500:700] = FG  # a small core: band share 1 - 200^2 / 800^2, above the bar
    assert band_share(tri) > SOLID_BAND_SHARE
    assert working_scale(tri) == pytest.approx(OBJECT_WORK_PX / 800)


def test_matte_scan_at_the_working_resolution(case, monkeypatch):
    """--matte-resolution working: matte_scan's estimate goes through matte_at_scale at the rule's scale
    (forced to 0.5 here: the 320x240 scene is below the rule's full-size bound) and says so."""
    img, _, tri, full = case
    _, _, depth = _scene()
    scan = Scan(img, depth, _camera(), "v0")
    assert matte_scan(scan, depth, MatteConfig(mode="estimate", resolution="working")).scale == 1.0  # the rule: small
    monkeypatch.setattr(matting_scale, "working_scale", lambda trimap, depth_width=None: 0.5)
    m = matte_scan(scan, depth, MatteConfig(mode="estimate", resolution="working"))
    a, f, _ = matte_at_scale(img, tri, _solve, 0.5)
    assert m.scale == 0.5 and m.method == "estimate"
    np.testing.assert_array_equal(m.alpha, a)
    np.testing.assert_array_equal(m.foreground, f)
    ref = matte_scan(scan, depth, MatteConfig(mode="estimate", resolution="full"))
    assert ref.scale == 1.0
    np.testing.assert_array_equal(ref.alpha, full.alpha)


def test_matte_config_takes_the_depth_width_from_the_scan_set():
    from volume.surroundings import matte_given

    cfg = MatteConfig(resolution="working")

    class W:  # what matte_given reads of a Work
        metadata = {"depth_size": [256, 192]}

    assert matte_given(cfg, W()).depth_width == 256
    assert matte_given(MatteConfig(resolution="full"), W()).depth_width is None  # full size: nothing to tie
    W.metadata = {}
    assert matte_given(cfg, W()).depth_width is None
    with pytest.raises(ValueError, match="matte resolution"):
        MatteConfig(resolution="half")


def _camera():
    from capture.camera import Camera

    K = np.array([[300.0, 0, (W - 1) / 2], [0, 300.0, (H - 1) / 2], [0, 0, 1]])
    return Camera(K, np.eye(4), W, H)


# ---------------------------------------------------------------- the known-background (plate) matte
#: Known-background matte at scale 0.5 against its full-size solve (needles 0.25-1.4 px over a
#: textured room, the photo 8-bit, the background known but for the left fifth): alpha MSE over
#: the frame at most issue 32's bar (measured 0.00051); against the true matte at most this many
#: times the full-size solve's (measured 0.00056 against 0.00037: 1.5x; without the per-pixel
#: refinement 0.0023, 6x).
KNOWN_MSE_FRAME_TOL = 0.002
KNOWN_TRUTH_LOSS = 2.0
#: Where the background is known and F is not clipped, alpha F = C - (1 - alpha) B (float32 rounding).
PREMUL_EXACT_TOL = 1e-5


@pytest.fixture(scope="module")
def known_case():
    from capture.matting import solve_known
    from capture.scan import srgb_to_linear, to_uint8_srgb
    from tests import plate_scenes as ps

    C, B, A, F, D = ps.needle_composite(192, 256, 160, seed=0, ss=4)
    C = srgb_to_linear(to_uint8_srgb(C) / np.float32(255.0))
    known = np.ones(A.shape, bool)
    known[:, : A.shape[1] // 5] = False
    tri = depth_trimap(D)
    return C, B, A, D, known, tri, solve_known(C, tri, B, known, 0.004, "plate", D > 0)


def _working_known(case, monkeypatch, scale=0.5):
    from capture.matting import solve_known

    C, B, A, D, known, tri, _ = case
    monkeypatch.setattr(matting_scale, "working_scale", lambda trimap, depth_width=None: scale)
    return solve_known(C, tri, B, known, 0.004, "plate", D > 0, MatteConfig(resolution="working"))


def test_the_working_resolution_is_the_default():
    assert MatteConfig().resolution == "working"


def test_known_background_matte_at_the_working_resolution(known_case, monkeypatch):
    C, B, A, D, known, tri, full = known_case
    m = _working_known(known_case, monkeypatch)
    assert m.scale == 0.5 and m.method == "plate"
    assert np.mean((m.alpha - full.alpha) ** 2) <= KNOWN_MSE_FRAME_TOL
    assert np.mean((m.alpha - A) ** 2) <= KNOWN_TRUTH_LOSS * np.mean((full.alpha - A) ** 2)
    # the colour is made at full size where B is known: the premultiplied colour is the photo's
    a, F = m.alpha[..., None], m.foreground
    exact = known & (m.alpha > 0) & (F.min(-1) > 0) & (F.max(-1) < 1)
    assert exact.sum() > 1000
    assert np.abs(a * F - (C - (1 - a) * B))[exact].max() <= PREMUL_EXACT_TOL
    assert np.all(m.alpha[(tri == BG) & ~known] == 0)  # widened only where B is known


def test_known_background_matte_full_size_is_the_reference(known_case, monkeypatch):
    """--matte-resolution working at scale 1 (the rule on a small image) is the full-size solve bit for bit."""
    full = known_case[-1]
    m = _working_known(known_case, monkeypatch, 1.0)
    assert m.scale == 1.0
    np.testing.assert_array_equal(m.alpha, full.alpha)
    np.testing.assert_array_equal(m.foreground, full.foreground)


def test_matte_scan_takes_the_plate_path_at_the_working_resolution(known_case, monkeypatch):
    from capture.plate import Plate

    C, B, A, D, known, tri, _ = known_case
    plate = Plate(B, known, 0.004, "fixed", 1.0, 0.0, 0.0)
    h, w = D.shape
    from capture.camera import Camera

    cam = Camera(np.array([[300.0, 0, (w - 1) / 2], [0, 300.0, (h - 1) / 2], [0, 0, 1]]), np.eye(4), w, h)
    scan = Scan(np.asarray(C, np.float32), D, cam, "v0")
    assert matte_scan(scan, D, MatteConfig(resolution="working"), plate).scale == 1.0  # the rule: small
    want = _working_known(known_case, monkeypatch)
    m = matte_scan(scan, D, MatteConfig(resolution="working"), plate)
    assert m.method == "plate" and m.scale == 0.5
    np.testing.assert_array_equal(m.alpha, want.alpha)


# ------------------------------------------- the working path's candidates are the full-size path's
#: Scene: tests/plate_scenes.needle_composite 192x256 (160 needles, every needle its own shade, shade
#: 0.7) before a bright room (0.45 + 0.5 x room_image, as the conifer's courtyard), the photo 8-bit,
#: the plate known everywhere; with a blown-out window (linear 1.6, the plate says 1) left of column
#: 100 or without; seeds 0 and 1; scale 0.5 against the full-size solve.  Measured before the working
#: path shared step 2 of capture.matting_known (issue 30 third round's rules at full size only):
#: alpha MSE against the truth 1.63x the full-size solve's without the window, 1.40x with it;
#: against the full-size solve 0.00010 / 0.00037 (seeds 0-1 mean).  With the shared rules: 1.18x /
#: 1.19x, 0.000045 / 0.00019.
CAND_TRUTH_RATIO = 1.3
CAND_FULL_TOL = 0.00025
#: With the rules switched off in capture.matting_known (PALETTE_MARGIN 0, sources wherever the depth
#: is opaque, no alpha floor before the blown-out plate) the working path follows them: its alpha MSE
#: against the truth with the window, the rules on, at most this fraction of it with them off
#: (measured 0.00151 / 0.00394, 0.38x, seeds 0-1 mean; before the sharing 0.00178 / 0.00394, 0.45x:
#: the working solve followed them already, its full-resolution refinement did not, which the test
#: above tells).
CAND_BEAT_OFF = 0.6
CAND_SEEDS = (0, 1)


def _bright_room_scene(seed: int, window: bool):
    from capture.scan import srgb_to_linear, to_uint8_srgb
    from tests import plate_scenes as ps

    room = 0.45 + 0.5 * ps.room_image(256, 192, seed)
    if window:
        room[:, :100] = 1.6
    C, B, A, F, D = ps.needle_composite(192, 256, 160, background=room, seed=seed, ss=4, shade=0.7)
    C = srgb_to_linear(to_uint8_srgb(np.clip(C, 0.0, 1.0)) / np.float32(255.0))
    return C, np.clip(B, 0.0, 1.0), A, D, depth_trimap(D)


def _plate_mattes(seed: int, window: bool, monkeypatch, full: bool = True):
    """(true alpha, full-size alpha or None, alpha at scale 0.5) of the bright-room scene."""
    from capture.matting import solve_known

    C, B, A, D, tri = _bright_room_scene(seed, window)
    known = np.ones(A.shape, bool)
    ref = solve_known(C, tri, B, known, 0.004, "plate", D > 0).alpha if full else None
    with monkeypatch.context() as m:
        m.setattr(matting_scale, "working_scale", lambda trimap, depth_width=None: 0.5)
        work = solve_known(C, tri, B, known, 0.004, "plate", D > 0, MatteConfig(resolution="working"))
    assert work.scale == 0.5
    return A, ref, work.alpha


@pytest.mark.parametrize("window", [False, True])
def test_the_working_path_keeps_the_full_size_candidates(monkeypatch, window):
    """The candidate rules only: the prior where the photo is blown out (capture.matting_blind) is
    off in both paths; with it on, the full-size solve gains more than the working one (seeds 0-1,
    window: full 0.00095, working 0.00137, 1.44x; tests/capture/test_matting_blind.py)."""
    from capture import matting_blind

    monkeypatch.setattr(matting_blind, "BLIND_PRIOR", False)
    truth, full, gap = [], [], []
    for seed in CAND_SEEDS:
        A, ref, work = _plate_mattes(seed, window, monkeypatch)
        truth.append(np.mean((work - A) ** 2))
        full.append(np.mean((ref - A) ** 2))
        gap.append(np.mean((work - ref) ** 2))
    assert np.mean(truth) <= CAND_TRUTH_RATIO * np.mean(full), (truth, full)
    assert np.mean(gap) <= CAND_FULL_TOL, gap


def test_the_working_path_follows_the_candidate_rules(monkeypatch):
    """The candidate rules only (the prior where the photo is blown out off: with it on, rules on
    0.00137, off 0.00203, 0.67x: the prior makes up part of what the rules gave)."""
    from capture import matting_blind
    from capture import matting_known as mk

    monkeypatch.setattr(matting_blind, "BLIND_PRIOR", False)
    def err():
        return np.mean([np.mean((w - A) ** 2) for A, _, w in
                        (_plate_mattes(s, True, monkeypatch, full=False) for s in CAND_SEEDS)])

    on = err()
    monkeypatch.setattr(mk, "PALETTE_MARGIN", 0.0)
    monkeypatch.setattr(mk, "SOURCES_KNOWN_ONLY", False)
    monkeypatch.setattr(mk, "BLOWN_BOUND", False)
    from capture import matting_channels

    monkeypatch.setattr(matting_channels, "COLOUR_BOUND", False)  # the bound against a blown plate with F (stop 62)
    off = err()
    assert on <= CAND_BEAT_OFF * off, (on, off)

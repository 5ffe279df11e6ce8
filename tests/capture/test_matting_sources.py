"""The sure colour sources' coverage (capture.matting_sources; a fixed SOURCE_COVERAGE, 1 by default: docs/matting.md,
stop 63; measured per view by the slope of the photo on the plate behind them: stop 81).

A mat of needles that covers 0.9 of its pixels, which the depth calls opaque, before a bright textured room, with
partial pixels of the same colour around it.  Taken as opaque, the sources' colour carries 0.1 B, and the partial
pixels' alpha comes out high; unmixed at their true coverage, the bias goes.  Off, the module gives the image back.
"""

from __future__ import annotations

import numpy as np
import pytest

from capture import matting_sources as ms
from capture.matting_known import BG, FG, UNKNOWN, known_background_matte
from tests import plate_scenes as ps

#: The mat's true coverage and the needles' colour (linear).
MAT_ALPHA = 0.9
NEEDLE = np.array([0.05, 0.12, 0.03])
#: With the sources unmixed at the mat's coverage the partial pixels' mean alpha error must shrink to this fraction
#: of the error with opaque sources (measured: +0.064 / +0.049 with opaque sources, -0.0001 / -0.0009 unmixed).
BIAS_FRACTION = 0.5


def _mat_scene(seed: int = 0):
    """(C, B, true alpha, trimap) of the mat and its partial fringe (module docstring)."""
    rng = np.random.default_rng(seed)
    h, w = 48, 64
    B = ps.room_image(w, h, seed).astype(np.float64)
    a = np.zeros((h, w))
    a[16:32, 20:44] = MAT_ALPHA
    fringe = np.zeros((h, w), bool)
    fringe[10:38, 14:50] = True
    fringe[16:32, 20:44] = False
    a[fringe] = rng.uniform(0.2, 0.8, fringe.sum())
    C = a[..., None] * NEEDLE + (1 - a[..., None]) * B
    tri = np.full((h, w), BG)
    tri[8:40, 12:52] = UNKNOWN
    tri[16:32, 20:44] = FG
    return C.astype(np.float32), B.astype(np.float32), a, tri, fringe


def test_off_gives_the_image_back():
    C, B, _, _, _ = _mat_scene()
    assert not ms.ESTIMATE_COVERAGE and ms.view_slope(C, B, np.ones(C.shape[:2], bool), 0.975) is None
    assert ms.source_colours(C, B, np.zeros(C.shape[:2]), np.ones(C.shape[:2], bool), np.ones(C.shape[:2], bool),
                             1.0) is C
    lower = np.zeros(C.shape[:2])
    assert ms.SOURCE_COVERAGE == 1.0
    assert ms.source_colours(C, B, lower, np.ones(C.shape[:2], bool), np.ones(C.shape[:2], bool)) is C
    assert np.array_equal(ms.source_coverage(lower, np.ones(C.shape[:2], bool)), np.ones(C.shape[:2]))


def test_a_source_unmixed_at_its_coverage_is_its_own_colour(monkeypatch):
    monkeypatch.setattr(ms, "SOURCE_COVERAGE", MAT_ALPHA)
    C, B, a, _, _ = _mat_scene()
    mat = a == MAT_ALPHA
    lower = np.zeros(C.shape[:2])
    F = ms.source_colours(C, B, lower, mat, np.ones(mat.shape, bool))
    assert np.abs(F[mat] - NEEDLE).max() < 1e-5
    assert np.array_equal(F[~mat], C[~mat])  # not a source: as it is
    # a bound above the coverage wins: the colour stays in [0, 1]
    high = np.full(C.shape[:2], 0.97)
    F2 = ms.source_colours(C, B, high, mat, np.ones(mat.shape, bool))
    assert F2.min() >= 0.0 and F2.max() <= 1.0
    assert np.allclose(F2[mat], B[mat] + (C[mat] - B[mat]) / 0.97, atol=1e-6)


@pytest.mark.parametrize("seed", [0, 1])
def test_sources_unmixed_at_the_mats_coverage_take_the_alpha_bias_away(monkeypatch, seed):
    C, B, a, tri, fringe = _mat_scene(seed)
    known = np.ones(a.shape, bool)
    bias = {}
    monkeypatch.setattr(ms, "ESTIMATE_COVERAGE", False)  # the fixed coverage alone
    for k in (1.0, MAT_ALPHA):
        monkeypatch.setattr(ms, "SOURCE_COVERAGE", k)
        alpha, _, _, ok = known_background_matte(C, tri, B, known)
        assert ok
        bias[k] = float(np.mean(alpha[fringe] - a[fringe]))
    assert bias[1.0] > 0.02, bias  # opaque sources: the fringe's alpha high
    assert abs(bias[MAT_ALPHA]) <= BIAS_FRACTION * bias[1.0], bias


#: A mat the depth calls opaque that covers this much of its pixels (a low-resolution conifer's: 0.79 measured).
THIN_ALPHA = 0.75
#: The measured transparency must be within this of the truth (the needles' colour varies, uncorrelated with B).
SLOPE_TOL = 0.03


def _thin_scene(seed: int = 0, coverage: float = THIN_ALPHA, plain: bool = False):
    """:func:`_mat_scene` with the mat at ``coverage``, cut into branches 2 px tall (not a solid body), and each needle
    pixel's colour drawn about NEEDLE (the needles' own texture, which does not follow the room behind them);
    ``plain``: a background of one colour."""
    C, B, a, tri, fringe = _mat_scene(seed)
    rng = np.random.default_rng(seed + 10)
    if plain:
        B = np.broadcast_to(np.asarray([0.5, 0.45, 0.4], np.float32), B.shape).copy()
    mat = tri == FG
    mat[np.arange(mat.shape[0]) % 4 >= 2] = False  # branches 2 px tall with gaps of room between them
    tri = np.where((tri == FG) & ~mat, UNKNOWN, tri)
    a = np.where(mat, coverage, np.where(tri == UNKNOWN, a, 0.0))
    a[(tri == UNKNOWN) & (a == MAT_ALPHA)] = 0.3
    F = np.clip(NEEDLE * rng.uniform(0.6, 1.4, a.shape + (1,)), 0, 1)
    C = (a[..., None] * F + (1 - a[..., None]) * B).astype(np.float32)
    return C, B.astype(np.float32), a, tri, fringe & (a > 0), mat


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_slope_of_the_photo_on_the_plate_is_the_sources_transparency(monkeypatch, seed):
    monkeypatch.setattr(ms, "ESTIMATE_COVERAGE", True)  # off by default (docs/matting.md)
    C, B, _, _, _, mat = _thin_scene(seed)
    slope = ms.view_slope(C, B, mat, 0.975)
    assert slope is not None and abs(slope - (1 - THIN_ALPHA)) <= SLOPE_TOL, slope


def test_opaque_a_solid_body_a_plain_background_or_too_few_sources_give_no_slope(monkeypatch):
    monkeypatch.setattr(ms, "ESTIMATE_COVERAGE", True)
    C, B, _, _, _, mat = _thin_scene(0, coverage=1.0)
    assert abs(ms.view_slope(C, B, mat, 0.975)) < 0.02  # opaque: the photo does not follow the plate
    C, B, _, _, _, mat = _thin_scene(0, plain=True)
    assert ms.view_slope(C, B, mat, 0.975) is None  # nothing to regress on
    C, B, a, tri, _, mat = _thin_scene(0)
    few = np.zeros_like(mat)
    ys, xs = np.nonzero(mat)
    few[ys[:ms.SLOPE_SOURCES - 1], xs[:ms.SLOPE_SOURCES - 1]] = True
    assert ms.view_slope(C, B, few, 0.975) is None
    assert ms.view_slope(C, B, mat, 0.2) is None  # every source clipped at that level
    body = tri != BG  # the whole block: a solid body (a fur ball's disc)
    assert ms.solid(body) and not ms.solid(mat)
    assert ms.view_slope(C, B, body, 0.975) is None
    monkeypatch.setattr(ms, "ESTIMATE_COVERAGE", False)
    assert ms.view_slope(C, B, mat, 0.975) is None


def test_the_captures_coverage_is_half_the_median_transparency():
    assert ms.capture_coverage([0.2, None, 0.3, 0.1, None]) == (pytest.approx(1 - ms.SLOPE_SHARE * 0.2), 0.2)
    assert ms.capture_coverage([0.2, 0.3, None]) == (None, None)  # fewer than SLOPE_VIEWS views with a slope
    assert ms.capture_coverage([0.05, 0.08, 0.2]) == (None, 0.08)  # the median under TRANSPARENCY_MIN: opaque
    cov, med = ms.capture_coverage([0.9, 0.8, 0.95])
    assert med == 0.9 and cov == pytest.approx(1 - ms.SLOPE_SHARE * ms.TRANSPARENCY_MAX)


@pytest.mark.parametrize("seed", [0, 1])
def test_the_measured_coverage_takes_the_fringes_alpha_bias_away(seed):
    C, B, a, tri, fringe, _ = _thin_scene(seed)
    known = np.ones(a.shape, bool)
    bias = {}
    for cov in (None, THIN_ALPHA):
        alpha, _, _, ok = known_background_matte(C, tri, B, known, coverage=cov)
        assert ok
        bias[cov] = float(np.mean(alpha[fringe] - a[fringe]))
    assert bias[None] > 0.05, bias  # the mat taken as opaque: the fringe's alpha high
    assert abs(bias[THIN_ALPHA]) <= BIAS_FRACTION * bias[None], bias

"""The sure colour sources' coverage (capture.matting_sources; off by default: SOURCE_COVERAGE 1, docs/matting.md,
stop 63).

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
    for k in (1.0, MAT_ALPHA):
        monkeypatch.setattr(ms, "SOURCE_COVERAGE", k)
        alpha, _, _, ok = known_background_matte(C, tri, B, known)
        assert ok
        bias[k] = float(np.mean(alpha[fringe] - a[fringe]))
    assert bias[1.0] > 0.02, bias  # opaque sources: the fringe's alpha high
    assert abs(bias[MAT_ALPHA]) <= BIAS_FRACTION * bias[1.0], bias

"""The known-background matte's Laplacian guide at one brightness (capture.matting_guide; docs/matting.md, stop 63).

The same needles before the same room, exposed 4x darker (photo and plate alike), should get the same matte.  The data
term's alpha is a ratio of colour differences and does not change; the Laplacian's epsilon is an absolute variance, so
with the crop as it is the darker copy's matte is smoother.  The darker copy's guide brightened to the level (the
brighter one, 0.40 on average, stays as it is), its matte comes closer to the truth and to the brighter copy's.
"""

from __future__ import annotations

import numpy as np
import pytest

from capture import matting_guide as mg
from capture.matting import depth_trimap
from capture.matting_known import known_background_matte
from tests import plate_scenes as ps

#: How much darker the second exposure is.
DARKER = 4.0
#: With the guide at one brightness the darker copy's alpha MSE against the truth must be at most this fraction of its
#: MSE with the crop as it is (measured 0.81 / 0.80 on seeds 0 / 1, 0.85 on seed 2).  The two exposures' mattes come
#: closer too (mean |difference| over the band 0.59 / 0.67 x), but not the same: the data term's confidence
#: (SEPARATION, RESIDUAL) and the bound's noise are absolute colour differences as well.
DARK_BETTER = 0.9


def test_off_is_the_crop_itself(monkeypatch):
    img = np.random.default_rng(0).uniform(0, 1, (8, 9, 3))
    monkeypatch.setattr(mg, "LAPLACIAN_LEVEL", None)
    assert mg.laplacian_guide(img) is img


def test_a_view_is_brightened_only_where_its_data_is_weak(monkeypatch):
    """capture.matting_guide.view_guide: the brightened guide where the blind prior's record says at least WEAK_GATE
    of the band is weak before a background of the object's colour; the crop itself below it, or without a count."""
    monkeypatch.setattr(mg, "LAPLACIAN_LEVEL", 0.3)
    dark = np.random.default_rng(3).uniform(0, 0.1, (8, 9, 3))
    band = 1000
    gated = {"weak": int(mg.WEAK_GATE * band), "band": band}
    assert mg.view_guide(dark, gated).mean() == pytest.approx(0.3)
    assert gated["guided"] is True  # the record says so (the matte record counts these views)
    for rec in ({"weak": int(mg.WEAK_GATE * band) - 1, "band": band}, {"weak": 0, "band": 0}, {}):
        assert mg.view_guide(dark, rec) is dark and rec["guided"] is False
    bright = np.random.default_rng(4).uniform(0.4, 0.9, (8, 9, 3))  # gated, but brighter than the level
    rec = {"weak": band, "band": band}
    assert mg.view_guide(bright, rec) is bright and rec["guided"] is False


def test_the_guide_has_the_level_as_its_mean(monkeypatch):
    monkeypatch.setattr(mg, "LAPLACIAN_LEVEL", 0.3)
    img = np.random.default_rng(1).uniform(0, 0.1, (8, 9, 3))
    g = mg.laplacian_guide(img)
    assert g.mean() == pytest.approx(0.3)
    assert np.allclose(g / img, g.flat[0] / img.flat[0])  # one factor
    assert np.isfinite(mg.laplacian_guide(np.zeros((4, 4, 3)))).all()  # a black crop
    bright = np.random.default_rng(2).uniform(0.2, 0.9, (8, 9, 3))
    assert mg.laplacian_guide(bright) is bright  # brighter than the level: as it is


@pytest.mark.parametrize("seed", [0, 1])
def test_a_darker_exposure_gets_a_closer_matte(monkeypatch, seed):
    C, B, A, _, D = ps.needle_composite(seed=seed)
    tri = depth_trimap(D)
    known = np.ones(A.shape, bool)
    band = tri == 0.5
    diff, dark = {}, {}
    monkeypatch.setattr(mg, "WEAK_GATE", 0.0)  # the guide itself, in every view (the gate: the test above)
    for level in (None, 0.3):
        monkeypatch.setattr(mg, "LAPLACIAN_LEVEL", level)
        a1 = known_background_matte(C, tri, B, known, noise=0.0)[0]
        rec = {}
        a2 = known_background_matte(C / DARKER, tri, B / DARKER, known, noise=0.0, record=rec)[0]
        assert rec["blind_prior"]["guided"] is (level is not None)  # the record says which guide was used
        diff[level] = float(np.abs(a1 - a2)[band].mean())
        dark[level] = float(np.mean((a2 - A)[band] ** 2))
    assert dark[0.3] <= DARK_BETTER * dark[None], dark
    assert diff[0.3] < diff[None], diff

"""Eq. 1 on a sample of L_max (volume.lopt_sample) against the full fusion of every level (the
reference path, FuseConfig(sample_eq1=False)): the same L_opt and the same fused levels on
scenes where L_opt is 8, 64 and 256; the skipped level is not fused, and the sample's interval
holds the exact fraction."""

from __future__ import annotations

import numpy as np
import pytest

from tests.scenes import furball_scene, make_scanset, sphere_scene
from tests.scenes import ring_cameras as scan_ring
from volume.build import fuse_levels
from volume.lopt_sample import wilson
from volume.pipeline.config import FuseConfig, PipelineConfig, PyramidConfig
from volume.pyramid import LoptConfig, choose_l_opt

CASES = [
    pytest.param(furball_scene, 64, 8, id="fur-lopt8"),
    pytest.param(sphere_scene, 64, 64, id="sphere-lopt64"),
    pytest.param(sphere_scene, 256, 256, id="sphere-lopt256", marks=pytest.mark.slow),
]


@pytest.mark.parametrize("scene_fn, top, expect", CASES)
def test_sampled_eq1_matches_full_fusion(scene_fn, top, expect):
    ss = make_scanset(scene_fn(), scan_ring(16, 96, 72), noise=0.001, holes=0.03, outliers=0.002)
    ref_cfg = FuseConfig(lopt=LoptConfig(max_res=top), sample_eq1=False)
    _, _, ref, ref_frac, none = fuse_levels(ss, ref_cfg, needed_res=top // 2)
    assert not none
    cfg = FuseConfig(lopt=LoptConfig(max_res=top))
    _, _, got, frac, sampled = fuse_levels(ss, cfg, needed_res=top // 2)
    t = cfg.lopt.t
    assert choose_l_opt(ref_frac, t) == expect == choose_l_opt(frac, t)
    s = sampled[top]
    assert s.decided and s.samples > 0
    assert s.low <= ref_frac[top] <= s.high, (s, ref_frac[top])
    if expect < top:
        assert top not in got  # the finest level was never fused
        assert frac[top] == s.fraction
    else:
        assert frac[top] == ref_frac[top]  # fused in full: exact
    for L, f in got.items():
        np.testing.assert_array_equal(f.measured, ref[L].measured)
        assert frac[L] == ref_frac[L]
        if f.values is not None and ref[L].values is not None:
            np.testing.assert_array_equal(f.values, ref[L].values)


def test_wilson_interval():
    lo, hi = wilson(0, 100, 5.0)
    assert lo == 0.0 and 0.1 < hi < 0.3
    lo, hi = wilson(50, 100, 5.0)
    assert lo < 0.5 < hi and abs((lo + hi) / 2 - 0.5) < 1e-12
    assert wilson(0, 0, 5.0) == (0.0, 1.0)


def test_model_keeps_values_up_to_values_max_res():
    """Levels finer than PyramidConfig.values_max_res keep their surface voxels, not their distances."""
    from volume.pipeline import build_model

    ss = make_scanset(sphere_scene(), scan_ring(8, 64, 48), noise=0.0005)
    model, summary = build_model(ss, PipelineConfig(fuse=FuseConfig(lopt=LoptConfig(max_res=32, t=1.0)),
                                                    pyramid=PyramidConfig(values_max_res=16)))
    assert summary["l_opt"] == 32
    assert [lv.values is not None for lv in model.pyramid.levels] == [True, True, False]
    assert len(model.pyramid.level(32).surface) > 100

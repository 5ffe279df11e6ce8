"""Eq. 1 on a sample of L_max (volume.lopt_sample) against the full fusion of every level (the
reference path, ModelConfig(sample_eq1=False)): the same L_opt and the same fused levels on
scenes where L_opt is 8, 64 and 256; the skipped level is not fused, and the sample's interval
holds the exact fraction."""

from __future__ import annotations

import numpy as np
import pytest

from tests.scenes import furball_scene, make_scanset, sphere_scene
from tests.scenes import ring_cameras as scan_ring
from volume.build import ModelConfig, fuse_levels
from volume.pyramid import LoptConfig, choose_l_opt

CASES = [
    pytest.param(furball_scene, 64, 8, id="fur-lopt8"),
    pytest.param(sphere_scene, 64, 64, id="sphere-lopt64"),
    pytest.param(sphere_scene, 256, 256, id="sphere-lopt256", marks=pytest.mark.slow),
]


@pytest.mark.parametrize("scene_fn, top, expect", CASES)
def test_sampled_eq1_matches_full_fusion(scene_fn, top, expect):
    ss = make_scanset(scene_fn(), scan_ring(16, 96, 72), noise=0.001, holes=0.03, outliers=0.002)
    ref_cfg = ModelConfig(lopt=LoptConfig(max_res=top), sample_eq1=False)
    _, _, ref, ref_frac, none = fuse_levels(ss, ref_cfg, needed_res=top // 2)
    assert not none
    cfg = ModelConfig(lopt=LoptConfig(max_res=top))
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

"""Median-cut lights (render/shading/median_cut.py) stand for the whole map."""

from __future__ import annotations

import numpy as np
import pytest

from render.shading.envmap import bundled_envmap
from render.shading.lights import env_minus_lights
from render.shading.median_cut import median_cut_lights
from render.shading.sh import irradiance_brute

#: Irradiance from 32 cut lights against the brute-force integral of the map (max over 600 normals,
#: fraction of the largest irradiance): measured 2.3 / 2.0 / 4.0 / 8.1 % on studio / forest / sunset /
#: courtyard without their 3 dominant lights.
IRRADIANCE_TOL_OF_PEAK = 0.10


@pytest.mark.parametrize("name", ["studio", "forest", "sunset", "courtyard"])
def test_cut_lights_keep_the_power_and_the_irradiance(name):
    rest = env_minus_lights(bundled_envmap(name).resized(128), 3)
    cut = median_cut_lights(rest, 5)
    assert len(cut.dirs) == 32
    np.testing.assert_allclose(np.linalg.norm(cut.dirs, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(cut.power.sum(0), rest.total_power(), rtol=1e-9)
    np.testing.assert_allclose(cut.solid_angle.sum(), 4 * np.pi, rtol=1e-9)
    # the first cut halves the luminance energy (up to the one column/row it falls in)
    half = median_cut_lights(rest, 1).power @ np.array([0.2126, 0.7152, 0.0722])
    assert abs(half[0] - half[1]) < 0.1 * half.sum()
    n = np.random.default_rng(0).normal(size=(600, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    ref = irradiance_brute(rest, n)
    got = np.maximum(n @ cut.dirs.T, 0) @ cut.power
    assert np.abs(got - ref).max() < IRRADIANCE_TOL_OF_PEAK * ref.max()
    np.testing.assert_allclose(got.mean(0), ref.mean(0), rtol=0.01)  # exact on average over normals


def test_more_lights_converge():
    rest = env_minus_lights(bundled_envmap("forest").resized(64), 3)
    n = np.random.default_rng(1).normal(size=(300, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    ref = irradiance_brute(rest, n)
    errs = []
    for depth in (2, 4, 6):
        c = median_cut_lights(rest, depth)
        errs.append(np.abs(np.maximum(n @ c.dirs.T, 0) @ c.power - ref).max())
    assert errs[0] > errs[1] > errs[2]

"""The harder fur ball of issue 22: curly strands and melanin patches (``furrow synth furball --curly``)."""

from __future__ import annotations

import argparse

import numpy as np
import pytest

from datasets_synthetic.fur_variants import CURLY, DARK_PATCH, LIGHT_PATCH, melanin_patches
from datasets_synthetic.scenes import build_scene


def test_patches_blend_dark_and_light_coat_and_are_seeded():
    rng = np.random.default_rng(0)
    roots = rng.normal(size=(4000, 3))
    axes = np.array([0.075, 0.062, 0.052])
    roots = roots / np.linalg.norm(roots, axis=1, keepdims=True) * axes
    base = np.full((4000, 3), [0.5, 0.21, 0.065])
    out = melanin_patches(0, roots, axes, base, 14)
    assert np.array_equal(out, melanin_patches(0, roots, axes, base, 14))
    assert np.array_equal(melanin_patches(0, roots, axes, base, 0), base)
    lum = out.mean(axis=1)
    assert (lum < 1.3 * np.mean(DARK_PATCH)).mean() > 0.05  # dark patches
    assert (lum > 0.8 * np.mean(LIGHT_PATCH)).mean() > 0.05  # light patches
    assert (np.abs(out - base).max(axis=1) < 1e-12).mean() > 0.2  # the base coat between them


def test_curly_furball_differs_from_the_default_and_the_flags_reach_the_scene():
    from furrow.cmd_synth import add_arguments, build_config

    p = argparse.ArgumentParser()
    add_arguments(p)
    cfg = build_config(p.parse_args(["furball", "-o", "x", "--curly", "--patches", "6"]))
    assert cfg.scene_params == {**CURLY, "patches": 6}
    with pytest.raises(ValueError, match="furball only"):
        build_config(p.parse_args(["plant", "-o", "x", "--curly"]))
    a = build_scene("furball", strands=300)
    b = build_scene("furball", strands=300, **CURLY)
    assert b.params["curl"] == CURLY["curl"] and b.params["patches"] == CURLY["patches"]
    assert not np.allclose(a.mesh.vertices[-100:], b.mesh.vertices[-100:])


def test_uniform_coat_is_one_colour_on_a_sphere_and_the_flag_reaches_the_scene():
    from datasets_synthetic.fur_variants import UNIFORM, UNIFORM_COAT, UNIFORM_JITTER, uniform_coat
    from furrow.cmd_synth import add_arguments, build_config

    p = argparse.ArgumentParser()
    add_arguments(p)
    assert build_config(p.parse_args(["furball", "-o", "x", "--coat", "uniform"])).scene_params == UNIFORM
    with pytest.raises(ValueError, match="furball only"):
        build_config(p.parse_args(["plant", "-o", "x", "--coat", "uniform"]))
    c = uniform_coat(0, 5000)
    ratio = c / np.asarray(UNIFORM_COAT)
    assert np.allclose(ratio, ratio[:, :1]) and UNIFORM_JITTER[0] <= ratio.min() < ratio.max() <= UNIFORM_JITTER[1]
    s = build_scene("furball", strands=300, **UNIFORM)
    t = build_scene("furball", strands=300)
    assert s.params["coat"] == "uniform" and len(set(s.params["body_axes"])) == 1
    # the strands' colours are one hue (no stripes, no belly) where the tabby coat has several
    hue = lambda m: m.colors[-3000:, 0] / np.maximum(m.colors[-3000:, 2], 1e-9)
    assert np.ptp(hue(s.mesh)) < 1e-3 < np.ptp(hue(t.mesh))
    with pytest.raises(ValueError, match="coat"):
        build_scene("furball", strands=10, coat="zebra")

"""Glare streaks (docs/methods.md §4, Eq. 6-12): shape rules and energy conservation through GL."""

from __future__ import annotations

import numpy as np

from render.shading.glare import (
    GlareConfig,
    bright_pixels,
    eyelash_factor,
    n_g,
    streak_energy,
    streak_shape,
    streak_triangles,
)


def test_shape_rules():
    k_l, k_s = 0.5, 2.0
    I = np.array([3.0, 30.0, 300.0])
    ng = n_g(I, k_l, k_s)
    for i, g in zip(I, ng):
        n = np.array([max(g, 0) * 0.5, g + 1e-6, g * 2 + 10])
        L, W = streak_shape(np.full(3, i), n, k_l, k_s)
        S = k_s * i
        np.testing.assert_allclose(L * W / 2, S, rtol=1e-12)  # Eq. 6, 8, 11: area independent of n
        if g > 0:
            np.testing.assert_allclose(L[0], np.sqrt(S), rtol=1e-12)  # Eq. 9-10 below n_g
        np.testing.assert_allclose(L[1:], k_l * i * (n[1:] + 2) / (8 * np.pi), rtol=1e-6)  # Eq. 7 above
    # Eq. 12 is where Eq. 7 meets sqrt(S)
    np.testing.assert_allclose(k_l * I * (ng + 2) / (8 * np.pi), np.sqrt(k_s * I), rtol=1e-12)


def test_eyelash_table_peaks_20_degrees_from_horizontal():
    a = np.arange(0, 180, 0.5)
    f = eyelash_factor(a)
    assert set(np.round(a[f >= f.max() - 1e-12])) <= {20.0, 160.0}
    assert f.min() >= 0.4 - 1e-12


def test_streak_light_equals_excess_analytically():
    rng = np.random.default_rng(0)
    c = rng.uniform(20, 300, (50, 2))
    e = rng.uniform(0, 20, (50, 3))
    pos, col = streak_triangles(c, e, rng.uniform(2, 100, 50), 50.0, GlareConfig())
    np.testing.assert_allclose(streak_energy(pos, col), e.sum(0), rtol=1e-6)  # float32 vertices


def test_bright_pixels_excess():
    img = np.full((20, 30, 3), 0.2, np.float32)
    img[5, 7] = [4.0, 2.0, 1.0]
    c, e, i = bright_pixels(img, 1.0)
    np.testing.assert_allclose(c, [[7.5, 5.5]])
    lum = 0.2126 * 4 + 0.7152 * 2 + 0.0722
    np.testing.assert_allclose(i, [lum])
    np.testing.assert_allclose(e[0], np.array([4.0, 2.0, 1.0]) * (1 - 1 / lum), rtol=1e-6)

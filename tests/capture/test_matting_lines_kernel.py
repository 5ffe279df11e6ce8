"""group_fit's compiled Gauss-Newton pass (capture.matting_lines_kernel) against numpy's
(capture.matting_lines._gn_totals), on samples grouped in cubes as capture.matting_cells.fit_cells groups them.

Tolerance: the same numbers.  The kernel follows numpy's operations and sums the groups in sample order,
as np.bincount does (its module docstring); measured here: bit for bit, totals, colours and sigma^2.
"""

from __future__ import annotations

import numpy as np
import pytest

import capture.matting_lines as ml
from capture.matting_lines_kernel import gn_pass


def _samples(rng, n=20000, groups=300):
    """Partial pixels of ``groups`` cubes: each cube one colour, seen before random backgrounds."""
    Ft = rng.uniform(0.05, 0.6, (groups, 3))
    g = np.sort(rng.integers(0, groups, n))
    rng.shuffle(g)
    B = rng.uniform(0.0, 1.0, (n, 3))
    a = rng.uniform(0.05, 0.95, n)
    C = a[:, None] * Ft[g] + (1 - a[:, None]) * B + rng.normal(0, 0.01, (n, 3))
    w = np.where(rng.random(n) < 0.2, 0.0, rng.uniform(0.2, 1.0, n))
    return C, B, w, a, g, groups


def _gsum(g, K):
    def gsum(x):
        return np.stack([np.bincount(g, x[:, j], minlength=K) for j in range(x.shape[1])], 1)

    gsum.groups = K
    return gsum


def test_one_pass_gives_numpys_totals():
    rng = np.random.default_rng(4)
    C, B, w, _, g, K = _samples(rng)
    F = rng.uniform(0, 1, (K, 3))
    T, imp = np.zeros((K, 11)), np.empty(len(w))
    gn_pass(C, B, w, F, g.astype(np.int64), K, T, imp)
    want_T, want_imp = ml._gn_totals(C, B, w, F, _gsum(g, K), g)
    np.testing.assert_array_equal(imp, want_imp)
    np.testing.assert_array_equal(T, want_T)


@pytest.mark.parametrize("seed", [0, 1])
def test_group_fit_compiled_is_numpys(monkeypatch, seed):
    rng = np.random.default_rng(seed)
    C, B, w, a, g, K = _samples(rng)
    out = {}
    for fast in (False, True):
        monkeypatch.setattr(ml, "GN_COMPILED", fast)
        terms: dict = {}
        out[fast] = ml.group_fit(C, B, w, a, _gsum(g, K), g, terms), terms
    (F0, s0), t0 = out[False]
    (F1, s1), t1 = out[True]
    assert np.isfinite(s0).mean() > 0.5  # most cubes fitted: the case exercises the passes
    np.testing.assert_array_equal(F1, F0)
    np.testing.assert_array_equal(s1, s0)
    for k in ("M", "n", "s", "spread"):
        np.testing.assert_array_equal(t1[k], t0[k])

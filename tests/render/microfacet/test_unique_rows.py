"""render.microfacet.lod.unique_rows against its reference, ``np.unique(axis=0)``: the same rows in the same order."""

from __future__ import annotations

import numpy as np
import pytest

from render.microfacet.lod import unique_rows


@pytest.mark.parametrize("n, span, offset", [(1, 3, 0), (50, 2, 0), (20_000, 64, 0), (20_000, 300, -7), (5, 1, 9)])
def test_unique_rows_equals_numpys_row_unique(n, span, offset):
    ijk = np.random.default_rng(n + span).integers(0, span, (n, 3)) + offset
    ref = np.unique(ijk, axis=0)
    got = unique_rows(ijk)
    assert got.dtype == np.int64 and np.array_equal(got, ref)


def test_unique_rows_falls_back_where_the_key_would_overflow():
    ijk = np.array([[0, 0, 0], [2**40, 2**40, 5], [0, 0, 0], [3, 2**40, 1]], np.int64)
    assert np.array_equal(unique_rows(ijk), np.unique(ijk, axis=0))


def test_unique_rows_of_nothing():
    assert unique_rows(np.zeros((0, 3), np.int64)).shape == (0, 3)

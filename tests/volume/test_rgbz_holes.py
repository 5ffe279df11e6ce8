"""The flood-fill hole count (volume.rgbz.HOLES_FLOOD) against scipy's binary_fill_holes (the reference)."""

import numpy as np
import pytest

from volume.rgbz import _enclosed, hole_fraction


def _random_depth(seed: int, shape=(97, 131)) -> np.ndarray:
    rng = np.random.default_rng(seed)
    d = rng.uniform(0.2, 2.0, shape).astype(np.float32)
    d[rng.random(shape) < rng.uniform(0.05, 0.6)] = 0.0  # speckle holes, some joined to the border
    yy, xx = np.mgrid[: shape[0], : shape[1]]
    d[(yy - shape[0] / 2) ** 2 + (xx - shape[1] / 3) ** 2 < 150] = 0.0  # one large enclosed or open hole
    d[:, : rng.integers(0, 9)] = 0.0  # an empty strip at the border
    return d


@pytest.mark.parametrize("seed", range(12))
def test_flood_fill_counts_the_same_holes_as_scipy(seed):
    d = _random_depth(seed)
    assert hole_fraction(d, fast=True) == hole_fraction(d, fast=False)


def test_a_ring_encloses_its_centre_but_a_diagonal_gap_does_not_leak():
    d = np.zeros((40, 40), np.float32)
    d[5:35, 5:35] = 1.0
    d[15:25, 15:25] = 0.0  # 100 enclosed empty pixels
    assert hole_fraction(d, fast=True) == pytest.approx(100 / 900)
    for k in range(4, 15):  # a diagonal chain of empty pixels from the hole to the outside: not a path
        d[k, k] = 0.0  # in 4-connectivity, so the hole stays enclosed
    assert _enclosed(d <= 0)[20, 20]
    assert hole_fraction(d, fast=True) == hole_fraction(d, fast=False)
    d[5:15, 20] = 0.0  # a straight channel to the outside: the hole is open
    assert hole_fraction(d, fast=True) == hole_fraction(d, fast=False)
    assert _enclosed(d <= 0)[20, 20] == np.False_


def test_nan_and_empty_inputs():
    d = np.ones((10, 10), np.float32)
    d[4:6, 4:6] = np.nan  # not > 0 and not <= 0: inside the silhouette, not a hole
    assert hole_fraction(d, fast=True) == hole_fraction(d, fast=False) == 0.0
    assert hole_fraction(np.zeros((8, 8), np.float32), fast=True) == 0.0

"""The push-pull fill (capture.fill): the strided 2 x 2 sums give numpy's reshaped sums bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from capture.fill import _down, push_pull, push_pull_reference


@pytest.mark.parametrize("shape", [(37, 51, 3), (64, 64, 1), (9, 7, 2), (130, 97, 4), (33, 200, 3), (256, 192, 6)])
def test_push_pull_equals_the_reference_bit_for_bit(shape):
    rng = np.random.default_rng(sum(shape))
    h, w, c = shape
    v = (rng.normal(size=shape) * rng.uniform(0, 1e3, (h, w, 1))).astype(np.float32)
    for share in (0.02, 0.5, 0.97):
        wt = (rng.uniform(size=(h, w)) < share) * rng.uniform(size=(h, w))
        assert np.array_equal(push_pull(v, wt), push_pull_reference(v, wt))


def test_the_down_step_is_numpys_sum():
    rng = np.random.default_rng(5)
    for c in (None, 1, 2, 3, 5):
        x = rng.normal(size=(2 * 41, 2 * 23) + (() if c is None else (c,))) * 1e4
        ref = x.reshape(41, 2, 23, 2, *x.shape[2:]).sum((1, 3))
        assert np.array_equal(_down(x), ref)
        assert not np.array_equal(_down(x), x[0::2, 0::2] + x[1::2, 1::2] + x[1::2, 0::2] + x[0::2, 1::2]) or c == 1


@pytest.mark.parametrize("shape", [(37, 51, 3), (64, 64, 1), (9, 7, 2), (130, 97, 4), (33, 200, 3), (1, 9, 3),
                                   (2, 2, 1), (255, 193, 3)])
def test_compiled_levels_equal_the_numpy_levels_bit_for_bit(shape, monkeypatch):
    import capture.fill as fill

    rng = np.random.default_rng(sum(shape) + 1)
    h, w, c = shape
    v = (rng.normal(size=shape) * rng.uniform(0, 1e3, (h, w, 1))).astype(np.float32)
    v[rng.uniform(size=(h, w)) < 0.1] *= -1.0
    cases = [(rng.uniform(size=(h, w)) < s) * rng.uniform(0, 3, (h, w)) for s in (0.0, 0.001, 0.02, 0.5, 0.97, 1.0)]
    cases.append((rng.uniform(size=(h, w)) < 0.3).astype(np.float64))
    one = np.zeros((h, w))
    one[h // 2, w // 2] = 1e-300  # a single tiny weight
    cases.append(one)
    for wt in cases:
        monkeypatch.setattr(fill, "COMPILED", True)
        got = push_pull(v, wt)
        monkeypatch.setattr(fill, "COMPILED", False)
        ref = push_pull_reference(v, wt)
        assert got.dtype == ref.dtype and got.shape == ref.shape
        assert np.array_equal(got.view(np.int64), ref.view(np.int64))  # the bits, signed zeros included


def test_compiled_levels_keep_nan_where_the_numpy_levels_do(monkeypatch):
    import capture.fill as fill

    rng = np.random.default_rng(3)
    v = rng.normal(size=(40, 30, 3))
    wt = (rng.uniform(size=(40, 30)) < 0.3) * 1.0
    v[5, 5] = np.nan  # a NaN colour under weight 0 spreads through the sums, as in numpy
    v[7, 9, 1] = np.nan
    wt[7, 9] = 1.0
    monkeypatch.setattr(fill, "COMPILED", True)
    got = push_pull(v, wt)
    monkeypatch.setattr(fill, "COMPILED", False)
    ref = push_pull_reference(v, wt)
    assert np.isnan(ref).any()
    assert np.array_equal(got, ref, equal_nan=True)


def test_the_compiled_levels_are_used_and_differ_from_a_wrong_order(monkeypatch):
    """The bit-for-bit test can fail: a down step that adds the four taps in another order differs."""
    import capture.fill as fill

    rng = np.random.default_rng(11)
    v = rng.normal(size=(64, 48, 3)) * 1e6
    wt = (rng.uniform(size=(64, 48)) < 0.2) * rng.uniform(size=(64, 48))
    monkeypatch.setattr(fill, "COMPILED", False)
    wrong = fill._push_pull(v, wt, lambda x: x[0::2, 0::2] + (x[1::2, 1::2] + (x[1::2, 0::2] + x[0::2, 1::2])))
    assert not np.array_equal(wrong, push_pull_reference(v, wt))

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

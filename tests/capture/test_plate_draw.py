"""capture.plate_draw: one view's fixed-camera plate put in its frame, against plate_fixed's (bit for bit)."""

from types import SimpleNamespace

import numpy as np

from capture.matting_known import CLIP_LEVEL
from capture.plate_draw import fixed_view_flat, in_view_bound
from capture.plate_fixed import _fixed_view, in_view


def _inputs(seed, H=37, W=53, n=900):
    """A view's drawn pixels with NaN plates, infinities, lower bounds above and below the clip level
    (and at it), estimated pixels with their sigma, a need mask."""
    rng = np.random.default_rng(seed)
    flat = rng.choice(H * W, n, replace=False)
    y, x = flat // W, flat % W
    med = rng.uniform(0, 1.3 * CLIP_LEVEL, (n, 3)).astype(np.float32)
    med[rng.random(n) < 0.2, rng.integers(0, 3)] = np.nan
    med[rng.random(n) < 0.02] = np.inf
    med[rng.random(n) < 0.02, 1] = -np.inf
    med[:5] = CLIP_LEVEL
    bound = rng.random(n) < 0.4
    est = rng.random(n) < 0.3
    sigma = np.where(est, rng.uniform(0, 0.2, n), np.nan)
    gain = rng.uniform(0.7, 1.3, 3).astype(np.float32)
    need = rng.random((H, W)) < 0.7
    p = SimpleNamespace(view=SimpleNamespace(linear=np.zeros((H, W, 3), np.float16)))
    return p, gain, need, (H, W), y, x, med, est, bound, sigma


def test_flat_view_equals_the_reference():
    """fixed_view_flat's four arrays equal _fixed_view's, dtype and bits (NaN, inf, bounds, sigma)."""
    for seed in range(6):
        a = _inputs(seed)
        for got, want in zip(fixed_view_flat(*a), _fixed_view(*a)):
            assert got.dtype == want.dtype and got.shape == want.shape
            assert np.array_equal(got.view(np.uint8), want.view(np.uint8))


def test_in_view_bound_equals_in_view_and_can_differ():
    """in_view_bound equals in_view bit for bit (also with no bound and every pixel bound); with the
    clip test left out it would differ (the test can fail)."""
    for seed in range(4):
        _, gain, _, _, _, _, med, _, bound, _ = _inputs(seed)
        for b in (bound, np.zeros_like(bound), np.ones_like(bound)):
            got, want = in_view_bound(med, b, gain), in_view(med, b, gain)
            assert np.array_equal(got.view(np.uint32), want.view(np.uint32))
        assert np.isnan(want).sum() > np.isnan(med / gain).sum()

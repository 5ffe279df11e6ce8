"""capture.matting_fast: each twin against the numpy / scipy expression it replaces, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from capture.matting_fast import channel_max, channel_sum, zoom2


@pytest.mark.parametrize("shape", [(517, 613, 3), (40001, 1, 3), (7, 3), (5, 4, 1), (9, 2)])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_channel_max_is_numpy_max(shape, dtype):
    x = np.random.default_rng(0).normal(size=shape).astype(dtype)
    x.flat[3] = np.nan
    assert np.array_equal(channel_max(x), x.max(axis=-1), equal_nan=True)
    assert channel_max(x).dtype == x.max(axis=-1).dtype


@pytest.mark.parametrize("shape", [(517, 613, 3), (40001, 1, 3), (1000, 3), (6, 4)])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_channel_sum_is_numpy_sum(shape, dtype):
    rng = np.random.default_rng(1)
    a, b = rng.normal(size=shape).astype(dtype), rng.normal(size=shape).astype(dtype)
    for x in (a * b, (a - b) ** 2, np.broadcast_to(a[:1], shape) * b):
        got, ref = channel_sum(x), x.sum(-1)
        assert got.dtype == ref.dtype and np.array_equal(got, ref)


@pytest.mark.parametrize("shape", [(57, 43, 3), (1, 9, 3), (8, 1, 4), (1, 1, 3), (200, 151, 1)])
def test_zoom2_is_ndimage_zoom(shape):
    c = np.random.default_rng(2).random(shape)
    ref = ndimage.zoom(c, (2, 2, 1), order=1, mode="nearest", grid_mode=True)
    for h, w in ((2 * shape[0], 2 * shape[1]), (2 * shape[0] - 1, max(1, 2 * shape[1] - 1))):
        assert np.array_equal(zoom2(c, h, w), ref[:h, :w])
    with pytest.raises(ValueError):
        zoom2(c, 2 * shape[0] + 1, 1)


@pytest.mark.parametrize("iterations", [1, 2, 6, 37])
def test_dilate_and_erode_are_ndimage(iterations):
    from capture.matting_fast import dilate, erode

    rng = np.random.default_rng(3)
    blobs = ndimage.gaussian_filter(rng.random((301, 257)), 6) > 0.5
    for m in (blobs, rng.random((64, 80)) > 0.97, np.ones((9, 7), bool), np.zeros((5, 5), bool)):
        m = m.copy()
        m[0, :3] = True  # at the border
        assert np.array_equal(dilate(m, iterations), ndimage.binary_dilation(m, iterations=iterations))
        assert np.array_equal(erode(m, iterations), ndimage.binary_erosion(m, iterations=iterations, border_value=0))
        square = np.ones((3, 3), bool)
        assert np.array_equal(erode(m, iterations, square=True),
                              ndimage.binary_erosion(m, structure=square, iterations=iterations, border_value=0))
        assert dilate(m, iterations).dtype == bool


@pytest.mark.parametrize("room", [4, 0])
def test_ichol_sized_is_pymattings_factor(monkeypatch, room):
    """capture.matting_fast.ichol_sized: the factor of a matting system (the closed-form Laplacian of a seeded
    image plus data weights) equals pymatting's ichol with its own room, bit for bit; with no room (0) the
    factor overflows it and is made again with pymatting's."""
    import scipy.sparse as sp
    from pymatting import cf_laplacian, ichol

    import capture.matting_fast as mf

    rng = np.random.default_rng(3)
    img = rng.random((40, 50, 3))
    A = (cf_laplacian(img, epsilon=1e-5, radius=1) + sp.diags(rng.random(40 * 50) * 0.5 + 1e-3)).tocsr()
    monkeypatch.setattr(mf, "ICHOL_ROOM", room)
    got, ref = mf.ichol_sized(A, 3e-3), ichol(A, discard_threshold=3e-3)
    for key in ("data", "indices", "indptr"):
        assert np.array_equal(getattr(got.L, key), getattr(ref.L, key))
    assert len(got.L.data) > 40 * 50  # room 0 (n entries) cannot hold it: the retry made it
    b = rng.random(40 * 50)
    assert np.array_equal(got(b), ref(b))


def test_pcg_solves_a_matting_system_and_takes_a_zero_right_side_as_solved():
    """capture.matting_fast.pcg: on a seeded matting system it gives the sparse direct solution within the CG
    tolerance (1e-6 relative: 1e-4 in alpha); with b = 0 it returns zeros, converged, without pymatting's
    0 / 0 (that system had run 2000 iterations on NaN and been called not converged)."""
    import warnings

    import scipy.sparse as sp
    from pymatting import cf_laplacian
    from scipy.sparse.linalg import spsolve

    from capture.matting_fast import pcg

    rng = np.random.default_rng(5)
    A = (cf_laplacian(rng.random((30, 40, 3)), epsilon=1e-5, radius=1) + sp.diags(rng.random(1200) + 0.1)).tocsr()
    b = rng.random(1200)
    x, ok = pcg(A, b, None, {}, 3e-3, 1e-6, 2000)
    assert ok and np.abs(x - spsolve(A.tocsc(), b)).max() < 1e-4
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # pymatting's cg warned "invalid value encountered in scalar divide"
        x0, ok0 = pcg(A, np.zeros(1200), None, {}, 3e-3, 1e-6, 2000)
    assert ok0 and not np.any(x0)

"""capture.matting_ichol: pymatting's incomplete Cholesky factor with the columns' rows sorted in place,
against ``pymatting.ichol`` bit for bit (values, row indices, column pointers)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse

import capture.matting_ichol as mi
from capture.matting_known import CF_EPSILON, CF_RADIUS, ICHOL_DISCARD


def _system(seed: int, h: int = 41, w: int = 57):
    """The known-background matte's system on a random textured crop: the matting Laplacian at the
    unknown pixels plus data weights (capture.matting_known._system's form), as CSR."""
    from pymatting import cf_laplacian

    rng = np.random.default_rng(seed)
    img = np.clip(rng.uniform(0, 1, (h, w, 3)) * 0.3 + np.linspace(0, 0.7, w)[None, :, None], 0, 1)
    unk = rng.random((h, w)) < 0.8
    L = cf_laplacian(img, epsilon=CF_EPSILON, radius=CF_RADIUS, is_known=~unk).tocsr()
    u = unk.ravel()
    return (L[u][:, u] + scipy.sparse.diags(rng.uniform(0.0, 0.3, int(u.sum())))).tocsr()


def _factor(A, thr):
    from pymatting import ichol

    return ichol(A.copy(), discard_threshold=thr).Ltuple


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("thr", [ICHOL_DISCARD, 1e-4, 0.05])
def test_the_factor_is_pymatting_s(seed, thr):
    A = _system(seed)
    want = _factor(A, thr)
    got = mi.ichol(A.copy(), discard_threshold=thr).Ltuple
    for g, w in zip(got, want, strict=True):
        assert g.dtype == w.dtype and g.shape == w.shape
        assert np.ascontiguousarray(g).tobytes() == np.ascontiguousarray(w).tobytes()
    x = np.random.default_rng(seed).normal(size=A.shape[0])  # and it preconditions the same
    from pymatting import ichol

    assert mi.ichol(A.copy(), discard_threshold=thr)(x).tobytes() == ichol(A.copy(), discard_threshold=thr)(x).tobytes()


def test_a_matrix_needing_a_shift_and_the_switch(monkeypatch, capsys):
    """An indefinite matrix: both try the same shifts (and say so) and give the same factor; the
    switch off is pymatting."""
    A = _system(5, 20, 20).tolil()
    A[3, 3] = -1.0
    A = A.tocsr()
    want = _factor(A, 1e-4)
    assert capsys.readouterr().out.count("PERFORMANCE WARNING") >= 1
    for on in (True, False):
        monkeypatch.setattr(mi, "ICHOL_IN_PLACE", on)
        got = mi.ichol(A.copy(), discard_threshold=1e-4).Ltuple
        assert capsys.readouterr().out.count("PERFORMANCE WARNING") >= 1
        assert all(g.tobytes() == w.tobytes() for g, w in zip(got, want, strict=True))


def test_the_order_of_a_column_s_rows_matters():
    """The comparison can fail: a factor whose columns keep their rows unsorted differs from pymatting's."""
    A = _system(0).T.tocsc()
    A.sum_duplicates()
    n = A.shape[0]
    Lv, Lr, Lp = np.empty(mi.MAX_NNZ // 1000), np.empty(mi.MAX_NNZ // 1000, np.int64), np.zeros(n + 1, np.int64)
    want = _factor(_system(0), 1e-4)
    import inspect

    code = inspect.getsource(mi._ichol.py_func).split("\n", 1)[1]  # without the decorator
    code = code.replace("c[q] > v", "False")  # no sort: the rows in the order they were met
    ns = {"np": np, "_ichol_start": mi._ichol_start}
    exec("from numba import njit\n@njit\n" + code.replace("def _ichol(", "def twin("), ns)
    nnz = ns["twin"](n, A.data, A.indices.astype(np.int64), A.indptr.astype(np.int64), Lv, Lr, Lp, 1e-4, 0.0,
                     len(Lv), 0.0, True)
    assert nnz > 0
    assert Lr[:nnz].tobytes() != want[1].tobytes()

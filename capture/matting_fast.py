"""Faster twins of numpy expressions in the matting paths (capture/matting.py, capture/matting_known.py,
capture/matting_scale.py; issue 32), each giving the same values bit for bit as the expression it
replaces (tests/capture/test_matting_fast.py holds each against it).

A 1920x1440 phone view spent about a quarter of its matte in numpy reductions over the three
colour channels (``x.max(axis=-1)``, ``(a * b).sum(-1)``: numpy's reduction over a short inner axis
runs an outer loop per pixel) and in ``scipy.ndimage.zoom``'s general spline code for the 2x
bilinear step of the push-pull fill (docs/speed.md, round 4).

* :func:`channel_max`: ``x.max(axis=-1)`` as elementwise maxima of the channels (exact: a maximum
  rounds nothing; NaN propagates as in ``max``).
* :func:`channel_sum`: ``x.sum(-1)`` of three channels as ``(x0 + x1) + x2``, the order numpy's
  reduction takes over a last axis of three (checked against it in the tests).
* :func:`dilate`, :func:`erode`: ``ndimage.binary_dilation`` / ``binary_erosion`` of a 2-D mask
  with the default cross (erode: or the 3 x 3 square), ``iterations`` times, the outside 0
  (``border_value=0``), as OpenCV's morphology with the same kernel and a constant 0 border (a set
  operation: nothing to round).
* :func:`zoom2`: ``scipy.ndimage.zoom(c, (2, 2, 1), order=1, mode="nearest", grid_mode=True)[:h, :w]``
  as one compiled loop: each output pixel sums its four taps in ndimage's order, each tap its value
  times the row weight times the column weight (0.25 / 0.75: the grid-mode coordinate of a 2x zoom).
* :func:`ichol_sized`: pymatting's ``ichol(A, discard_threshold)`` with room for ICHOL_ROOM x ``A.nnz``
  entries instead of pymatting's 250 million (two arrays of 2 GB: a new mapping, faulted in afresh, for
  every view's factor). The factor is the same bit for bit (the room only bounds it); one that needs more
  is made again with pymatting's room.
* :func:`pcg`: pymatting's ``cg`` with that factor, except that a system its start already solves comes back
  as it is (pymatting's divides 0 by 0 there and ran every iteration on NaN).
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: :func:`ichol_sized`'s room for the factor, in multiples of the system's non-zeros.  The matte's systems'
#: factors at capture.matting_known.ICHOL_DISCARD hold about 0.85 x theirs (1.12 M against 1.34 M).
ICHOL_ROOM = 4


def channel_max(x: np.ndarray) -> np.ndarray:
    """``x.max(axis=-1)`` (module docstring)."""
    x = np.asarray(x)
    if x.ndim == 0 or x.shape[-1] < 2:
        return x.max(axis=-1)
    out = np.maximum(x[..., 0], x[..., 1])
    for k in range(2, x.shape[-1]):
        np.maximum(out, x[..., k], out=out)
    return out


def channel_sum(x: np.ndarray) -> np.ndarray:
    """``x.sum(-1)`` of an array of three channels (module docstring); other widths go to numpy."""
    x = np.asarray(x)
    if x.ndim == 0 or x.shape[-1] != 3 or x.dtype.kind != "f":
        return x.sum(-1)
    out = x[..., 0] + x[..., 1]
    out += x[..., 2]
    return out


#: The 3x3 cross (scipy.ndimage.generate_binary_structure(2, 1)) as an OpenCV kernel.
_CROSS = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], np.uint8)


def dilate(mask: np.ndarray, iterations: int = 1) -> np.ndarray:
    """``ndimage.binary_dilation(mask, iterations=iterations)`` of a 2-D mask (module docstring)."""
    import cv2

    m = np.asarray(mask, bool)
    if m.ndim != 2 or iterations < 1 or m.size == 0:
        from scipy import ndimage

        return ndimage.binary_dilation(m, iterations=iterations)
    return cv2.dilate(m.view(np.uint8), _CROSS, iterations=int(iterations), borderType=cv2.BORDER_CONSTANT,
                      borderValue=0).view(bool)


def erode(mask: np.ndarray, iterations: int = 1, square: bool = False) -> np.ndarray:
    """``ndimage.binary_erosion(mask, iterations=iterations, border_value=0)`` of a 2-D mask (module
    docstring); ``square``: with the 3 x 3 square (``structure=np.ones((3, 3), bool)``) instead of the cross."""
    import cv2

    m = np.asarray(mask, bool)
    kernel = np.ones((3, 3), np.uint8) if square else _CROSS
    if m.ndim != 2 or iterations < 1 or m.size == 0:
        from scipy import ndimage

        return ndimage.binary_erosion(m, structure=kernel.astype(bool), iterations=iterations, border_value=0)
    return cv2.erode(np.ascontiguousarray(m).view(np.uint8), kernel, iterations=int(iterations),
                     borderType=cv2.BORDER_CONSTANT, borderValue=0).view(bool)


@njit(cache=True, nogil=True)
def _zoom2(c, h, w):
    n0, n1, nc = c.shape
    out = np.empty((h, w, nc), np.float64)
    for i in range(h):
        y0 = (i - 1) // 2 if i % 2 == 0 else i // 2  # floor(i / 2 - 0.25)
        wy1 = 0.75 if i % 2 == 0 else 0.25
        wy0 = 1.0 - wy1
        a0 = min(max(y0, 0), n0 - 1)
        a1 = min(max(y0 + 1, 0), n0 - 1)
        for j in range(w):
            x0 = (j - 1) // 2 if j % 2 == 0 else j // 2
            wx1 = 0.75 if j % 2 == 0 else 0.25
            wx0 = 1.0 - wx1
            b0 = min(max(x0, 0), n1 - 1)
            b1 = min(max(x0 + 1, 0), n1 - 1)
            for k in range(nc):
                t = 0.0
                t += c[a0, b0, k] * wy0 * wx0
                t += c[a0, b1, k] * wy0 * wx1
                t += c[a1, b0, k] * wy1 * wx0
                t += c[a1, b1, k] * wy1 * wx1
                out[i, j, k] = t
    return out


def zoom2(coarse: np.ndarray, h: int, w: int) -> np.ndarray:
    """(h, w, C) float64: ``ndimage.zoom(coarse, (2, 2, 1), order=1, mode="nearest",
    grid_mode=True)[:h, :w]`` of a (h2, w2, C) ``coarse`` with h <= 2 h2, w <= 2 w2 (module docstring)."""
    c = np.ascontiguousarray(coarse, np.float64)
    if c.ndim != 3 or h > 2 * c.shape[0] or w > 2 * c.shape[1]:
        raise ValueError(f"zoom2 takes (h2, w2, C) to at most (2 h2, 2 w2), got {c.shape} to {(h, w)}")
    return _zoom2(c, int(h), int(w))


def ichol_sized(A, discard_threshold: float):
    """``pymatting.ichol(A, discard_threshold=discard_threshold)`` (module docstring; ``A`` scipy sparse,
    symmetric positive definite)."""
    from pymatting import ichol

    try:
        return ichol(A, discard_threshold=discard_threshold, max_nnz=ICHOL_ROOM * int(A.nnz) + A.shape[0])
    except ValueError as e:  # pymatting: "... more than max_nnz non-zero elements were created ..."
        if "max_nnz" not in str(e):
            raise
    return ichol(A, discard_threshold=discard_threshold)


def pcg(A, b: np.ndarray, x0: np.ndarray | None, pre: dict, discard_threshold: float, rtol: float,
        maxiter: int) -> tuple[np.ndarray | None, bool]:
    """(x, converged) of ``A x = b`` by pymatting's ``cg`` from ``x0`` (None: zeros), preconditioned by
    :func:`ichol_sized` (made once into ``pre['M']``), its prints kept off stdout (``furrow model --json``);
    (None, False) where it does not converge.  Where the start solves the system already (``b = 0`` with no
    ``x0``: an unknown band with no data and no opaque pixel beside it) the start comes back, converged:
    pymatting's ``cg`` tests its residual against ``rtol`` x |b| = 0 there, divides 0 by 0 and runs every
    iteration on NaN (the matte was then called not converged)."""
    import contextlib
    import io

    from pymatting import cg

    x = np.zeros_like(b) if x0 is None else np.asarray(x0)
    if not np.any(b - A @ x):
        return x, True
    try:
        with contextlib.redirect_stdout(io.StringIO()):  # pymatting prints on stdout
            if "M" not in pre:
                pre["M"] = ichol_sized(A, discard_threshold)
            return cg(A, b, x0=x0, M=pre["M"], rtol=rtol, maxiter=maxiter), True
    except ValueError as e:  # "Conjugate gradient descent did not converge ..."
        if "converge" not in str(e):
            raise
        return None, False

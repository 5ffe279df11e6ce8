"""Real spherical harmonics as 3D Gaussian Splatting uses them (Kerbl et al. 2023), and their
least-squares fit to what the views recorded.

The basis, its constants and its signs are those of the reference rasteriser
(graphdeco-inria/diff-gaussian-rasterization, ``computeColorFromSH``): for a unit direction
``(x, y, z)`` **from the camera centre to the Gaussian** (world axes), coefficient k of a channel
multiplies :func:`basis` ``[k]`` and the colour is ``max(0, 0.5 + sum_k basis_k sh_k)`` per channel.
Degree d has (d + 1)^2 coefficients: 1, 4, 9 or 16.  The colour is what the standard viewers
show, i.e. display (sRGB-encoded) values in [0, 1]: see volume/splats.py for furrow's use of it.

:func:`fit` solves, per Gaussian and channel, ridge-regularised least squares

    min_x  sum_v w_v (basis(d_v) . x - (c_v - 0.5))^2 + ridge * |x_1..K-1|^2

over the samples (direction d_v, colour c_v, weight w_v) of the views that see it: the ridge
pulls every coefficient but the constant (DC) one towards 0, so a Gaussian seen by few views, or
from directions that do not pin a coefficient down (a ring of views in one plane leaves the
z-terms free), keeps a view-independent colour.
"""

from __future__ import annotations

import numpy as np

#: Reference constants (diff-gaussian-rasterization auxiliary.h): degree 0, 1, 2, 3.
SH_C0 = 0.28209479177387814
SH_C1 = 0.4886025119029199
SH_C2 = (1.0925484305920792, -1.0925484305920792, 0.31539156525252005, -1.0925484305920792, 0.5462742152960396)
SH_C3 = (-0.5900435899266435, 2.890611442640554, -0.4570457994644658, 0.3731763325901154, -0.4570457994644658,
         1.445305721320277, -0.5900435899266435)
#: Highest degree the reference (and this module) evaluates.
MAX_DEGREE = 3
#: Offset added to the SH sum (the reference's grey anchor).
COLOUR_OFFSET = 0.5


def n_coeffs(degree: int) -> int:
    """Coefficients per channel of SH degree ``degree`` ((degree + 1)^2)."""
    if not 0 <= int(degree) <= MAX_DEGREE:
        raise ValueError(f"SH degree must be 0..{MAX_DEGREE}, got {degree}")
    return (int(degree) + 1) ** 2


def degree_of(k: int) -> int:
    """SH degree with ``k`` coefficients per channel (1, 4, 9, 16); ValueError otherwise."""
    for d in range(MAX_DEGREE + 1):
        if n_coeffs(d) == k:
            return d
    raise ValueError(f"{k} coefficients per channel is no SH degree (1, 4, 9 or 16)")


def basis(dirs: np.ndarray, degree: int) -> np.ndarray:
    """(..., K) float64 basis values of unit directions ``dirs`` (..., 3), K = n_coeffs(degree),
    in the reference's order and signs."""
    d = np.asarray(dirs, np.float64)
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    out = [np.full(x.shape, SH_C0)]
    if degree > 0:
        out += [-SH_C1 * y, SH_C1 * z, -SH_C1 * x]
    if degree > 1:
        xx, yy, zz, xy, yz, xz = x * x, y * y, z * z, x * y, y * z, x * z
        out += [SH_C2[0] * xy, SH_C2[1] * yz, SH_C2[2] * (2 * zz - xx - yy), SH_C2[3] * xz, SH_C2[4] * (xx - yy)]
    if degree > 2:
        out += [SH_C3[0] * y * (3 * xx - yy), SH_C3[1] * xy * z, SH_C3[2] * y * (4 * zz - xx - yy),
                SH_C3[3] * z * (2 * zz - 3 * xx - 3 * yy), SH_C3[4] * x * (4 * zz - xx - yy),
                SH_C3[5] * z * (xx - yy), SH_C3[6] * x * (xx - 3 * yy)]
    n_coeffs(degree)
    return np.stack(out, -1)


def colour(sh: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """(N, 3) colour max(0, 0.5 + SH) of Gaussians with coefficients ``sh`` (N, K, 3) seen along
    unit directions ``dirs`` (N, 3) (camera centre -> Gaussian)."""
    sh = np.asarray(sh, np.float64)
    b = basis(dirs, degree_of(sh.shape[1]))
    return np.maximum(COLOUR_OFFSET + np.einsum("nk,nkc->nc", b, sh), 0.0)


def dc_from_colour(c: np.ndarray) -> np.ndarray:
    """The DC coefficient giving the view-independent colour ``c`` ((c - 0.5) / SH_C0)."""
    return (np.asarray(c, np.float64) - COLOUR_OFFSET) / SH_C0


class NormalEquations:
    """The per-Gaussian normal equations of :func:`fit`, accumulated view by view.

    Args:
        n: Gaussians.
        degree: SH degree fitted.
    """

    def __init__(self, n: int, degree: int):
        self.degree = int(degree)
        k = n_coeffs(degree)
        self.ata = np.zeros((n, k, k), np.float64)
        self.atb = np.zeros((n, k, 3), np.float64)
        self.weight = np.zeros(n, np.float64)

    def add(self, idx: np.ndarray, dirs: np.ndarray, colours: np.ndarray, weights: np.ndarray) -> None:
        """Add samples: Gaussian ``idx`` (M,) seen along ``dirs`` (M, 3) with colour ``colours``
        (M, 3) and weight ``weights`` (M,); a Gaussian appears at most once per call."""
        if not len(idx):
            return
        b = basis(dirs, self.degree)
        w = np.asarray(weights, np.float64)
        self.ata[idx] += w[:, None, None] * b[:, :, None] * b[:, None, :]
        self.atb[idx] += (w[:, None] * b)[:, :, None] * (np.asarray(colours, np.float64) - COLOUR_OFFSET)[:, None, :]
        self.weight[idx] += w

    def solve(self, ridge: float, fallback: np.ndarray) -> np.ndarray:
        """(N, K, 3) coefficients: the ridge solution where a Gaussian has samples, else the DC
        colour ``fallback`` (N, 3)."""
        n, k = self.ata.shape[:2]
        reg = np.eye(k) * float(ridge)
        reg[0, 0] = 0.0
        seen = self.weight > 0
        out = np.zeros((n, k, 3), np.float64)
        if seen.any():
            a = self.ata[seen] + reg
            a[:, 0, 0] += 1e-12  # a weight > 0 makes it positive; guard against underflow only
            out[seen] = np.linalg.solve(a, self.atb[seen])
        out[~seen, 0, :] = dc_from_colour(np.asarray(fallback)[~seen])
        return out


def fit(idx_dirs_colours_weights, n: int, degree: int, ridge: float, fallback: np.ndarray) -> np.ndarray:
    """Ridge least-squares SH coefficients (N, K, 3) from an iterable of sample batches
    (idx, dirs, colours, weights) (:class:`NormalEquations`); Gaussians without samples get the
    view-independent ``fallback`` colour (N, 3)."""
    eq = NormalEquations(n, degree)
    for batch in idx_dirs_colours_weights:
        eq.add(*batch)
    return eq.solve(ridge, fallback)

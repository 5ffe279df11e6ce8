"""The object's colour from a window of pixels before a textured known background (issue 30, third round).

With the background B known, each partial pixel C_i = a_i F + (1 - a_i) B_i lies on the line from
B_i through the object's colour F.  Where F is about constant over a small window and B varies
across it (a needle before a textured room), the window's lines meet at F: triangulation matting
(Smith and Blinn 1996) within a window instead of across plates.  :func:`window_foreground` finds per
pixel the point nearest to its window's lines in the least-squares sense (each line weighted by
|C_i - B_i|^2, a 3 x 3 system per pixel from box sums) and says how well the lines pin it down:

* **Conditioning.**  The lines must cross at a finite angle: the smallest eigenvalue of the normal
  matrix over its trace (``WINDOW_MIN_CONDITION``).  Over a plain backdrop every line passes
  through the one B and the point found is B itself: then the window's B must vary
  (``WINDOW_MIN_SPREAD``, the weighted spread of B), else no colour.
* **Beyond the pixels.**  F lies at or beyond every line's photo colour seen from its B (a_i <= 1):
  a point between the B's and the photos (the degenerate meeting near the background) is refused
  (``WINDOW_MIN_REACH``: the root weighted mean square of 1 / a_i, the distance from B to F over
  that to C, at least about 1).
* **A colour.**  F in [0, 1] within ``WINDOW_RANGE_SLACK``.

Where all hold, the colour is a candidate of capture.matting_known's per-pixel fit (step 2) beside
the nearest sure colours and the palette; elsewhere it is NaN and the candidates are as before.
:func:`window_foreground_reference` is the slow twin (an explicit loop over the windows).
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

#: Window radius (pixels; 2 = 5 x 5).
WINDOW_RADIUS = 2
#: Least smallest-eigenvalue / trace of the window's normal matrix (the lines' crossing).
WINDOW_MIN_CONDITION = 0.02
#: Least weighted standard deviation of B over the window (linear, summed over channels).
WINDOW_MIN_SPREAD = 0.02
#: Least root weighted mean square of |F - B_i| / |C_i - B_i| (1 / a_i): F beyond the photos.  Below
#: 1 by a margin: a window of opaque pixels (C = F, the ratio exactly 1) passes whatever the rounding.
WINDOW_MIN_REACH = 0.9
#: F may leave [0, 1] by this much per channel before the fit is refused (then clipped).
WINDOW_RANGE_SLACK = 0.05
#: Least |C - B| (linear, Euclidean) for a pixel's line to count (below: noise, no direction).
WINDOW_MIN_DIFF = 0.02


def _box(x: np.ndarray, r: int) -> np.ndarray:
    """Sum over the (2r + 1)^2 window of each pixel of (h, w, ...) ``x`` (zero outside)."""
    n = (2 * r + 1) ** 2
    size = (2 * r + 1, 2 * r + 1) + (1,) * (x.ndim - 2)
    return ndimage.uniform_filter(x, size=size, mode="constant") * n


def _weights(C: np.ndarray, B: np.ndarray, known: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(D = C - B (h, w, 3), weight (h, w)): |D|^2 where B is known and |D| >= WINDOW_MIN_DIFF."""
    D = C - B
    d2 = (D * D).sum(-1)
    return D, np.where(known & (d2 >= WINDOW_MIN_DIFF ** 2), d2, 0.0)


def _normal(D: np.ndarray, B: np.ndarray, w: np.ndarray, r: int, sel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(A (n, 3, 3), b (n, 3)) of sum_i M_i X = sum_i M_i B_i, M_i = w_i (I - u_i u_i^T), over the
    window of each of the n ``sel`` pixels."""
    u = D / np.sqrt(np.maximum((D * D).sum(-1), 1e-12))[..., None]
    wu = w[..., None] * u
    S_w = _box(w, r)[sel]
    S_uu = _box(wu[..., :, None] * u[..., None, :], r)[sel]
    S_B = _box(w[..., None] * B, r)[sel]
    S_uuB = _box(wu * (u * B).sum(-1, keepdims=True), r)[sel]
    A = S_w[..., None, None] * np.eye(3) - S_uu
    return A, S_B - S_uuB


def _checks(F, A, B, w, r, sel) -> np.ndarray:
    """(n,) bool: the fits ``F`` (n, 3) of the windows at the ``sel`` pixels with their normal
    matrices ``A`` (n, 3, 3) pass the module docstring's checks."""
    tr = np.trace(A, axis1=-2, axis2=-1)
    lam = np.linalg.eigvalsh(A)[..., 0]
    ok = (tr > 0) & (lam >= WINDOW_MIN_CONDITION * np.maximum(tr, 1e-12))
    on = (w > 0).astype(np.float64)
    n = _box(on, r)[sel]
    S_w = np.maximum(_box(w, r)[sel], 1e-12)
    S_B = _box(on[..., None] * B, r)[sel]
    S_BB = _box(on * (B * B).sum(-1), r)[sel]
    S_wB = _box(w[..., None] * B, r)[sel]
    var = (_box(w[..., None] * B * B, r)[sel] / S_w[:, None] - (S_wB / S_w[:, None]) ** 2).sum(-1)
    ok &= np.sqrt(np.maximum(var, 0.0)) >= WINDOW_MIN_SPREAD
    ok &= np.all((F >= -WINDOW_RANGE_SLACK) & (F <= 1 + WINDOW_RANGE_SLACK), axis=-1)
    # reach: sum_i |F - B_i|^2 = sum_i w_i (|F - B_i| / |C_i - B_i|)^2 against sum_i w_i (w_i = |C_i - B_i|^2)
    reach = n * (F * F).sum(-1) - 2 * (F * S_B).sum(-1) + S_BB
    return ok & (reach >= WINDOW_MIN_REACH ** 2 * S_w)


def window_foreground(image: np.ndarray, background: np.ndarray, known: np.ndarray,
                      radius: int = WINDOW_RADIUS, where: np.ndarray | None = None) -> np.ndarray:
    """(h, w, 3) the object colour each pixel's window of linear ``image`` points to over its known
    ``background`` (module docstring), clipped to [0, 1]; NaN where the window's fit fails a check,
    B is not known at the pixel or (h, w) ``where`` is False."""
    C = np.asarray(image, np.float64)
    B = np.asarray(background, np.float64)
    known = np.asarray(known, bool)
    sel = known if where is None else known & np.asarray(where, bool)
    out = np.full(C.shape, np.nan)
    D, w = _weights(C, B, known)
    if not sel.any() or not w.any():
        return out
    A, b = _normal(D, B, w, radius, sel)
    good = np.linalg.det(A) > 1e-12
    F = np.zeros(b.shape)
    F[good] = np.linalg.solve(A[good], b[good][..., None])[..., 0]
    ok = good & _checks(F, A, B, w, radius, sel)
    vals = np.full(b.shape, np.nan)
    vals[ok] = np.clip(F[ok], 0.0, 1.0)
    out[sel] = vals
    return out


def window_foreground_reference(image: np.ndarray, background: np.ndarray, known: np.ndarray,
                                radius: int = WINDOW_RADIUS) -> np.ndarray:
    """The slow twin of :func:`window_foreground`: each window's normal equations summed pixel by
    pixel in a loop, the same checks.  Small images only."""
    C = np.asarray(image, np.float64)
    B = np.asarray(background, np.float64)
    D, w = _weights(C, B, np.asarray(known, bool))
    h, wd = w.shape
    out = np.full(C.shape, np.nan)
    for y in range(h):
        for x in range(wd):
            if not known[y, x]:
                continue
            A, b, S_B, S_wB, S_wBB = np.zeros((3, 3)), np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3)
            n, S_w, S_BB = 0, 0.0, 0.0
            for yy in range(max(y - radius, 0), min(y + radius + 1, h)):
                for xx in range(max(x - radius, 0), min(x + radius + 1, wd)):
                    wi = w[yy, xx]
                    if wi <= 0:
                        continue
                    u = D[yy, xx] / np.linalg.norm(D[yy, xx])
                    M = wi * (np.eye(3) - np.outer(u, u))
                    A += M
                    b += M @ B[yy, xx]
                    n, S_w, S_B, S_BB = n + 1, S_w + wi, S_B + B[yy, xx], S_BB + B[yy, xx] @ B[yy, xx]
                    S_wB, S_wBB = S_wB + wi * B[yy, xx], S_wBB + wi * B[yy, xx] ** 2
            if S_w <= 0 or np.linalg.det(A) <= 1e-12:
                continue
            F = np.linalg.solve(A, b)
            ok = np.linalg.eigvalsh(A)[0] >= WINDOW_MIN_CONDITION * np.trace(A)
            ok &= np.sqrt(max((S_wBB / S_w - (S_wB / S_w) ** 2).sum(), 0.0)) >= WINDOW_MIN_SPREAD
            ok &= bool(np.all((F >= -WINDOW_RANGE_SLACK) & (F <= 1 + WINDOW_RANGE_SLACK)))
            ok &= n * F @ F - 2 * F @ S_B + S_BB >= WINDOW_MIN_REACH ** 2 * S_w
            if ok:
                out[y, x] = np.clip(F, 0.0, 1.0)
    return out


def window_candidates(image: np.ndarray, background: np.ndarray, known: np.ndarray, radius: int,
                      where: np.ndarray) -> list[np.ndarray]:
    """[:func:`window_foreground` at the ``where`` pixels] as a candidate of capture.matting_known's step 2
    (NaN: never chosen), or [] where no window fits."""
    Fw = window_foreground(image, background, known, radius, where)
    return [Fw] if np.isfinite(Fw[..., 0]).any() else []

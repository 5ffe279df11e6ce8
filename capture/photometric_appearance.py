"""Appearance is not exposure (capture.photometric, step 4): the part of the views' solved log gains that
is view-dependent appearance -- sheen and hair lobes of the lights, a patterned coat seen along or across
its stripes -- told from per-view exposure and left in the colours.

* :func:`colour_appearance_part` (the default, ``appearance`` "colour"): appearance changes the colour with
  the brightness, an exposure does not; each view's EV is predicted from its chromatic change by the
  relation the other views show, when that relation holds beyond chance.
* :func:`exposure_part` (``appearance`` "smooth", issue 21's): appearance changes smoothly with the viewing
  direction, exposure jumps; split by maximum likelihood of their variances.

"auto" (the default) tries the colour, then the smoothness, each applied only when it holds beyond chance
(the views' colours, or the views, shuffled: a 1 % test), so that a capture with no appearance keeps every
exposure the solve found (issue 21's smooth split alone took 0.14 EV of the jitter for appearance on the
plant; measured in docs/real_cameras.md).
"""

from __future__ import annotations

import numpy as np

#: Fewest linked views the colour regression of :func:`colour_appearance_part` needs; its chance level:
#: this quantile of the leave-one-out R^2 over this many shuffles of the views' colours (seeded).
MIN_APPEARANCE_VIEWS = 6
APPEARANCE_QUANTILE = 0.99
APPEARANCE_SHUFFLES = 200
APPEARANCE_SEED = 0
#: Ratios (appearance variance / exposure variance) tried by :func:`exposure_part`.
APPEARANCE_RATIOS = np.logspace(-3, 4, 29)


def _smooth_nll(z: np.ndarray, lam: np.ndarray) -> np.ndarray:
    """(R,) negative log likelihood (up to a constant) at each APPEARANCE_RATIOS r of data ``z`` (n-1, C) in the
    eigenbasis of the appearance covariance (eigenvalues ``lam`` (n-1,)), the exposure variance profiled out."""
    d = 1.0 + APPEARANCE_RATIOS[:, None] * lam[None]                       # (R, n-1)
    quad = (z ** 2).sum(axis=1)[None] / d
    m, c = z.shape
    return c * m * np.log(quad.sum(axis=1) / (c * m) + 1e-300) + c * np.log(d).sum(axis=1)


def exposure_part(x: np.ndarray, forward: np.ndarray, corr_deg: float, chance: float | None = None):
    """The per-view exposure in log gains ``x`` (V, 3), separated from view-dependent appearance.

    ``x = e + a``: exposure e is independent per view (covariance s_e I); appearance a is
    correlated between views that look from similar directions (covariance s_a K, K_ij =
    exp(-angle_ij^2 / 2 corr_deg^2) from the viewing directions ``forward`` (V, 3)).  The ratio
    s_a / s_e is chosen by maximum likelihood (profiled over s_e, the three channels pooled, the
    global gain projected out), and e is its posterior mean (Wiener filter).  A capture whose views
    differ only smoothly with the viewpoint (fur lit from one side) keeps its colours; one whose
    views jump independently (auto exposure) is corrected.  With ``chance`` (a quantile, e.g. 0.99) the
    split is made only when the likelihood gain over no appearance beats that quantile of the gain with
    the views shuffled (APPEARANCE_SHUFFLES draws, seeded: shuffled views show no smooth appearance);
    else ``x`` is returned as it is.  Returns (e, s_a / s_e; 0 when no split)."""
    n = len(x)
    if n < 3:
        return x, 0.0
    cos = np.clip(forward @ forward.T, -1.0, 1.0)
    K = np.exp(-np.degrees(np.arccos(cos)) ** 2 / (2 * corr_deg ** 2))
    Q = np.linalg.svd(np.eye(n) - 1.0 / n, hermitian=True)[0][:, : n - 1]   # basis without the global gain
    lam, U = np.linalg.eigh(Q.T @ K @ Q)
    lam = np.maximum(lam, 0.0)
    P = U.T @ Q.T
    nll = _smooth_nll(P @ x, lam)
    k = int(np.argmin(nll))
    if chance is not None:
        rng = np.random.default_rng(APPEARANCE_SEED)
        gains = [(lambda v: v[0] - v.min())(_smooth_nll(P @ x[rng.permutation(n)], lam))
                 for _ in range(APPEARANCE_SHUFFLES)]
        if nll[0] - nll[k] <= float(np.quantile(gains, chance)):
            return x, 0.0
    r = float(APPEARANCE_RATIOS[k])
    return Q @ (U @ ((P @ x) / (1.0 + r * lam)[:, None])), r


def _loo(A: np.ndarray, y: np.ndarray) -> tuple[float, np.ndarray]:
    """(q2, (n,) each row's predicted appearance A[i, :2] beta_(-i)) of the least-squares fit y ~ A with each
    row left out in turn (the hat-matrix identities: no refit per row)."""
    G = np.linalg.pinv(A.T @ A)
    beta = G @ A.T @ y
    r = y - A @ beta
    h = np.einsum("ij,jk,ik->i", A, G, A)
    k = r / np.maximum(1.0 - h, 1e-9)
    beta_i = beta[None] - (A @ G) * k[:, None]            # (n, 3): beta without row i
    sst = float(np.sum((y - y.mean()) ** 2))
    q2 = 1.0 - float(np.sum(k ** 2)) / sst if sst > 0 else 0.0
    return q2, np.einsum("ij,ij->i", A[:, :2], beta_i[:, :2])


def colour_appearance_part(x: np.ndarray, linked: np.ndarray) -> tuple[np.ndarray, float]:
    """The per-view exposure in log gains ``x`` (V, 3) of the ``linked`` views, the appearance that comes
    with a change of colour left out (module docstring, step 4).  Each view against the others: the EV
    a = mean over channels of x is regressed (least squares) on the chromatic part (x - a: its red and
    blue) over the *other* linked views, and the view's own chromatic part through that fit is its
    appearance -- so one view whose exposure and white balance both jumped does not explain itself.  It is
    taken out only when the colour predicts the EV of views it was not fitted to beyond chance: the
    leave-one-out R^2 (q2) above the APPEARANCE_QUANTILE of q2 with the views' colours shuffled
    (APPEARANCE_SHUFFLES draws, seeded: exposure and white balance jitter are independent); then in the
    share q2 / R^2.  Returns (log gains (V, 3): one exposure per view when appearance was found, else ``x``
    as it is; q2 when taken out, else 0)."""
    a = x.mean(axis=1)
    c = (x - a[:, None])[:, [0, 2]]
    idx = np.flatnonzero(linked)
    n = len(idx)
    y = a[idx]
    if n < MIN_APPEARANCE_VIEWS or not np.sum((y - y.mean()) ** 2) > 0:
        return x, 0.0
    A = np.concatenate([c[idx], np.ones((n, 1))], axis=1)
    q2, app = _loo(A, y)
    rng = np.random.default_rng(APPEARANCE_SEED)
    null = [_loo(np.concatenate([c[idx][rng.permutation(n)], np.ones((n, 1))], axis=1), y)[0]
            for _ in range(APPEARANCE_SHUFFLES)]
    beta = np.linalg.lstsq(A, y, rcond=None)[0]
    r2 = 1.0 - float(np.sum((y - A @ beta) ** 2)) / float(np.sum((y - y.mean()) ** 2))
    if q2 <= max(0.0, float(np.quantile(null, APPEARANCE_QUANTILE))) or r2 <= 0:
        return x, 0.0
    e = a.copy()
    e[idx] -= min(1.0, q2 / r2) * app
    return np.repeat(e[:, None], 3, axis=1), float(q2)

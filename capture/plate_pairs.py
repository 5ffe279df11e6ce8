"""A moving camera's exposure gains solved at once from pairs of views (capture.plate's panorama path).

The panorama path predicts each view's held-back background ring from its nearest views (capture.plate_reproject)
and fits every view's gain to that prediction (capture.plate.fit_gains), again and again (capture.plate.refit).
A view's prediction comes from its neighbours, whose own gains are still off, so each pass only spreads a view's
exposure to its neighbours: a fixed-point iteration that settles the differences between neighbours at once and
the drift along the orbit very slowly.  On the path-traced orbit with auto exposure (0.35 EV, 18 kept views:
scripts/hardcases.py conifer_room_orbit_ae) two passes left the gains **0.179 EV RMS** off the truth (doing
nothing: 0.300), 20 passes 0.070, 60 passes 0.051; the plates drawn in those exposures missed the held-back
background by up to 0.24 (median, linear; 0.005-0.12 in the views beside it), and the known-background matte
with them (docs/matting.md, "The orbit's exposure").

Here every pair (view i, neighbour j) gives one equation in the log gains h = log g (true colour = colour x g):
a pixel of i's ring that j saw as background satisfies c_i g_i = c_j g_j, so

    h_i - h_j = median over the pair's usable pixels of (log c_j - log c_i)      (per channel)

with both colours neither dark nor blown out (capture.plate's _usable) and at least capture.plate.GAIN_MIN_SAMPLES
pixels.  The equations are solved together by least squares (one gauge row, sum h = 0; then the median view is
1 as capture.plate.fit_gains gives), reweighted PAIR_IRLS_PASSES times with Huber weights at PAIR_HUBER (log
units) so that one pair the room's parallax spoils does not pull the rest.  A view in no usable pair keeps gain 1.
The samples are the ones the panorama's prediction takes (the same background hypotheses and the same sources),
at gain 1.
"""

from __future__ import annotations

import numpy as np

#: The panorama's gains are solved from pairs of views at once (True), else fitted to the panorama's own
#: predictions by capture.plate.refit from gain 1 (the rule before: 0.18 EV RMS off on the orbit above).
PANORAMA_PAIR_GAINS = True
#: Huber threshold of the pair equations' residuals (log gain; 0.05 is about 0.07 EV).
PAIR_HUBER = 0.05
#: Reweighting passes of the pair equations (0: plain least squares).
PAIR_IRLS_PASSES = 3


def ring_samples(ps, i: int, sources) -> tuple[list[int], np.ndarray]:
    """(neighbour indices, (K, N, 3) float32 samples, NaN = none) of view i's ring pixels from each of its
    ``ps.neighbours`` nearest views (capture.plate_reproject.first_samples: the plate's hypotheses in its order),
    in the exposures of ``sources`` (PlateSource list) at gain 1."""
    from capture.plate_reproject import first_samples, neighbour_order

    p = ps.views[i]
    nb = neighbour_order(ps.cameras, i, ps.neighbours)
    return nb, first_samples(p.view.camera, p.ring, np.ones(3), [sources[j] for j in nb], ps.plane, p.room)


def pair_equations(ps, samples, use=None) -> list[tuple[int, int, np.ndarray, int]]:
    """[(i, j, d (3,) = h_i - h_j, pixels)] of every pair with at least GAIN_MIN_SAMPLES usable pixels
    (module docstring); ``samples``: per view :func:`ring_samples`; ``use``: per view a (N_i,) bool of the ring
    pixels to take (None: all)."""
    from capture.plate import GAIN_MIN_SAMPLES, _usable

    eqs = []
    for i, (nb, s) in enumerate(samples):
        obs = ps.views[i].observed
        ok_i = _usable(obs) if use is None else _usable(obs) & use[i]
        for k, j in enumerate(nb):
            ok = ok_i & np.isfinite(s[k]).all(axis=1) & _usable(np.nan_to_num(s[k]))
            n = int(ok.sum())
            if n >= GAIN_MIN_SAMPLES:
                d = np.median(np.log(s[k][ok].astype(np.float64)) - np.log(obs[ok]), axis=0)
                eqs.append((i, j, d, n))
    return eqs


def solve_pairs(eqs, V: int, huber: float = PAIR_HUBER, passes: int = PAIR_IRLS_PASSES) -> np.ndarray:
    """(V, 3) gains g = exp(h) from the pair equations ``eqs`` (:func:`pair_equations`): least squares with
    the gauge sum h = 0, Huber-reweighted ``passes`` times; the median view 1 per channel; views in no
    equation 1."""
    h = np.zeros((V, 3))
    if not eqs:
        return np.ones((V, 3))
    E = len(eqs)
    A = np.zeros((E + 1, V))
    D = np.zeros((E + 1, 3))
    for e, (i, j, d, _) in enumerate(eqs):
        A[e, i], A[e, j], D[e] = 1.0, -1.0, d
    A[E] = 1.0
    seen = np.zeros(V, bool)
    seen[[i for i, *_ in eqs]] = True
    seen[[j for _, j, *_ in eqs]] = True
    for c in range(3):
        w = np.ones(E + 1)
        for _ in range(1 + max(int(passes), 0)):
            sw = np.sqrt(w)[:, None]
            h[:, c] = np.linalg.lstsq(A * sw, D[:, c] * sw[:, 0], rcond=None)[0]
            r = np.abs(A[:E] @ h[:, c] - D[:E, c])
            w[:E] = np.where(r <= huber, 1.0, huber / np.maximum(r, 1e-12))
    h[~seen] = 0.0
    h -= np.median(h[seen], axis=0) if seen.any() else 0.0
    h[~seen] = 0.0
    return np.exp(h)


def pair_gains(ps, use=None, samples=None) -> tuple[np.ndarray, list]:
    """(V, 3) gains of the views of ``ps`` (capture.plate.PlateSet) from their pairs (module docstring),
    and the ring samples used (pass them back as ``samples`` to solve again on other ring pixels ``use``)."""
    from capture.plate_reproject import panorama_sources

    V = len(ps.views)
    if samples is None:
        src = panorama_sources(ps, np.ones((V, 3)))
        samples = [ring_samples(ps, i, src) for i in range(V)]
    return solve_pairs(pair_equations(ps, samples, use), V), samples


def fitted(ps, mode: str, trial) -> tuple:
    """(the chosen path's capture.plate.Trial with its fitted gains, the pair samples or None) for
    capture.plate.background_plates: the panorama's gains from :func:`pair_gains` (PANORAMA_PAIR_GAINS),
    else capture.plate.refit from ``trial`` (the path's first gains)."""
    from capture.plate import refit, ring_trial

    if mode != "panorama" or not PANORAMA_PAIR_GAINS:
        return refit(ps, mode, trial), None
    gains, samples = pair_gains(ps)
    return ring_trial(ps, mode, gains), samples

"""Depth whose scale drifts from view to view: part of the depth-agreement check (volume/agreement.py,
capture/depth_agreement.py).

A monocular network's "metric" depth (a phone without a depth sensor, a video's frames) has each frame at its own
scale, 5-15 % apart.  The scale search of capture.depth_agreement finds one scale for every view, and a capture
whose views are each 15 % either way (``scripts/broken_captures.py CAPTURE OUT scaledrift``) passed it: the
path-traced fur over black "agreed" (3.1 % of its points against the right capture's 23.5 %) and lost 1.7 dB held
out, the path-traced conifer (room, table, auto exposure, lens) 4.2 dB, the synthetic fur ball 3.0 dB.

The check (:func:`view_scale_check`).  Each view's depth gets its own factor, found by coordinate descent (Gauss-
Seidel, at most :data:`ROUNDS` rounds, fewer where the factors stay within :data:`SETTLED_SPREAD` of one): in turn,
each view's factor is the one of a grid about the capture's best scale (within :data:`SPAN`, ratio
:data:`COARSE_STEP`, then :data:`STEP` about the best) at which the most points agree, its own sampled points
projected into its :data:`NEIGHBOURS` nearest views (their depth at their current factors) and theirs into it (the
poses' baselines hold the set's own scale); a set that spreads is then brought to the poses by the scale search of
capture.depth_agreement.agreement.  The factors are fitted on half of every view's points (seeded) and judged on
the other half: the points agreeing with the views' own factors only (b) against those agreeing at the capture's
one scale only (c) give McNemar's z = (b - c) / sqrt(b + c); the drift is named where z >= :data:`VIEW_SCALE_Z` and
the factors spread by at least :data:`MIN_SPREAD` (their log's standard deviation).  ``--depth-agreement fix``
scales every view's depth by its factor.  Measured: docs/capture_formats.md.
"""

from __future__ import annotations

import numpy as np

from capture.depth_agreement import agreement, depth_at, neighbours, verdict

#: Each view's factor is searched within this factor either way of the capture's best scale, at the ratio
#: COARSE_STEP, then at STEP within COARSE_STEP of the best (73 factors tried, not 135 at STEP alone; a coarse
#: step of 1.02 left the conifer's drifting copy 5 % off, against 0.5 %).
SPAN = 1.4
COARSE_STEP = 1.01
STEP = 1.005
#: Each view is held against this many nearest views in viewing direction (both ways).
NEIGHBOURS = 4
#: Gauss-Seidel rounds over the views: on the drifting copies the factors come within 0.2-1.1 % (log RMS) of the
#: truth in 5 rounds, 0.6-5 % in 1 (a ring of three spheres: 0.5 % at most in 5, 0.8 % in 3).
ROUNDS = 5
#: The rounds stop early where the factors spread by less than this (the standard deviation of their logarithm): a
#: right capture's after one round (0.000-0.009; the 72-view phone plant 0.000).
SETTLED_SPREAD = 0.01
#: Named where the points agreeing at the views' own factors only outnumber those agreeing at one scale only by this
#: many standard deviations (McNemar's z, on the points the factors were not fitted on).
VIEW_SCALE_Z = 5.0
#: ... and the factors spread by at least this much (the standard deviation of their logarithm): the copies drifting
#: 5 % either way 0.023-0.027, 15 % 0.075-0.084; right captures at most 0.009 (3-degree pose noise), but the synthetic
#: one with every noise at once (depth, holes, 1-degree pose noise with its translations) 0.016-0.017: a pose off along
#: its view's axis reads as that view's depth scale, and its own factors gave it nothing held out (12.93 -> 12.97 dB).
MIN_SPREAD = 0.02


def scale_grid(centre: float, step: float = STEP, span: float = SPAN) -> np.ndarray:
    """(G,) factors about ``centre``: ``centre`` times ``step`` ** k within ``span`` either way."""
    k = int(np.ceil(np.log(span) / np.log(step)))
    return float(centre) * step ** np.arange(-k, k + 1, dtype=np.float64)


def _agrees(points: np.ndarray, s_i: np.ndarray, cam_i, cam_j, sample_j, s_j: np.ndarray, rel: float) -> np.ndarray:
    """(G, m) whether view i's camera-frame ``points`` (m, 3), its depth times each of ``s_i`` (G,), agree with view
    j's depth map (``sample_j``: capture.depth_agreement.view_sample's) times ``s_j`` (G,)."""
    T = cam_i.world_from_cam
    world = s_i[:, None, None] * (np.asarray(points, np.float64) @ T[:3, :3].T)[None] + T[:3, 3]
    uv, z = cam_j.project(world)
    zj, _ = depth_at(uv, z, sample_j[1], sample_j[2])
    zj *= s_j[:, None]
    return (zj > 0) & (np.abs(z - zj) <= rel * zj)


def _counts(i: int, samples, cameras, nb: np.ndarray, s: np.ndarray, grid: np.ndarray, use, rel: float) -> np.ndarray:
    """(G,) the points agreeing with view i's depth times each of ``grid``, its neighbours' at their factors ``s``:
    its ``use`` points into each neighbour, each neighbour's ``use`` points into it."""
    out = np.zeros(len(grid))
    for j in nb[i][nb[i] >= 0]:
        if len(samples[j][0]):
            sj = np.full(len(grid), s[j])
            out += _agrees(samples[i][0][use[i]], grid, cameras[i], cameras[j], samples[j], sj, rel).sum(axis=1)
            out += _agrees(samples[j][0][use[j]], sj, cameras[j], cameras[i], samples[i], grid, rel).sum(axis=1)
    return out


def _best(counts: np.ndarray, grid: np.ndarray, current: float) -> float:
    """The factor of ``grid`` with the most ``counts``, the nearest ``current`` among ties; ``current`` with none."""
    if counts.max() <= 0:
        return current
    top = np.flatnonzero(counts == counts.max())
    return float(grid[top[np.argmin(np.abs(np.log(grid[top] / current)))]])


def fit_view_scales(samples, cameras, nb: np.ndarray, centre: float, use, rel: float, rounds: int = ROUNDS):
    """(V,) each view's depth factor (module docstring: Gauss-Seidel over the views, from ``centre`` for all, each the
    best given its neighbours' current ones, first of :func:`scale_grid` ``(centre, COARSE_STEP)``, then at STEP
    within COARSE_STEP of that; the poses' baselines hold the set's own scale); ``use``: per view, which of its
    sampled points count."""
    coarse = scale_grid(centre, COARSE_STEP)
    s = np.full(len(cameras), float(centre))
    for _ in range(rounds):
        for i in range(len(cameras)):
            if len(samples[i][0]):
                b = _best(_counts(i, samples, cameras, nb, s, coarse, use, rel), coarse, s[i])
                fine = scale_grid(b, STEP, COARSE_STEP)
                s[i] = _best(_counts(i, samples, cameras, nb, s, fine, use, rel), fine, s[i])
        if np.std(np.log(s)) < SETTLED_SPREAD:  # one scale fits: no round will part them
            break
    return s


def scaled_samples(samples, s: np.ndarray):
    """The views' capture.depth_agreement.view_sample's with each view's depth times its ``s``."""
    return [(p * k, small * np.float32(k), step) for (p, small, step), k in zip(samples, s)]


def judged_hits(samples, cameras, nb: np.ndarray, s: np.ndarray, held, rel: float) -> np.ndarray:
    """(n,) whether each ``held`` point (per view, which of its sampled points; None: all) of every view agrees with
    its neighbours ``nb`` (capture.depth_agreement.neighbours), every view's depth times its ``s`` (V,)."""
    pts = [x[0] if held is None else x[0][held[k]] for k, x in enumerate(samples)]
    out = [_agrees(pts[i], s[i:i + 1], cameras[i], cameras[j], samples[j], s[j:j + 1], rel)[0]
           for i in range(len(cameras)) for j in nb[i][nb[i] >= 0] if len(samples[i][0])]
    return np.concatenate(out) if out else np.zeros(0, bool)


def view_scale_check(samples, cameras, cfg, scale: float, seed: int = 0) -> dict:
    """Each view's depth at its own factor against all at ``scale`` (the capture's best; module docstring):
    ``status`` ``view scales`` with ``factors`` (per view) and the warning's ``message``, or ``one scale``; both with
    ``share`` (its own factors), ``share_one`` (one scale), McNemar's ``z`` and ``spread``."""
    nb = neighbours(cameras, NEIGHBOURS)
    if not (nb >= 0).any():
        return {"status": "one scale"}
    rng = np.random.default_rng(seed)
    use = [rng.random(len(p)) < 0.5 for p, _, _ in samples]
    s = fit_view_scales(samples, cameras, nb, scale, use, cfg.rel)
    if np.std(np.log(s)) >= MIN_SPREAD:  # the set brought to the poses (the factors' own scale is the baselines')
        g, share, share_all, _, _ = agreement(scaled_samples(samples, s), cameras, cfg)
        s *= verdict(g, share, share_all)["best_scale"]
    held = [~u for u in use]
    own = judged_hits(samples, cameras, nb, s, held, cfg.rel)
    one = judged_hits(samples, cameras, nb, np.full(len(cameras), float(scale)), held, cfg.rel)
    b, c = int(np.count_nonzero(own & ~one)), int(np.count_nonzero(one & ~own))
    z = (b - c) / max(float(np.sqrt(b + c)), 1e-9)
    spread = float(np.std(np.log(s)))
    rec = {"share": round(float(own.mean()), 4) if len(own) else 0.0,
           "share_one": round(float(one.mean()), 4) if len(one) else 0.0, "z": round(z, 2),
           "spread": round(spread, 4), "status": "one scale"}
    if z < VIEW_SCALE_Z or spread < MIN_SPREAD:
        return rec
    return {**rec, "status": "view scales", "factors": [round(float(x), 5) for x in s], "message": (
        f"the views' depths agree with their poses far better each at its own scale (factors {s.min():.3g}-"
        f"{s.max():.3g}, spread {spread:.1%}; {rec['share']:.1%} of the points against {rec['share_one']:.1%} at one "
        f"scale; McNemar's z {z:.1f}): is the depth a monocular network's, its scale drifting from frame to frame "
        "(or are the poses off along the views' axes)?")}


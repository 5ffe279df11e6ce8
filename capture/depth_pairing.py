"""Is each depth file its own frame's?  Part of the depth-agreement check (volume/agreement.py).

A capture whose depth files are paired with the wrong frames (each frame given the next frame's depth: an exporter
that dropped one frame of one stream) passes every check on a regular orbit: the depth of frame i + 1 read with the
pose of frame i is the object turned by one step, and every pair of such views agrees with itself (the relative
pose of views i, j is that of views i + 1, j + 1).  The path-traced conifer (room, table, auto exposure, lens) with
every frame given the next frame's depth was modelled 26.41 -> 23.76 dB held out, without a word
(docs/capture_formats.md).

The colour tells.  For a colour image, the depth edges of its own view sit on its edges better than those of its
neighbours' views (the silhouette moves between views).  Each scored colour view (about 24 of them) is held against
the depth edges of its own view and of its :data:`PAIR_NEIGHBOURS` nearest views in viewing direction: the mean
colour-gradient magnitude at each depth's edges, at the best shift within :data:`PAIR_RADIUS` working pixels (a
depth camera beside the colour's), all at most :data:`PAIR_WORK_PX` wide (:func:`pairing_data`,
:func:`edge_fit`).  Within one colour image the scores compare depths only, so no view's contrast or background
weighs.  The files are called mispaired where at least :data:`PAIR_SHARE` of the scored colour views fit a
neighbour's depth best and the median of (best neighbour / own) is at least :data:`PAIR_GAIN`
(:func:`pairing_verdict`).  Measured (docs/capture_formats.md): the copies with each frame given the next frame's
depth: three path-traced conifers 33-36 of 36 views, median 1.07-1.16, the 72-view phone plant 61 of 72, 1.24; right
captures at most 1.02-1.03 (noisy synthetic depth; fur balls 1.007-1.017, where a neighbour's depth is as good as
their own: a fur ball looks alike from each side, and its mispaired copies, 1.015-1.04, are not found).  Where most
scored views (:data:`PAIR_SHIFT_SHARE`) fit best the depth file k places from their own in the capture's order,
the files are shifted by k frames, and ``--depth-agreement fix`` gives each frame the depth file k places on (the
frames without one left out).
"""

from __future__ import annotations

import numpy as np

#: Colour and depth are compared at most this many pixels wide.
PAIR_WORK_PX = 320
#: Shifts searched each way between a colour image and a depth map's edges (working pixels).
PAIR_RADIUS = 3
#: Depth-edge pixels scored per view at most (drawn with the view's seed), and at least.
PAIR_EDGES = 1000
PAIR_MIN_EDGES = 50
#: A colour view is held against the depth edges of this many nearest views in viewing direction, and its own.
PAIR_NEIGHBOURS = 4
#: Mispaired: at least this share of the scored colour views fit a neighbour's depth best ...
PAIR_SHARE = 0.75
#: ... by a median factor of at least this (right captures 1.00-1.024, mispaired asymmetric objects 1.07-1.24).
PAIR_GAIN = 1.05
#: Fewer scored colour views than this are not judged.
PAIR_MIN_VIEWS = 8
#: Mispaired files are shifted by k frames (``--depth-agreement fix`` pairs them again) where at least this share of
#: the scored views fit best the depth file k places from their own in the capture's order (the copies given the
#: next frame's depth: 29-51 of their views at -1; a right capture's best neighbours are either side).
PAIR_SHIFT_SHARE = 2 / 3


def pairing_data(rgb: np.ndarray, depth: np.ndarray, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(the colour's gradient magnitude (h, w) float16 at most PAIR_WORK_PX wide, the depth's edge pixels (ys, xs)
    at least PAIR_RADIUS inside it, at most PAIR_EDGES drawn with ``seed``) of one view (``depth`` on the colour's
    pixel grid, metres)."""
    from capture.depth_registration import gradient_and_edges

    G, ys, xs, _ = gradient_and_edges(rgb, depth, seed, PAIR_WORK_PX, PAIR_RADIUS, PAIR_EDGES)
    return G.astype(np.float16), ys.astype(np.int32), xs.astype(np.int32)


def edge_fit(G: np.ndarray, ys: np.ndarray, xs: np.ndarray) -> float:
    """The mean of ``G`` at the edge pixels (ys, xs), at the best shift within PAIR_RADIUS each way; NaN with fewer
    than PAIR_MIN_EDGES edges or a map of another size's edges outside it."""
    R = PAIR_RADIUS
    if len(ys) < PAIR_MIN_EDGES or ys.max() >= G.shape[0] - R or xs.max() >= G.shape[1] - R:
        return float("nan")
    d = np.arange(-R, R + 1)
    v = np.asarray(G, np.float32)[(ys[None, :] + d[:, None])[:, None, :], (xs[None, :] + d[:, None])[None, :, :]]
    return float(v.mean(axis=-1).max())


def pairing_views(cameras, scored: list[int]) -> tuple[dict[int, list[int]], list[int]]:
    """(each scored colour view -> its candidate depth views: itself and its PAIR_NEIGHBOURS nearest in viewing
    direction; every view whose pairing data is needed, sorted)."""
    f = np.array([c.forward for c in cameras], np.float64)
    f /= np.maximum(np.linalg.norm(f, axis=1, keepdims=True), 1e-12)
    cand = {}
    for j in scored:
        order = [int(i) for i in np.argsort(-(f @ f[j]), kind="stable") if int(i) != j]
        cand[j] = [j, *order[:PAIR_NEIGHBOURS]]
    return cand, sorted({i for c in cand.values() for i in c})


def pairing_verdict(data: dict, candidates: dict[int, list[int]]) -> dict:
    """The record of the depth files against their frames from ``data`` (view -> :func:`pairing_data`) and
    ``candidates`` (:func:`pairing_views`): ``pairing_views`` (colour views scored), ``pairing_other_best`` (of
    them, those a neighbour's depth fits best), ``pairing_gain`` (the median best neighbour / own), ``mispaired``
    (the rule of PAIR_SHARE and PAIR_GAIN, from PAIR_MIN_VIEWS views), and a message where it is."""
    other, gains, shifts = 0, [], []
    for j, cand in candidates.items():
        G = data[j][0]
        fit = {i: edge_fit(G, data[i][1], data[i][2]) for i in cand}
        others = {i: v for i, v in fit.items() if i != j and v == v}
        if not fit[j] > 0 or not others:
            continue
        best = max(others, key=others.get)
        other += others[best] > fit[j]
        gains.append(others[best] / fit[j])
        shifts.append(best - j if others[best] > fit[j] else 0)
    n = len(gains)
    gain = float(np.median(gains)) if gains else 1.0
    bad = n >= PAIR_MIN_VIEWS and other >= PAIR_SHARE * n and gain >= PAIR_GAIN
    rec = {"pairing_views": n, "pairing_other_best": int(other), "pairing_gain": round(gain, 4), "mispaired": bool(bad)}
    if bad:
        k, count = np.unique(shifts, return_counts=True)
        top = int(np.argmax(count))
        shift = int(k[top]) if k[top] != 0 and count[top] >= PAIR_SHIFT_SHARE * n else None
        rec["pairing_shift"] = shift
        rec["pairing_message"] = (
            f"{other} of {n} colour images fit a neighbouring view's depth edges better than their own (median "
            f"{gain:.2f} times)" + ("" if shift is None else
                                    f", {int(count[top])} of them the depth file {shift:+d} frames from their own")
            + ": is each depth file its own frame's (depth_file_path; a stream that dropped a frame pairs every later "
            "depth with the next colour image)?")
    return rec

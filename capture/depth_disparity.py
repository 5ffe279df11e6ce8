"""Disparity stored where depth belongs: part of the depth-agreement check (volume/agreement.py,
capture/depth_agreement.py).

An iPhone's depth (AVDepthData) comes as depth or as disparity (1 / metres), a stereo camera gives its disparity
(focal length x baseline / depth), and either, written as a 16-bit PNG, looks like millimetres.  Read as depth, the
near side of the object is the far side.  The scale search of capture.depth_agreement read such a capture (1000 /
z in metres, ``scripts/broken_captures.py CAPTURE OUT disparity``) as a depth scale of 0.24-0.30 (the fur captures)
or as nothing (the path-traced conifer with a room and a table), and ``--depth-agreement fix`` would have scaled it
by 0.24: a wrong repair.

The check (:func:`disparity_check`, run where the scales' verdict is ``scale`` or ``none``).  Every view's sampled
points are read as disparity: a value d becomes the depth k / d, the point moved along its ray, each neighbour's
depth map read the same way.  One constant k serves every view (a sensor's disparity is one constant over its
depth; a monocular network's relative output, normalised per frame, is not read here and stays ``none``).  Its
first guess makes the median depth the poses' own distance to the object (:func:`pose_distance`: the median
distance of the cameras to the point nearest every optical axis) and the scale search of
capture.depth_agreement.agreement finds the rest, within its SCALE_RANGE.  The points agreeing read as disparity
only (b) against those agreeing as stored only (c), each at its best scale, give McNemar's z = (b - c) /
sqrt(b + c); disparity is named where z >= :data:`DISPARITY_Z`.  Measured (docs/capture_formats.md): the
disparity copies of the path-traced conifer (room, table, auto exposure, lens), the path-traced fur over black,
the synthetic fur ball and the 72-view phone plant +51.9 to +209 (their shares read so equal to the right
captures': 0.228 against 0.228, 0.337 against 0.338); the right captures -26 to -62.
``--depth-agreement fix`` reads every depth map as k / d (:func:`read_disparity`).
"""

from __future__ import annotations

import numpy as np

from capture.depth_agreement import agreement, neighbours, verdict
from capture.depth_view_scales import judged_hits
from capture.orbit import closest_point_to_axes

#: Disparity is named where the points agreeing read so only outnumber those agreeing as stored only by this many
#: standard deviations (McNemar's z): the disparity copies +51.9 to +209, right captures -26 to -62.
DISPARITY_Z = 5.0


def pose_distance(cameras) -> float:
    """The median distance (metres) of the cameras' centres from the point nearest every optical axis
    (capture.orbit.closest_point_to_axes: 1 m in front of them where the axes are all parallel)."""
    x = closest_point_to_axes(cameras)
    return float(np.median([np.linalg.norm(np.asarray(c.center, np.float64) - x) for c in cameras]))


def inverted_sample(sample, k: float):
    """A view's capture.depth_agreement.view_sample (points, depth map every ``step`` pixels, step) with every
    depth d read as ``k`` / d (its points moved along their rays; zeros kept)."""
    pts, small, step = sample
    if len(pts):
        pts = pts * (k / np.square(pts[:, 2:3]))
    out = np.zeros_like(small)
    v = small > 0
    out[v] = k / small[v]
    return pts, out, step


def disparity_check(samples, cameras, cfg, stored_scale: float) -> dict:
    """The depth read as disparity against as stored at ``stored_scale`` (its best, the scales' verdict's; module
    docstring): ``status`` ``disparity`` with ``constant`` (k, metres squared: depth = k / value) and the warning's
    ``message``, or ``as stored``; both with ``share`` (read so), ``share_as_stored`` and McNemar's ``z``."""
    values = np.concatenate([x[0][:, 2] for x in samples if len(x[0])] or [np.zeros(0)])
    if not len(values):
        return {"status": "as stored"}
    median = float(np.median(values))
    d = pose_distance(cameras)
    k0 = (d if np.isfinite(d) and d > 0 else median) * median
    inv = [inverted_sample(x, k0) for x in samples]
    s, share, share_all, _, _ = agreement(inv, cameras, cfg)
    rec = verdict(s, share, share_all)
    nb, V = neighbours(cameras, cfg.neighbours), len(cameras)  # each at its best scale, over the scales' search's pairs
    a = judged_hits(samples, cameras, nb, np.full(V, float(stored_scale)), None, cfg.rel)
    b = judged_hits(inv, cameras, nb, np.full(V, float(rec["best_scale"])), None, cfg.rel)
    n_b, n_c = int(np.count_nonzero(b & ~a)), int(np.count_nonzero(a & ~b))
    z = (n_b - n_c) / max(float(np.sqrt(n_b + n_c)), 1e-9)
    k = k0 * float(rec["best_scale"])
    out = {"constant": round(k, 6), "share": round(float(b.mean()), 4), "share_as_stored": round(float(a.mean()), 4),
           "z": round(z, 2), "status": "as stored"}
    if z < DISPARITY_Z or rec["status"] == "none":
        return out
    return {**out, "status": "disparity", "message": (
        f"the views' depths agree with their poses read as disparity, depth = {k:.4g} / value in metres "
        f"({out['share']:.1%} of the points against {out['share_as_stored']:.1%} as stored at their best scale; "
        f"McNemar's z {z:.1f}): are the depth maps disparity (inverse depth: an iPhone's AVDepthData can be either, "
        "a stereo camera gives disparity), not depth?")}


def read_disparity(depth: np.ndarray, k: float) -> np.ndarray:
    """(H, W) float32 depth (metres) from a map of disparity ``depth`` read as depth: ``k`` / value, 0 and NaN
    kept."""
    d = np.asarray(depth, np.float32)
    out = d.copy()
    v = np.isfinite(d) & (d > 0)
    out[v] = np.float32(k) / d[v]
    return out

"""Do the views' depths agree with their poses?  A check before any model is built.

A capture whose poses and depth do not describe one scene is modelled wrong without a word: the
poses of a structure-from-motion run (COLMAP's have no metric scale) with a sensor's metric depth,
a wrong ``depth_unit_scale_factor``, intrinsics of another image size, a principal point in the
corner, poses in the other axis convention.  Measured on a 24-view synthetic fur ball (furrow eval
--holdout 2, gather): 24.48 dB as captured; poses at half scale 15.88, principal point at (0, 0)
15.60, focal length x 1.5 19.49; all exit 0 with no warning (docs/capture_formats.md).

The check.  For each view, :data:`AGREE_POINTS` of its depth pixels (seeded by the view's name) are
back-projected and projected into its :data:`AGREE_NEIGHBOURS` nearest views in viewing direction.
A point *agrees* where its depth in that view is within :data:`AGREE_REL` of the depth that view
measured at the pixel it lands on (the nearest sample of that view's depth map, subsampled to at most
:data:`AGREE_MAP_PX` on its longer side).  This is counted with every depth multiplied by a scale s
from 1 / SCALE_RANGE to SCALE_RANGE (ratio :data:`SCALE_STEP`, the best refined at :data:`FINE_STEP`):
scaling the depth by s is scaling the poses' translations by 1 / s.  A point that agrees at more than
:data:`BLIND_SCALES` of those scales is *scale-blind*: a table top seen by a ring of cameras at one
height agrees at every scale (each camera's scaled plane is one plane), and on a path-traced fur ball
with a table, auto exposure and a lens, 6 views 60 degrees apart, such points put the best scale at 0.71.
The best scale is the one where the most points that are not scale-blind agree.  With poses and depth
right it is 1 (within 0.3 %: the synthetic fur ball 0.26 of its points, a path-traced conifer before a
room with a table 0.19, path-traced fur 0.15-0.22, the 72-view phone plant 0.79, noisy depth and 1-3
degree pose noise 0.05-0.33 at 0.96-1.00); with the poses at half scale it is 0.50 (0.28).
Verdicts (:func:`verdict`):

* ``agree``: the best scale is within :data:`SCALE_TOLERANCE` of 1, or it does not agree
  :data:`SCALE_GAIN` times more than 1 does;
* ``scale``: the depth agrees best scaled by s (the record gives s and both shares): the depth unit or
  the poses' scale is off;
* ``none``: no scale makes more than :data:`AGREE_FLOOR` of all the points (scale-blind ones included)
  agree: the poses' convention, the intrinsics or the frames' files are wrong, or the depth's unit and
  the poses' are more than SCALE_RANGE apart (the principal point at (0, 0): 0.035 at best; the poses in
  OpenCV axes where OpenGL's are read: 0.016; the poses in millimetres: 0; the right captures above
  0.17-0.76).

A focal length that is off is a fourth verdict, ``focal`` (:func:`focal_check`, run where the scales' verdict is
``agree`` or ``scale``): the scale search alone read a focal length 0.7x its own as the scale 0.85 (``fix`` cost it
2.9 dB) and did not see 1.5x (best scale 1.07).  With every view's fl_x and fl_y times a factor a (principal points
kept), the search finds the a that undoes it (within 1 % on nine captures with focal lengths 0.7-2.0x their own:
the synthetic fur ball, a path-traced conifer and fur ball with a table, auto exposure and a lens), and the depth
then agrees best at its own scale.  A right capture whose best a is off 1 (noisy depth with pose noise: 0.78) is
told apart by its pairs (0.74 of them agree more there, against 0.82-1.0) and its depth's best scale there (0.88).
It is warned about and never fixed.  Each view's own share at s = 1 is recorded too (of its
points that land on a neighbour's measured depth, so that a view whose neighbours measured only the
object is not counted against), but no view is named: on three path-traced captures a view given another
view's depth file fell to 0.26-0.72 of the median view's share, while the lowest view of a right capture
sits at 0.39-0.91 of it (the 72-view phone plant 0.39, the conifer with a table 0.51).

By default nothing is changed: the check warns (volume/agreement.py) and the model record keeps its
figures; ``--depth-agreement fix`` scales every view's depth by s on a ``scale`` verdict (the poses stay
the capture's; the half-scale fur ball's held-out views: docs/capture_formats.md).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from capture.camera import invert_rigid, misread_intrinsics, misread_poses

#: Views further apart in viewing direction than this (degrees) are not compared.
MAX_PAIR_ANGLE = 75.0
#: Depth pixels sampled per view (1,000 gave the same verdicts and best scales within 0.3 % on every capture measured,
#: at 5 times the cost: the default test run builds hundreds of small models).
AGREE_POINTS = 400
#: Nearest views (in viewing direction) each view's points are projected into.
AGREE_NEIGHBOURS = 2
#: A point agrees where its depth is within this fraction of the depth the other view measured there.
AGREE_REL = 0.01
#: The other views' depth maps are read at most this many samples on their longer side (nearest).
AGREE_MAP_PX = 320
#: Depth scales searched: 1 / SCALE_RANGE .. SCALE_RANGE ...
SCALE_RANGE = 4.0
#: ... each this ratio from the next.
SCALE_STEP = 1.03
#: The best scale of that grid is refined on a grid of this ratio, one step either side.
FINE_STEP = 1.003
#: A best scale within [1 / SCALE_TOLERANCE, SCALE_TOLERANCE] is taken as 1.
SCALE_TOLERANCE = 1.1
#: A best scale away from 1 is reported when its share is at least this many times the share at 1.
SCALE_GAIN = 1.5
#: A point agreeing at more than this many scales of the grid (a span of about 1.03^6 = 1.19) is scale-blind:
#: a table top seen by a ring of cameras at one height agrees at every scale (module docstring).
BLIND_SCALES = 6
#: Below this share at every scale the views' depths agree nowhere.
AGREE_FLOOR = 0.05
#: Focal-length factors searched (every view's fl_x and fl_y times a, principal points kept): 1 / FOCAL_RANGE ..
#: FOCAL_RANGE ...
FOCAL_RANGE = 2.0
#: ... each this ratio from the next; the best refined at FOCAL_FINE, FOCAL_FINE_STEPS either side.
FOCAL_STEP = 1.06
FOCAL_FINE = 1.01
FOCAL_FINE_STEPS = 6
#: A best factor within [1 / FOCAL_TOLERANCE, FOCAL_TOLERANCE] is taken as 1.
FOCAL_TOLERANCE = 1.08
#: A focal length is reported when, at the best factor a: the points agree at least FOCAL_GAIN times as often as
#: with the focal lengths as given; at least FOCAL_PAIRS of the view pairs whose count changed agree more (and at
#: least FOCAL_MIN_PAIRS of them changed); and the depth agrees best at its own scale there (within
#: FOCAL_SCALE_TOLERANCE, on a grid of FOCAL_FINE). Right captures whose best factor is off 1 (noisy depth, pose
#: noise) failed the last two: 0.69-0.74 of their pairs, the depth's best scale 0.88-0.95 there (focal_check).
FOCAL_GAIN = 1.08
FOCAL_PAIRS = 0.8
FOCAL_MIN_PAIRS = 8
FOCAL_SCALE_TOLERANCE = 1.011
#: ... and the points that agree at a but not as given outnumber the reverse by at least this many standard
#: deviations (McNemar's z, (b - c) / sqrt(b + c)): focal lengths off by 10-43 % score 7.2-73; right captures with
#: pose noise whose best factor is off 1 score 3.2-3.3 (six noisy views 60 degrees apart had passed every other
#: rule at 0.917: the best of 38 factors on a few hundred points).
FOCAL_Z = 5.0
#: Where the views' depths agree with their poses at no scale or at another, the poses read in other conventions
#: (capture.camera.misread_poses) are tried: one is named when its depths agree at scale 1 (verdict ``agree``) with at
#: least this many times the share that the poses as read reach at their best scale (points that are not
#: scale-blind; measured: the right convention 0.25-0.76, the poses as read 0-0.015, the wrong ones under 0.01).
CONVENTION_GAIN = 2.0
#: The intrinsics' misreadings (capture.camera.misread_intrinsics), in the warning.
INTRINSICS_HINTS = {
    "image size": "with every view's fl_x, fl_y, cx and cy times {k:.3g}: are they the intrinsics of images "
                  "{inv:.3g} times the size of these (images resized after calibration)?",
    "centre": "with the principal point at the image's centre: are cx, cy in pixels from the top-left corner?",
}
#: Depth units off by more than the scale search reaches (SCALE_RANGE): every depth times each of these is tried
#: (:func:`units_check`: millimetres or centimetres read as metres, or the reverse; the poses' translations in
#: other units read the same).
UNIT_FACTORS = (0.001, 0.01, 0.1, 10.0, 100.0, 1000.0)
#: What each misreading is, in the warning.
CONVENTION_HINTS = {
    "axes": "read with their camera y and z axes negated (camera-to-world matrices in OpenCV axes where "
            "transforms.json has OpenGL's?)",
    "inverse": "inverted (world-to-camera matrices where camera-to-world ones belong: in transforms.json written in "
               "OpenCV axes; or camera-to-world poses where COLMAP's images.txt has world-to-camera ones?)",
    "inverse, axes": "inverted with their camera y and z axes negated (world-to-camera matrices in OpenGL axes where "
                     "transforms.json has camera-to-world ones?)",
}


@dataclass(frozen=True)
class AgreementConfig:
    """Settings of the depth-agreement check (volume/agreement.py)."""

    points: int = AGREE_POINTS
    """Depth pixels sampled per view."""
    neighbours: int = AGREE_NEIGHBOURS
    """Nearest views in viewing direction each view's points are projected into."""
    rel: float = AGREE_REL
    """Agreement tolerance: a fraction of the measured depth."""
    fix: bool = False
    """``--depth-agreement fix``: where the depth agrees best at another scale s (verdict ``scale``), every
    view's depth is scaled by s (the poses, and the model's frame, stay the capture's); where the colour's edges
    sit beside the depth's (capture.depth_registration), every depth map is moved onto its colour; where the depth
    agrees only flipped or read as range (capture.depth_readings), it is read so."""

    def __post_init__(self) -> None:
        if self.points < 1 or self.neighbours < 1 or not 0 < self.rel < 1:
            raise ValueError(f"depth agreement: points and neighbours >= 1 and 0 < rel < 1, got {self}")


def scales() -> np.ndarray:
    """(S,) the depth scales searched (module docstring), 1 among them."""
    k = int(np.ceil(np.log(SCALE_RANGE) / np.log(SCALE_STEP)))
    return SCALE_STEP ** np.arange(-k, k + 1, dtype=np.float64)


def view_sample(depth: np.ndarray, camera, n: int, seed: int) -> tuple[np.ndarray, np.ndarray, int]:
    """(points (m, 3) float64 in the camera's frame, m <= n, of random measured pixels; the depth map
    subsampled every ``step`` pixels; step) of one view (module docstring)."""
    d = np.asarray(depth, np.float32)
    v = np.flatnonzero(np.isfinite(d.ravel()) & (d.ravel() > 0))
    rng = np.random.default_rng(seed)
    pick = np.sort(rng.choice(v, min(int(n), len(v)), replace=False)) if len(v) else v
    ys, xs = np.divmod(pick, d.shape[1])
    z = d.ravel()[pick].astype(np.float64)
    pts = camera.pixel_rays(np.stack([xs, ys], axis=1)) * z[:, None]
    step = max(1, int(np.ceil(max(d.shape) / AGREE_MAP_PX)))
    small = np.where(np.isfinite(d[::step, ::step]), d[::step, ::step], 0.0).astype(np.float32)
    return pts, small, step


def neighbours(cameras, k: int) -> np.ndarray:
    """(V, min(k, V - 1)) the views nearest each view in viewing direction (its optical axis), -1 where the
    next nearest is more than :data:`MAX_PAIR_ANGLE` degrees away (two views of opposite sides share too
    little of the object to be compared)."""
    f = np.array([c.forward for c in cameras], np.float64)
    f /= np.maximum(np.linalg.norm(f, axis=1, keepdims=True), 1e-12)
    cos = f @ f.T
    np.fill_diagonal(cos, -np.inf)
    nb = np.argsort(-cos, axis=1, kind="stable")[:, : max(0, min(int(k), len(cameras) - 1))]
    far = np.take_along_axis(cos, nb, axis=1) < np.cos(np.radians(MAX_PAIR_ANGLE))
    return np.where(far, -1, nb)


def pair_hits(points: np.ndarray, cam_i, cam_j, small: np.ndarray, step: int, s: np.ndarray,
              rel: float, focal: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """((S, m) whether each of view i's camera-frame ``points`` agrees with view j's depth (``small``, every
    ``step`` pixels), (S, m) whether it lands on a pixel where view j measured depth), with every depth
    scaled by each of ``s`` (module docstring) and, given ``focal`` (S,), every view's focal lengths times
    ``focal`` (its principal point kept: a point's x and y in its camera's frame divided by it, view j's pixel
    moved from its principal point times it)."""
    Ti = cam_i.world_from_cam
    if focal is not None:
        lateral = np.stack([1.0 / focal, 1.0 / focal, np.ones_like(focal)], axis=1)[:, None, :]
        world = s[:, None, None] * ((points[None] * lateral) @ Ti[:3, :3].T) + Ti[:3, 3]
    else:
        world = s[:, None, None] * (points @ Ti[:3, :3].T)[None] + Ti[:3, 3]   # (S, m, 3): depth x s about view i
    uv, z = cam_j.project(world)                                          # uv NaN behind view j
    if focal is not None:
        c = cam_j.K[:2, 2]
        uv = c + focal[:, None, None] * (uv - c)
    zj, _ = depth_at(uv, z, small, step)
    zj *= s[:, None]
    landed = zj > 0
    return landed & (np.abs(z - zj) <= rel * zj), landed


def depth_at(uv: np.ndarray, z: np.ndarray, small: np.ndarray, step: int) -> tuple[np.ndarray, np.ndarray]:
    """(the depth map ``small`` (a view's, every ``step`` pixels) at its sample nearest each pixel ``uv`` (..., 2)
    whose point is in front (``z`` > 0), 0 elsewhere; whether the pixel falls inside the map and in front)."""
    with np.errstate(invalid="ignore"):
        r, c = np.rint(uv[..., 1] / step), np.rint(uv[..., 0] / step)
        inside = (z > 1e-9) & (r >= 0) & (r < small.shape[0]) & (c >= 0) & (c < small.shape[1])
    zj = np.zeros(z.shape)
    zj[inside] = small[r[inside].astype(np.int64), c[inside].astype(np.int64)]
    return zj, inside


def agreement(samples, cameras, cfg: AgreementConfig):
    """(the scales searched (S,) ascending; the share of the points that are not scale-blind that agree at
    each (S,); the share of every point that agrees at each (S,); each view's own share at scale 1 (V,), NaN
    for a view without depth; the share of points left out as scale-blind) from ``samples``
    (:func:`view_sample` of each view) and the views' ``cameras``: the grid of :func:`scales`, then a grid
    of ratio :data:`FINE_STEP` one step either side of its best.  A point that agrees at more than
    :data:`BLIND_SCALES` scales of the grid is scale-blind and left out of the first share (module
    docstring)."""
    s = scales()
    one = int(np.argmin(np.abs(np.log(s))))
    nb = neighbours(cameras, cfg.neighbours)
    if not (nb >= 0).any():
        return s, np.zeros(len(s)), np.zeros(len(s)), np.full(len(cameras), np.nan), 0.0
    hits, every, kept, seen = np.zeros(len(s)), np.zeros(len(s)), 0, 0
    per_view = np.full(len(cameras), np.nan)
    keeps = {}
    for i, (pts, _, _) in enumerate(samples):
        h = np.zeros((2, len(s)))
        for j in nb[i][nb[i] >= 0] if len(pts) else ():
            ok, landed = pair_hits(pts, cameras[i], cameras[j], samples[j][1], samples[j][2], s, cfg.rel)
            keeps[i, j] = keep = np.count_nonzero(ok, axis=0) <= BLIND_SCALES
            h += [np.count_nonzero(ok[:, keep], axis=1), np.count_nonzero(landed[:, keep], axis=1)]
            every += np.count_nonzero(ok, axis=1)
            kept += int(keep.sum())
            seen += len(pts)
        hits += h[0]
        if h[1, one]:
            per_view[i] = h[0, one] / h[1, one]
    share = hits / max(kept, 1)
    b = s[int(np.argmax(share))]
    k = int(np.ceil(np.log(SCALE_STEP) / np.log(FINE_STEP)))
    fine = b * FINE_STEP ** np.arange(-k, k + 1, dtype=np.float64)
    fine = fine[np.abs(np.log(fine)) > 1e-12]  # 1 stays the grid's own
    fine_hits = np.zeros((2, len(fine)))
    for (i, j), keep in keeps.items():
        ok, _ = pair_hits(samples[i][0], cameras[i], cameras[j], samples[j][1], samples[j][2], fine, cfg.rel)
        fine_hits += [np.count_nonzero(ok[:, keep], axis=1), np.count_nonzero(ok, axis=1)]
    s_all = np.concatenate([s, fine])
    informative = np.concatenate([share, fine_hits[0] / max(kept, 1)])
    everything = np.concatenate([every, fine_hits[1]]) / max(seen, 1)
    order = np.argsort(s_all, kind="stable")
    return s_all[order], informative[order], everything[order], per_view, 1.0 - kept / max(seen, 1)


def verdict(s: np.ndarray, share: np.ndarray, share_all: np.ndarray) -> dict:
    """The check's record: status ``agree`` / ``scale`` / ``none`` (module docstring), the share at scale 1
    and at the best scale, the best scale, and a message; ``share``: of the points that are not scale-blind
    (where the best scale is found), ``share_all``: of every point (what ``none`` reads)."""
    one = int(np.argmin(np.abs(np.log(s))))
    best = int(np.argmax(share))
    top = float(np.max(share_all))
    rec = {"share": round(float(share[one]), 4), "best_scale": round(float(s[best]), 4),
           "best_share": round(float(share[best]), 4), "share_all_best": round(top, 4)}
    if top < AGREE_FLOOR:
        rec["status"] = "none"
        rec["message"] = (f"the views' depths do not agree with their poses at any scale (at best "
                          f"{top:.1%} of the points land on a neighbour's measured depth): are the poses "
                          "in the capture's convention (transforms.json: OpenGL axes), the intrinsics those of "
                          "these image sizes (fl_x, fl_y, cx, cy), each depth file its frame's, the depth's unit "
                          f"and the poses' within {SCALE_RANGE:g}x of each other, and the depth metric (not a "
                          "network's relative depth)?")
    elif abs(np.log(s[best])) > np.log(SCALE_TOLERANCE) and share[best] >= SCALE_GAIN * share[one]:
        rec["status"] = "scale"
        rec["message"] = (f"the views' depths agree best with their poses when scaled by {s[best]:.3g} "
                          f"({share[best]:.1%} of the points against {share[one]:.1%} as given): is the depth's "
                          f"unit right (depth_unit_scale_factor x {s[best]:.3g}), or are the poses at another "
                          f"scale (their translations x {1 / s[best]:.3g}; structure-from-motion poses have none)?")
    else:
        rec["status"] = "agree"
        rec["message"] = (f"the views' depths agree with their poses ({share[one]:.1%} of the points; best scale "
                          f"{s[best]:.3g})")
    return rec


def focal_factors() -> np.ndarray:
    """(A,) the focal-length factors searched (:data:`FOCAL_RANGE`, :data:`FOCAL_STEP`), 1 among them."""
    k = int(np.ceil(np.log(FOCAL_RANGE) / np.log(FOCAL_STEP)))
    return FOCAL_STEP ** np.arange(-k, k + 1, dtype=np.float64)


def _pair_counts(samples, cameras, pairs, s: np.ndarray, focal: np.ndarray, rel: float) -> np.ndarray:
    """(P, G) the points of each view pair (i, j) of ``pairs`` agreeing at each (depth scale, focal factor)."""
    return np.array([np.count_nonzero(pair_hits(samples[i][0], cameras[i], cameras[j], samples[j][1],
                                                samples[j][2], s, rel, focal)[0], axis=1) for i, j in pairs])


def _discordance_z(samples, cameras, pairs, a: float, rel: float) -> float:
    """McNemar's z of the points of ``pairs`` that agree with the focal lengths times ``a`` but not as given (b)
    against the reverse (c): (b - c) / sqrt(b + c)."""
    b = c = 0
    for i, j in pairs:
        ok, _ = pair_hits(samples[i][0], cameras[i], cameras[j], samples[j][1], samples[j][2], np.ones(2), rel,
                          np.array([1.0, a]))
        b, c = b + int(np.count_nonzero(ok[1] & ~ok[0])), c + int(np.count_nonzero(ok[0] & ~ok[1]))
    return (b - c) / max(float(np.sqrt(b + c)), 1e-9)


def focal_check(samples, cameras, cfg: AgreementConfig) -> dict:
    """Whether the depths agree with the poses better with every view's focal lengths times a factor a (the
    principal points and the depth as given): a wrong fl_x / fl_y (intrinsics of another image size, a focal
    length in other units) moves every point sideways, not along its ray, so no depth scale undoes it.  Every
    sampled point counts (a table top is not scale-blind here).  Record: ``focal_factor`` (the best a),
    ``focal_share`` and ``share_as_given`` (of all points), ``pairs_better`` / ``pairs_worse`` (view pairs whose
    count rose / fell at a), ``discordance_z`` and ``depth_scale_at_focal`` (where tested), ``status``
    ``focal`` (the rules of :data:`FOCAL_GAIN` and :data:`FOCAL_Z`) or ``as given``, and ``message``."""
    nb = neighbours(cameras, cfg.neighbours)
    pairs = [(i, int(j)) for i in range(len(cameras)) for j in nb[i] if j >= 0 and len(samples[i][0])]
    n = sum(len(samples[i][0]) for i, _ in pairs)
    if not n:
        return {"status": "as given", "focal_factor": 1.0, "message": "no view pairs to compare"}
    grid = focal_factors()
    counts = _pair_counts(samples, cameras, pairs, np.ones(len(grid)), grid, cfg.rel)
    one = int(np.argmin(np.abs(np.log(grid))))
    best, at_best = 1.0, counts[:, one]
    if int(np.argmax(counts.sum(0))) != one:
        fine = grid[int(np.argmax(counts.sum(0)))] * FOCAL_FINE ** np.arange(-FOCAL_FINE_STEPS, FOCAL_FINE_STEPS + 1)
        fc = _pair_counts(samples, cameras, pairs, np.ones(len(fine)), fine, cfg.rel)
        best, at_best = float(fine[int(np.argmax(fc.sum(0)))]), fc[:, int(np.argmax(fc.sum(0)))]
    given = counts[:, one]
    up, down = int(np.count_nonzero(at_best > given)), int(np.count_nonzero(at_best < given))
    rec = {"focal_factor": round(best, 4), "focal_share": round(float(at_best.sum() / n), 4),
           "share_as_given": round(float(given.sum() / n), 4), "pairs_better": up, "pairs_worse": down}
    found = (abs(np.log(best)) > np.log(FOCAL_TOLERANCE) and at_best.sum() >= FOCAL_GAIN * given.sum()
             and up + down >= FOCAL_MIN_PAIRS and up >= FOCAL_PAIRS * (up + down))
    if found:  # more than chance among the factors tried: the points that changed, as given against at best
        rec["discordance_z"] = round(_discordance_z(samples, cameras, pairs, best, cfg.rel), 2)
        found = rec["discordance_z"] >= FOCAL_Z
    if found:  # the depth's own scale must be the best there: a focal error leaves the depth along its rays right
        k = int(np.ceil(np.log(FOCAL_STEP) / np.log(FOCAL_FINE))) + FOCAL_FINE_STEPS
        sg = FOCAL_FINE ** np.arange(-k, k + 1, dtype=np.float64)
        sc = _pair_counts(samples, cameras, pairs, sg, np.full(len(sg), best), cfg.rel).sum(0)
        rec["depth_scale_at_focal"] = round(float(sg[int(np.argmax(sc))]), 4)
        found = abs(np.log(rec["depth_scale_at_focal"])) <= np.log(FOCAL_SCALE_TOLERANCE)
    rec["status"] = "focal" if found else "as given"
    rec["message"] = (
        f"the views' depths agree best with their poses when every focal length (fl_x, fl_y) is {best:.3g} times "
        f"the capture's ({rec['focal_share']:.1%} of the points against {rec['share_as_given']:.1%} as given; "
        f"{up} of {up + down} view pairs better): are the intrinsics those of these image sizes (images resized "
        "after calibration?) and in pixels?" if found else
        f"the focal lengths as given agree best (or no better factor is sure: best {best:.3g})")
    return rec


def _readings(samples, cameras, cfg: AgreementConfig, given_best: float, readings: dict) -> dict:
    """The depths held against the poses under each of ``readings`` (name -> (cameras, samples)): the share of the
    points that are not scale-blind agreeing at scale 1 and the verdict of each (``tried``); the best named
    (``found``, and ``said``: the warning's first words) where its verdict is ``agree`` and its share is at least
    :data:`CONVENTION_GAIN` times ``given_best`` (what the capture as read reaches at its best scale, ``verdict``'s
    ``best_share``) and at least :data:`AGREE_FLOOR`.  Scale-blind points are left out: cameras all at one point
    (poses inverted) agree at every scale (0.15 of all points on the fur ball, 0.49 on a ring of spheres) and at
    none of them for a reason."""
    tried = {}
    for name, (cams, smp) in readings.items():
        s, share, share_all, _, _ = agreement(smp, cams, cfg)
        rec = verdict(s, share, share_all)
        tried[name] = {"status": rec["status"], "share": round(float(share[int(np.argmin(np.abs(np.log(s))))]), 4)}
    ok = {n: t for n, t in tried.items() if t["status"] == "agree"
          and t["share"] >= max(AGREE_FLOOR, CONVENTION_GAIN * given_best)}
    found = max(ok, key=lambda n: ok[n]["share"]) if ok else None
    said = None if found is None else (f"the views' depths agree with their poses ({ok[found]['share']:.1%} of the "
                                       f"points, against at best {given_best:.1%} as read)")
    return {"tried": tried, "found": found, "said": said}


def convention_check(samples, cameras, cfg: AgreementConfig, given_best: float) -> dict:
    """The poses read in each other convention (capture.camera.misread_poses), the samples kept (they are in their
    cameras' frames), through :func:`_readings`: status ``convention`` with the one named, or ``as read``."""
    readings = {name: ([replace(c, cam_from_world=invert_rigid(misread_poses(c.world_from_cam)[name]))
                        for c in cameras], samples) for name in CONVENTION_HINTS}
    r = _readings(samples, cameras, cfg, given_best, readings)
    name = r["found"]
    if name is None:
        return {"status": "as read", "tried": r["tried"]}
    return {"status": "convention", "convention": name, "tried": r["tried"],
            "message": f"{r['said']} once the poses are {CONVENTION_HINTS[name]}"}


def _reprojected(sample, K_old: np.ndarray, K_new: np.ndarray):
    """A view's :func:`view_sample` with its points back-projected through ``K_new`` from the pixels ``K_old``
    had put them at (the depth map as it is)."""
    pts, small, step = sample
    if not len(pts):
        return sample
    z = pts[:, 2:3]
    uv1 = (pts / z) @ K_old.T
    return (uv1 @ np.linalg.inv(K_new).T) * z, small, step


def intrinsics_check(samples, cameras, cfg: AgreementConfig, given_best: float) -> dict:
    """The intrinsics read in the common wrong ways (capture.camera.misread_intrinsics: those of another image
    size; the principal point elsewhere than the image's centre), each view's points back-projected again, through
    :func:`_readings`: status ``intrinsics`` with the one named and its factor (``image size``: the median of the
    views'), or ``as read``."""
    alt = [misread_intrinsics(c) for c in cameras]
    readings = {}
    for name in INTRINSICS_HINTS:
        if all(name in a for a in alt):
            readings[name] = ([replace(c, K=a[name]) for c, a in zip(cameras, alt)],
                              [_reprojected(x, c.K, a[name]) for x, c, a in zip(samples, cameras, alt)])
    r = _readings(samples, cameras, cfg, given_best, readings)
    name = r["found"]
    if name is None:
        return {"status": "as read", "tried": r["tried"]}
    k = float(np.median([a[name][0, 0] / c.K[0, 0] for c, a in zip(cameras, alt)]))
    return {"status": "intrinsics", "intrinsics": name, "factor": round(k, 4), "tried": r["tried"],
            "message": f"{r['said']} " + INTRINSICS_HINTS[name].format(k=k, inv=1 / k)}


def units_check(samples, cameras, cfg: AgreementConfig, given_best: float) -> dict:
    """Every view's depth times each of :data:`UNIT_FACTORS` (its points and its depth map), through
    :func:`_readings`: status ``units`` with the factor that makes the depths agree with the poses, or ``as
    read``."""
    readings = {f"x{k:g}": (cameras, [(p * k, small * np.float32(k), step) for p, small, step in samples])
                for k in UNIT_FACTORS}
    r = _readings(samples, cameras, cfg, given_best, readings)
    name = r["found"]
    if name is None:
        return {"status": "as read", "tried": r["tried"]}
    k = float(name[1:])
    return {"status": "units", "factor": k, "tried": r["tried"], "message": (
        f"{r['said']} with every depth times {k:g}: is the depth's unit {k:g} times what the capture says "
        f"(depth_unit_scale_factor x {k:g}), or are the poses' translations in other units (x {1 / k:g})?")}

"""Placing every view under the turntable prior from all the evidence at once (issue 16).

Unknowns: the turntable axis (4 numbers) and one angle per view (``turntable.Turntable``).
Evidence, per ordered pair of views less than ``pair_max_deg`` apart, each a Gauss-Newton
system in the pair's relative twist chained to the unknowns (``Turntable.pair_jacobian``):

* ``geometry``: projective point-to-plane of the range images (``projective``), residuals in
  units of the measured depth noise;
* ``colour``: the photometric (chromaticity) term of the same association;
* ``silhouette``: outline points inside the other view's silhouette (``evidence``), pixels; it
  informs the axis only, from nearly opposite views (``SILHOUETTE_OPPOSITE_DEG``), and is off by
  default (measured to tilt the axis); silhouettes always check the result (a foreign object's
  outline falls outside its neighbours');
* ``features``: SIFT matches lifted by depth, reprojection pixels (Cauchy-weighted).

Each pair's evidence counts only where it agrees with itself at the current poses (enough
surface correspondences, a small chromaticity residual, mostly inlying features).  The sum is
solved by damped Gauss-Newton over coarse-to-fine depth gates, the chromaticity blurred at
the coarse ones (``COLOR_BLUR_PX``), with the axis prior and (issue 31) the angle prior and bound
of the input (``turntable.AnglePrior``: every step clamped).  Then, per view: which evidence
carries its angle (share of the information on it), with what residual, and the angle's
standard deviation from the inverse information.  The orchestration (views that contradict
their neighbours' silhouettes taken out, the angle hypotheses of each view) is in
``turntable_place``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from capture.registration import evidence as EV
from capture.registration import icp as ICP
from capture.registration import points as P
from capture.registration import projective as PR
from capture.registration import report as R
from capture.registration.turntable import AnglePrior, AxisPrior, Turntable, opposite_pairs, ring_pairs

EVIDENCE = ("geometry", "colour", "silhouette", "features")
#: The evidence a turntable solve uses by default (see ``SILHOUETTE_OPPOSITE_DEG``).
DEFAULT_EVIDENCE = ("geometry", "colour", "features")
#: Silhouette residuals are in units of this many pixels.
SILHOUETTE_SIGMA_PX = 1.0
#: Feature residuals are in units of this many pixels.
FEATURE_SIGMA_PX = 1.0
#: The surface residual's unit is the measured depth noise, but at least this fraction of the
#: object size (noise-free synthetic depth would otherwise drown every other evidence).
GEOMETRY_SIGMA_FLOOR_FRAC = 2e-4
#: Silhouettes inform the axis, not the angles: a body turning about the axis moves its outline
#: points in depth, not across the image (to first order), so the one-sided silhouette term
#: only biases the angles (fur ball from the true poses, alone: 1.8 degrees median drift).
SILHOUETTE_AXIS_ONLY = True
#: ... and only between views this close to opposite (degrees from 180): there the outlines are
#: one rim seen from both sides, and an axis tilt moves them apart.  Even so silhouettes are not
#: in the default evidence (``DEFAULT_EVIDENCE``): 36 views at 640x480, millimetre depth, 5
#: degrees, median error with near-view silhouettes / opposite-view silhouettes / none: plant
#: 0.106 / 0.191 / 0.067 degrees, fur ball 0.336 / 0.275 / 0.268 (nearly all of it the axis
#: tilt).  They remain the consistency check that flags a foreign object.
SILHOUETTE_OPPOSITE_DEG = 20.0
#: Chromaticity blur (pixels at 640 across) of the photometric term at each gate, coarse to
#: fine: the colour pattern's basin of convergence widens with the blur.
COLOR_BLUR_PX = (8.0, 4.0, 2.0, 0.0)
#: A pair's evidence counts only where it agrees with itself at the current poses: the surface
#: where at least ``report.MIN_FITNESS`` of the samples find a correspondence within the gate
#: (fur: 0.06-0.12 at the finest gate, the plant 0.63), colour where its RMS chromaticity
#: difference is below ``report.MAX_COLOR_RMSE``, features where at least this fraction of the
#: matches are inliers (fur: 10 % at the true poses, with a 3.5 degree bias alone) ...
MIN_FEATURE_INLIER_FRAC = 0.5
#: ... and at least this many.
MIN_FEATURE_INLIERS = 6
#: ... and colour where its RMS chromaticity difference is below this (looser than a free pair's
#: ``report.MAX_COLOR_RMSE``: here the ring holds the pair).  Fur's chromaticity residual at the
#: solution is 0.087-0.095 (strands do not repeat between views): with 0.08 the synthetic fur ball
#: (24 views, 320x240, 2 degrees input) placed 7/24 views, with 0.12 24/24 at 0.32 median / 0.48
#: max degrees.  What it lets through wrongly, the independent check (``verify``) catches.
TURNTABLE_MAX_COLOR_RMSE = 0.12
#: Largest angle change of one Gauss-Newton step (degrees); larger steps are scaled down.
MAX_STEP_DEG = 2.0
#: Stop a gate when no angle moves by more than this (degrees).
CONVERGED_DEG = 2e-3
#: A view is placed only when its angle's standard deviation is below this (degrees).
MAX_ANGLE_SIGMA_DEG = 0.5
#: An outline point further than this (pixels) outside a neighbour's silhouette is outside ...
SILHOUETTE_OUTSIDE_PX = 3.0
#: ... and a view with more than this fraction of its outline points outside contradicts its
#: neighbours' silhouettes (a foreign object, a wrong pose).
MAX_SILHOUETTE_OUTSIDE_FRAC = 0.1
#: A feature match within this many pixels at the solution is an inlier.
FEATURE_INLIER_PX = 3.0
#: An evidence is named as placing a view when it holds at least this share of the information
#: on the view's angle.
EVIDENCE_SHARE_MIN = 0.1
#: Most views taken out as contradicting before giving up.
MAX_REMOVALS = 8
#: When the range surface holds less than this share of the information on the axis (fur: none),
#: opposite views' silhouettes join the solve for the axis (with the axis prior): curly fur ball,
#: 36 views, 320x240, 2 degrees input: 0.40 / 0.69 -> 0.33 / 0.64 degrees median / max.  Where the
#: surface does inform the axis (plant) they stay out (``SILHOUETTE_OPPOSITE_DEG``).
GEOMETRY_AXIS_SHARE_MIN = 0.05
#: The evidence may move the axis this many sigmas of the nominal ring's axis (``AxisPrior``);
#: further, it disagrees with the ring and the axis is held at the ring's.
AXIS_AGREE_SIGMAS = 3.0


@dataclass(frozen=True)
class TurntableConfig:
    """Knobs of the turntable solver."""

    gates: tuple[float, ...] = (1 / 10, 1 / 25, 1 / 50, 1 / 150)
    """Depth gates of the surface association, coarse to fine (fractions of object size)."""
    iterations: int = 10
    """Gauss-Newton iterations per gate ..."""
    final_iterations: int = 40
    """Gauss-Newton iterations of the angles alone (the axis held) after the finest gate, where the
    chain of angles converges slowly: each iteration re-associates the pixels, so the convergence
    is linear (issue 31: the furry bunny at 5 degrees, 640x480: 0.31 / 0.57 degrees median / max
    after the gates, 0.15 / 0.29 after 10 more, 0.11 / 0.23 after 20, 0.10 / 0.22 after 30; with
    the axis free as well it tilted until no view could be better than 0.10).  ``CONVERGED_DEG``
    stops it earlier."""
    pair_max_deg: float = 40.0
    """Views closer than this about the axis form pairs."""
    geometry_samples: int = 6000
    """Source samples of the surface term per view."""
    silhouette_samples: int = 800
    """Outline points per view."""
    evidence: tuple[str, ...] = DEFAULT_EVIDENCE
    """Evidence used to place the views (a subset of ``EVIDENCE``); silhouettes always check them."""
    cloud: P.CloudConfig = field(default_factory=P.CloudConfig)
    """Range-image preparation (``projective.depth_frame``)."""
    color_scale_frac: float = ICP.IcpConfig.color_scale_frac
    """Photometric scale on noise-free depth (see ``icp.color_scale``)."""
    max_color_rmse: float = TURNTABLE_MAX_COLOR_RMSE
    """A pair's colour counts only where its RMS chromaticity difference is below this."""
    axis_prior: bool = True
    """Hold the axis near the nominal ring's (``AXIS_PRIOR_FLOOR_DEG``) instead of leaving it to the evidence."""


@dataclass
class ViewData:
    """One view's evidence inputs."""

    frames: list[PR.DepthFrame]
    """The range frame with its chromaticity blurred for each gate (``COLOR_BLUR_PX``)."""
    samples: list[PR.Samples]
    silhouette: EV.Silhouette
    features: EV.Features | None

    @property
    def frame(self) -> PR.DepthFrame:
        return self.frames[-1]


def blurred(frame: PR.DepthFrame, sigma_px: float) -> PR.DepthFrame:
    """The frame with its chromaticity (and gradient) blurred by a Gaussian of ``sigma_px``."""
    from scipy.ndimage import gaussian_filter

    if sigma_px <= 0:
        return frame
    lum = gaussian_filter(frame.intensity, sigma_px)
    gv, gu = np.gradient(lum)
    return replace(frame, intensity=lum, grad=np.stack([gu, gv], axis=-1))


def prepare_view(scan, cfg: TurntableConfig) -> ViewData:
    frame = PR.depth_frame(scan, cfg.cloud)
    stride = max(1, int(round(math.sqrt(frame.valid.sum() / max(cfg.geometry_samples, 1)))))
    mask = EV.silhouette_mask(scan)
    sil = EV.silhouette(scan, mask, frame.points, frame.valid, cfg.silhouette_samples)
    feats = EV.features(scan, mask, np.asarray(scan.depth)) if "features" in cfg.evidence else None
    blur = [COLOR_BLUR_PX[min(k, len(COLOR_BLUR_PX) - 1)] * scan.camera.width / 640 for k in range(len(cfg.gates))]
    frames = [blurred(frame, b) for b in blur[:-1]] + [frame]
    return ViewData(frames, [PR.source_samples(f, stride) for f in frames], sil, feats)


@dataclass(frozen=True)
class PairSet:
    """The ordered (target, source) pairs of the solve: ``near`` ones carry the surface, colour and
    features (they overlap), ``opposite`` ones the silhouettes (``SILHOUETTE_OPPOSITE_DEG``)."""

    near: list
    opposite: list


def pair_set(model: Turntable, active: list[int], cfg: TurntableConfig) -> PairSet:
    return PairSet(ring_pairs(model, active, cfg.pair_max_deg), opposite_pairs(model, active, SILHOUETTE_OPPOSITE_DEG))


def _geometry_sigma(vi: ViewData, vj: ViewData, size: float) -> float:
    return max(vi.frame.depth_sigma_m, vj.frame.depth_sigma_m, GEOMETRY_SIGMA_FLOOR_FRAC * size)


def _pair_systems(views, matches, i, j, T, level, gate, cfg, size, opposite=False) -> dict:
    """Per evidence: (A 6x6, b 6) of the ordered pair (target i, source j) at ``T``, for the
    evidence that agrees with itself there (see ``MIN_FEATURE_INLIER_FRAC``): the silhouette
    alone for ``opposite`` pairs, the rest for near ones."""
    vi, vj = views[i], views[j]
    fi, sj = vi.frames[level], vj.samples[level]
    out = {}
    if opposite:
        if "silhouette" in cfg.evidence:
            A, b, _ = EV.silhouette_equations(vj.silhouette, vi.silhouette, vi.frame.camera, T, SILHOUETTE_SIGMA_PX)
            out["silhouette"] = (A, b)
        return out
    if "geometry" in cfg.evidence or "colour" in cfg.evidence:
        cs = ICP.color_scale(ICP.IcpConfig(color_scale_frac=cfg.color_scale_frac), size, vi.frame, vj.frame) \
            if "colour" in cfg.evidence else 0.0
        parts = PR.normal_equation_parts(sj, fi, T, gate, cs)
        s2 = _geometry_sigma(vi, vj, size) ** 2
        if parts is not None:
            (A, b), (Ac, bc), n, crmse = parts
            if "geometry" in cfg.evidence and n >= R.MIN_FITNESS * len(sj.points):
                out["geometry"] = (A / s2, b / s2)
            if cs > 0 and crmse <= cfg.max_color_rmse:
                out["colour"] = (Ac / s2, bc / s2)
    if "features" in cfg.evidence:
        m = matches.get((i, j))
        if m is not None and len(m):
            A, b, r = EV.feature_equations(vj.features.points[m[:, 1]], vi.features.pixels[m[:, 0]],
                                           vi.frame.camera, T, FEATURE_SIGMA_PX)
            z = max(float(np.median(vj.samples[-1].points[:, 2])), 1e-6) if len(vj.samples[-1].points) else 1.0
            tol = max(FEATURE_INLIER_PX, gate * vi.frame.camera.K[0, 0] / z)
            inl = int(np.sum(r < tol))
            if inl >= MIN_FEATURE_INLIERS and inl >= MIN_FEATURE_INLIER_FRAC * len(r):
                out["features"] = (A, b)
    return out


def _chain(model: Turntable, i: int, j: int, size: float) -> np.ndarray:
    """(6, 4 + N) d twist(cam_i_from_cam_j) / d (axis 4, angles N)."""
    J5 = model.pair_jacobian(i, j, size)
    J = np.zeros((6, 4 + len(model.angles)))
    J[:, :4] = J5[:, :4]
    J[:, 4 + j] += J5[:, 4]
    J[:, 4 + i] -= J5[:, 4]
    return J


def build_system(model, views, matches, pairs: PairSet, level, cfg, size) -> dict:
    """Per evidence: (H (4+N)^2, g (4+N)) summed over the pairs at the model's poses, at gate
    number ``level`` of ``cfg.gates``."""
    n = 4 + len(model.angles)
    acc = {e: (np.zeros((n, n)), np.zeros(n)) for e in EVIDENCE}
    tagged = [(i, j, False) for i, j in pairs.near] + [(i, j, True) for i, j in pairs.opposite]
    for i, j, opposite in tagged:
        systems = _pair_systems(views, matches, i, j, model.relative(i, j), level, cfg.gates[level] * size, cfg,
                                size, opposite)
        if not systems:
            continue
        J = _chain(model, i, j, size)
        for e, (A, b) in systems.items():
            Je = J
            if e == "silhouette" and SILHOUETTE_AXIS_ONLY:
                Je = J.copy()
                Je[:, 4:] = 0.0
            H, g = acc[e]
            H += Je.T @ A @ Je
            g += Je.T @ b
    return acc


def _system(acc: dict, model, prior: AxisPrior | None, size: float,
            angle_prior: AnglePrior | None = None) -> tuple[np.ndarray, np.ndarray]:
    H = sum(acc[e][0] for e in EVIDENCE).copy()
    g = sum(acc[e][1] for e in EVIDENCE).copy()
    if prior is not None:
        W, b = prior.system(model, size)
        H[:4, :4] += W
        g[:4] += b
    if angle_prior is not None:
        h, b = angle_prior.system(model)
        H[4:, 4:] += np.diag(h)
        g[4:] += b
    return H, g


def _angle_columns(model, active, angle_prior) -> list[int]:
    """The free angle parameters: every active view's, less the reference's without an angle prior
    (then it is the gauge; with one, the prior fixes the common shift)."""
    return [4 + k for k in active if angle_prior is not None or k != model.reference]


def solve_gate(model, views, matches, pairs, free, level, cfg, size, prior: AxisPrior | None = None,
               angle_prior: AnglePrior | None = None, iterations: int | None = None) -> Turntable:
    """Damped Gauss-Newton at gate number ``level`` over the ``free`` parameters (``iterations``, or
    ``cfg.iterations``); with an ``angle_prior`` every step is clamped to its bound (a bounded search)."""
    active = [c - 4 for c in free if c >= 4]
    for _ in range(cfg.iterations if iterations is None else iterations):
        acc = build_system(model, views, matches, pairs, level, cfg, size)
        H, g = _system(acc, model, prior, size, angle_prior)
        H, g = H[np.ix_(free, free)], g[free]
        x = PR.solve_damped(H, g)
        if x is None:
            break
        ang = np.abs(x[4:]) if len(free) > 4 else np.zeros(1)
        big = np.degrees(max(ang.max(initial=0.0), np.abs(x[:2]).max()))
        if big > MAX_STEP_DEG:
            x = x * MAX_STEP_DEG / big
        dx = np.zeros(4 + len(model.angles))
        dx[free] = x
        model = model.updated(dx, size)
        if angle_prior is not None:
            model = angle_prior.clamp(model, active)
        if np.degrees(np.abs(x).max()) < CONVERGED_DEG:
            break
    return model


def refine_angles(model, views, matches, pairs, active, cfg, size, prior=None, angle_prior=None) -> Turntable:
    """The angles alone at the finest gate, ``cfg.final_iterations`` more (the axis held)."""
    angles = _angle_columns(model, active, angle_prior)
    return solve_gate(model, views, matches, pairs, angles, len(cfg.gates) - 1, cfg, size, prior, angle_prior,
                      cfg.final_iterations)


@dataclass
class ViewRecord:
    """How one view was (or was not) placed."""

    placed: bool
    evidence: list[str]
    """The evidence holding at least ``EVIDENCE_SHARE_MIN`` of the information on its angle."""
    sigma_deg: float
    """Standard deviation of its angle (degrees) from the inverse information."""
    residuals: dict
    """Per evidence: its residual figures against its neighbours."""
    reason: str = ""
    angle: dict = field(default_factory=dict)
    """Where its angle comes from (``angles.AngleDecision.to_json``): the evidence or its input."""


def _view_residuals(model, views, matches, pairs, k, gate, size) -> dict:
    """Residual figures of view k as the source of its pairs (at the finest gate)."""
    fit, rmse, crmse, outside, feat = [], [], [], [], []
    for i, j in pairs.near:
        if j != k:
            continue
        T = model.relative(i, j)
        f, r, _, c = PR.alignment_stats(views[j].samples[-1], views[i].frame, T, gate * size)
        fit.append(f)
        rmse.append(r)
        crmse.append(c)
        _, _, d = EV.silhouette_equations(views[j].silhouette, views[i].silhouette, views[i].frame.camera, T, 1.0)
        outside.append(d)
        m = matches.get((i, j))
        if m is not None and len(m):
            feat.append(EV.feature_equations(views[j].features.points[m[:, 1]], views[i].features.pixels[m[:, 0]],
                                             views[i].frame.camera, T, 1.0)[2])
    out = {}
    if fit:
        out["geometry"] = {"fitness": float(np.median(fit)), "rmse_m": float(np.median(rmse))}
        c = [x for x in crmse if math.isfinite(x)]
        if c:
            out["colour"] = {"chroma_rmse": float(np.median(c))}
    if outside:
        d = np.concatenate(outside)
        out["silhouette"] = {"outside_frac": float(np.mean(d > SILHOUETTE_OUTSIDE_PX)) if len(d) else 1.0,
                             "rms_px": float(np.sqrt(np.mean(np.minimum(d, EV.SILHOUETTE_CLIP_PX) ** 2)))
                                       if len(d) else 0.0}
    if feat:
        r = np.concatenate(feat)
        inl = r[r < FEATURE_INLIER_PX]
        out["features"] = {"inliers": int(len(inl)), "matches": int(len(r)),
                           "rms_px": float(np.sqrt(np.mean(inl**2))) if len(inl) else float("nan")}
    return out


def evaluate(model, views, matches, pairs, active, cfg, size, prior: AxisPrior | None = None,
             axis_fixed: bool = False, angle_prior: AnglePrior | None = None) -> tuple[list[ViewRecord], dict]:
    """Per view: evidence shares, angle sigma, residuals, placement (inactive views: not placed);
    and the evidence shares of the information on the axis."""
    gate = cfg.gates[-1]
    acc = build_system(model, views, matches, pairs, len(cfg.gates) - 1, cfg, size)
    axis = {e: float(np.trace(acc[e][0][:4, :4])) for e in EVIDENCE}
    total_axis = sum(axis.values())
    axis = {e: v / total_axis for e, v in axis.items() if total_axis > 0 and v > 0}
    # the angles' standard deviations relative to the reference view's (the common shift is the
    # gauge: with an angle prior only the prior holds it, and it says nothing about the evidence)
    free = ([] if axis_fixed else [0, 1, 2, 3]) + _angle_columns(model, active, None)
    H = _system(acc, model, prior, size, angle_prior)[0][np.ix_(free, free)]
    try:  # nothing free (the axis fixed, no angle to solve): no covariance, and no 0 / 0 warning
        cov = np.linalg.inv(H + PR.DAMPING * np.trace(H) / len(H) * np.eye(len(H))) if len(H) else H
    except np.linalg.LinAlgError:
        cov = np.full(H.shape, np.inf)
    records = []
    for k in range(len(model.angles)):
        if k not in active:
            records.append(ViewRecord(False, [], float("nan"), {}, "left out"))
            continue
        info = {e: float(acc[e][0][4 + k, 4 + k]) for e in EVIDENCE}
        total = sum(info.values())
        ev = [e for e in EVIDENCE if total > 0 and info[e] / total >= EVIDENCE_SHARE_MIN]
        c = free.index(4 + k) if 4 + k in free else None
        sigma = 0.0 if c is None else float(np.degrees(np.sqrt(max(cov[c, c], 0.0))))
        res = _view_residuals(model, views, matches, pairs, k, gate, size)
        for e in res:
            res[e]["information_share"] = info.get(e, 0.0) / total if total > 0 else 0.0
        sil = res.get("silhouette", {}).get("outside_frac", 0.0)
        reason = ""
        if sil > MAX_SILHOUETTE_OUTSIDE_FRAC:
            reason = f"{sil:.0%} of its outline falls outside its neighbours' silhouettes"
        elif not ev:
            reason = "no evidence about its angle"
        elif sigma > MAX_ANGLE_SIGMA_DEG:
            reason = f"its angle is not determined (sigma {sigma:.2f} degrees)"
        records.append(ViewRecord(not reason, ev, sigma, res, reason))
    return records, axis

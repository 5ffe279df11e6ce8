"""Placing the views of a turntable (issues 16, 22, 31): the joint solve (``turntable_solve``)
bounded by the input (``prior``), then each view's angle judged against its input angle and the
other angles that fit as well (``angles``).

1. The joint solve over the axis and every angle, coarse to fine, with the axis prior of the
   nominal ring and (issue 31) an angle prior: a Gaussian about each input angle whose every step
   is clamped to the input's stated bound (``turntable.AnglePrior``).  Views whose outline falls
   outside their neighbours' silhouettes are taken out one at a time (a foreign object).
2. Per view, the angle hypotheses (``angles.decide``): the evidence places the view only when its
   angle is the one clear answer within the bound and beats the input angle by a margin
   calibrated on the capture's noise; else the view keeps its input angle (on the fitted ring).
3. The views that keep their input angle are taken out of the evidence (it was not to be
   trusted) and the rest solved again, until no view changes (``HYPOTHESIS_ROUNDS``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from capture.registration import angles as AN
from capture.registration import evidence as EV
from capture.registration import turntable_solve as TS
from capture.registration.turntable import AnglePrior, Turntable, axis_prior

#: Rounds of angle decisions and re-solves of the views whose evidence placed them.
HYPOTHESIS_ROUNDS = 3
#: The re-solve after a round runs the finest gates only (the views are near their answer).
RESOLVE_GATES = 2


@dataclass
class TurntableOutcome:
    """Result of :func:`solve_turntable`."""

    model: Turntable
    records: list[TS.ViewRecord]
    pairs: TS.PairSet
    axis_evidence: dict = field(default_factory=dict)
    """Share of the information on the axis (4 numbers) per evidence."""
    axis_note: str = ""
    """Why the axis was held at the nominal ring's (``AXIS_AGREE_SIGMAS``), if it was."""

    @property
    def placed(self) -> list[bool]:
        return [r.placed for r in self.records]


def _match_features(views, model, active, cfg) -> dict:
    matches = {}
    if "features" in cfg.evidence:
        for i, j in TS.pair_set(model, active, cfg).near:
            matches[(i, j)] = EV.match(views[i].features, views[j].features)
    return matches


def solve_turntable(scans, model: Turntable, off: dict, cfg: TS.TurntableConfig, size: float,
                    progress=None, axis_sigma_deg: float | None = None, pose_prior=None) -> TurntableOutcome:
    """Place the views of ``scans`` on the turntable ``model`` (views in ``off`` are left out).

    Args:
        scans: the scans (their own poses are not used: the model holds the initial angles).
        off: view index -> reason, for views that must not take part.
        progress: optional ``f(iterable, label)`` wrapper of the per-view preparation loop.
        axis_sigma_deg: the nominal ring's axis uncertainty (``TurntableFit.axis_sigma_deg``),
            for the axis prior (``cfg.axis_prior``).
        pose_prior: the input's stated uncertainty (``prior.PosePrior``): the angle prior and bound,
            and the angle hypotheses; None = a search unbounded by the input (``--init none``).
    """
    n = len(scans)
    idx = range(n)
    views = [TS.prepare_view(scans[k], cfg) for k in (progress(idx, "turntable evidence") if progress else idx)]
    active = [k for k in range(n) if k not in off]
    matches = _match_features(views, model, active, cfg)
    start = model
    prior = axis_prior(model, axis_sigma_deg) if cfg.axis_prior else None
    aprior = None if pose_prior is None else AnglePrior(np.array(model.angles, np.float64), pose_prior.sigma_rad,
                                                         math.radians(pose_prior.rot_deg))
    removed: dict = {}
    note = ""
    while True:
        model = _rereference(start, active)
        pairs = TS.pair_set(model, active, cfg)
        model, fixed, why = _solve_gates(model, views, matches, pairs, active, cfg, size, prior, aprior)
        note = why or note
        records, axis = TS.evaluate(model, views, matches, pairs, active, cfg, size, prior, fixed, aprior)
        bad = [k for k in active if records[k].residuals.get("silhouette", {}).get("outside_frac", 0.0)
               > TS.MAX_SILHOUETTE_OUTSIDE_FRAC]
        if not bad or len(removed) >= TS.MAX_REMOVALS or len(active) <= 3:
            break
        worst = max(bad, key=lambda k: records[k].residuals["silhouette"]["outside_frac"])
        removed[worst] = records[worst].reason
        active = [k for k in active if k != worst]
    no_axis = axis.get("geometry", 0.0) < TS.GEOMETRY_AXIS_SHARE_MIN
    if prior is not None and "silhouette" not in cfg.evidence and no_axis:
        cfg = replace(cfg, evidence=(*cfg.evidence, "silhouette"))
        model, fixed, why = _solve_gates(model, views, matches, pairs, active, cfg, size, prior, aprior)
        records, axis = TS.evaluate(model, views, matches, pairs, active, cfg, size, prior, fixed, aprior)
        note = "; ".join(x for x in (note, why, "the range surface gave the axis nothing (fur): opposite views' "
                                     "silhouettes were added for the axis") if x)
    if aprior is None or not _drifted(model, active, aprior):  # a drifted solve is not worth refining
        model = TS.refine_angles(model, views, matches, pairs, active, cfg, size, prior, aprior)
        records, axis = TS.evaluate(model, views, matches, pairs, active, cfg, size, prior, fixed, aprior)
    if aprior is not None:
        model, records, pairs = _hypotheses(model, views, matches, active, cfg, size, prior, aprior, pose_prior,
                                            records, fixed)
    for k, why in {**off, **removed}.items():
        records[k] = TS.ViewRecord(False, [], float("nan"), records[k].residuals if k in removed else {}, why)
    return TurntableOutcome(model, records, pairs, axis, note)


def _decide_all(model, views, matches, trusted, cfg, size, aprior, bound_deg) -> dict:
    """View -> ``angles.AngleDecision`` for every ``trusted`` view, the others fixed."""
    step = 360.0 / max(len(trusted), 1)
    win = AN.window(bound_deg, step)
    gate = cfg.gates[max(len(cfg.gates) - 2, 0)] * size
    off = aprior.offsets(model, trusted)
    out = {}
    for k in trusted:
        nb = AN.neighbours(model, trusted, k)
        if not nb:
            out[k] = AN.AngleDecision(AN.INPUT, 0.0, "no neighbour to compare with")
            continue
        sigma = max([TS._geometry_sigma(views[k], views[j], size) for j in nb])
        prof = AN.Profile(model, views, matches, k, nb, gate, sigma)
        out[k] = AN.decide(prof, math.degrees(off[k]), bound_deg, win, math.degrees(aprior.sigma))
    return out


def _drifted(model, trusted: list[int], aprior: AnglePrior) -> str:
    """Why the solve's angles are not to be trusted at all (``angles.drift``), or ""."""
    off = np.degrees(aprior.offsets(model, trusted))
    order = sorted(trusted, key=lambda k: model.angles[k] % (2 * math.pi))
    sigma = math.degrees(aprior.sigma)
    z, run, mean = AN.drift(off, order, sigma)
    if z <= AN.T_DRIFT:
        return ""
    return (f"the evidence moved a run of {len(run)} neighbouring views together by {mean:+.2f} deg from their input "
            f"angles ({z:.1f} standard errors of independent input errors of {sigma:.2f} deg, > {AN.T_DRIFT:g}): it is "
            "biased (a group that agrees with itself), so every view keeps its input angle")


def _hypotheses(model, views, matches, active, cfg, size, prior, aprior, pose_prior, records, fixed):
    """Steps 2-3 of the module docstring: (model, records, pairs)."""
    trusted = list(active)
    decisions: dict = {}
    pairs = TS.pair_set(model, trusted, cfg)
    for _ in range(HYPOTHESIS_ROUNDS):
        drifted = _drifted(model, trusted, aprior)
        if drifted:
            decisions.update({k: AN.AngleDecision(AN.INPUT, 0.0, drifted) for k in trusted})
            trusted = []
            break
        dec = _decide_all(model, views, matches, trusted, cfg, size, aprior, pose_prior.rot_deg)
        decisions.update(dec)
        untrusted = [k for k in trusted if dec[k].source == AN.INPUT]
        shift = aprior.shift(model, trusted)
        moved = False
        ang = model.angles.copy()
        for k in trusted:
            if dec[k].source == AN.EVIDENCE:
                target = aprior.centre[k] + shift + math.radians(dec[k].offset_deg)
                moved |= abs(target - ang[k]) > math.radians(AN.SAME_DEG) / 4
                ang[k] = target
        model = replace(model, angles=ang)
        if not untrusted and not moved:
            break
        trusted = [k for k in trusted if k not in untrusted]
        if len(trusted) < 3:
            break
        model = _rereference(model, trusted)
        pairs = TS.pair_set(model, trusted, cfg)
        angle_cols = TS._angle_columns(model, trusted, aprior)
        free = ([] if fixed else [0, 1, 2, 3]) + angle_cols
        for level in range(max(len(cfg.gates) - RESOLVE_GATES, 0), len(cfg.gates)):
            model = TS.solve_gate(model, views, matches, pairs, free, level, cfg, size, prior, aprior)
        model = TS.refine_angles(model, views, matches, pairs, trusted, cfg, size, prior, aprior)
    trusted = [k for k in trusted if decisions[k].source == AN.EVIDENCE]
    shift = aprior.shift(model, trusted) if trusted else 0.0
    ang = model.angles.copy()
    for k in active:
        if k not in trusted:
            ang[k] = aprior.centre[k] + shift
    model = replace(model, angles=ang)
    if trusted:
        model = _rereference(model, trusted)
        pairs = TS.pair_set(model, trusted, cfg)
        records, _ = TS.evaluate(model, views, matches, pairs, trusted, cfg, size, prior, fixed, aprior)
    every = TS.pair_set(model, active, cfg)
    for k in active:
        d = decisions[k]
        if k in trusted:
            records[k].placed, records[k].reason = True, ""
        else:
            res = TS._view_residuals(model, views, matches, every, k, cfg.gates[-1], size)
            records[k] = TS.ViewRecord(True, ["input angle"], float("nan"), res, d.reason)
        records[k].angle = d.to_json()
    return model, records, pairs


def _solve_gates(model, views, matches, pairs, active, cfg, size, prior, aprior=None) -> tuple[Turntable, bool, str]:
    """All gates, coarse to fine (``solve_turntable`` then refines the angles alone once,
    ``turntable_solve.refine_angles``): (model, axis held fixed?, why).  When the evidence moves the axis
    further from the nominal ring's than ``AXIS_AGREE_SIGMAS`` prior sigmas, it disagrees with
    the ring (fur: the coat's apparent surface moves with the viewpoint and tilts the axis), and
    the angles are solved again about the ring's axis."""
    start = model
    angles = TS._angle_columns(model, active, aprior)
    for level in range(len(cfg.gates)):
        model = TS.solve_gate(model, views, matches, pairs, [0, 1, 2, 3] + angles, level, cfg, size, prior, aprior)
    dev = prior.sigmas(model, size) if prior is not None else 0.0
    if dev <= TS.AXIS_AGREE_SIGMAS:
        return model, False, ""
    moved = prior.tilt_deg(model)
    model = start
    for level in range(len(cfg.gates)):
        model = TS.solve_gate(model, views, matches, pairs, angles, level, cfg, size, prior, aprior)
    return model, True, (f"the evidence tilted the axis by {moved:.2f} degrees ({dev:.0f} sigma of the nominal "
                         "ring's axis): the angles were solved about the ring's axis")


def _rereference(model: Turntable, active: list[int]) -> Turntable:
    """The model with an active reference view (the old one when still active)."""
    if model.reference in active:
        return model
    r = active[0]
    return replace(model, reference=r, reference_pose=model.pose(r))

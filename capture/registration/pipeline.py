"""One entry point: register a scan set by a named method and build the report.

``method``: ``icp`` (geometric, ``icp.py``), ``colmap`` (SfM on the colour images + Umeyama
into the depth frame, then checked/refined by ICP), ``board`` (ChArUco PnP, then ICP
refinement), ``auto`` (board when a board is seen in most images, else ICP; with
``init="none"`` and more than a third of the scans flagged, SfM initialisation is tried).

Bounded by the input (issue 31): with ``init="nominal"`` no view moves further from its input pose
than the input's stated uncertainty (``prior.PosePrior``, a default per rig), the solvers use it
as a prior and a bound, and the independent check (``verify``) keeps a registered pose only where
it explains the data significantly better than the input pose.  Every input view is in the
returned scan set: registered, kept at its input pose, or flagged (at its input pose), each with
its reason in the report.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from capture.camera import Camera, invert_rigid
from capture.registration import icp as ICP
from capture.registration import prior as PR
from capture.registration import report as R
from capture.scan import Scan, ScanSet

METHODS = ("auto", "icp", "colmap", "board")
#: ``auto`` uses the board when it is detected in at least this fraction of the images.
AUTO_BOARD_FRACTION = 0.5
#: ``auto`` falls back to SfM initialisation when more than this fraction of scans is flagged.
AUTO_SFM_FLAGGED_FRACTION = 1 / 3


def _with_poses(scanset: ScanSet, poses: list[np.ndarray]) -> ScanSet:
    scans = []
    for s, p in zip(scanset.scans, poses):
        cam = s.camera
        scans.append(Scan(s.rgb, s.depth, Camera(cam.K, p, cam.width, cam.height, cam.name), s.name))
    return ScanSet(tuple(scans), scanset.bounds, dict(scanset.metadata))


def _report_from_icp(scanset: ScanSet, out: ICP.IcpOutcome, method: str, init: str) -> R.RegistrationReport:
    names = [s.name or f"scan{k}" for k, s in enumerate(scanset.scans)]
    rep = R.RegistrationReport(method=method, init=init, gauge=names[out.gauge], object_size_m=scanset.size,
                               thresholds=R.thresholds())
    for p in out.pairs:
        res = out.residuals.get((p.i, p.j), (float("nan"), float("nan")))
        rep.pairs.append(R.PairRecord(names[p.j], names[p.i], p.method, p.status, p.fitness, p.rmse,
                                      p.correction_deg, res[0], res[1]))
    for k, nm in enumerate(names):
        mine = [p for p in out.pairs if k in (p.i, p.j)]
        ok = [p for p in mine if p.status == "ok"]
        rec = R.ScanRecord(nm, bool(out.registered[k]), pairs_ok=len(ok))
        if mine:
            best = max(mine, key=lambda p: p.fitness)
            rec.best_fitness, rec.best_inlier_rmse_m = best.fitness, best.rmse
        res = [out.residuals[(p.i, p.j)] for p in ok if (p.i, p.j) in out.residuals]
        if res:
            rec.max_residual_deg = max(r[0] for r in res)
            rec.max_residual_m = max(r[1] for r in res)
        if not rec.registered:
            statuses = sorted({p.status for p in mine}) or ["no pair"]
            rec.reason = ("no accepted pair connects it to the gauge scan; its pairs: " + ", ".join(statuses))
        rep.scans.append(rec)
    rep.seconds.update(out.seconds)
    return rep


RIGS = ("auto", "free", "turntable")


def _initial_poses(scanset, method, board, notes):
    """(initial cam_from_world per scan or None, board poses or None, method used) from the
    board or SfM for ``board``/``colmap``/``auto``."""
    if method in ("board", "auto"):
        from capture.registration import board as B

        bres = B.board_poses(scanset, board)
        seen = sum(p is not None for p in bres.poses)
        if method == "board" or seen >= AUTO_BOARD_FRACTION * len(scanset.scans):
            if seen == 0:
                raise RuntimeError("method 'board': no ChArUco board detected in any image")
            notes.append(f"board detected in {seen}/{len(scanset.scans)} images; "
                         f"median reprojection {bres.median_reprojection_px:.3f} px")
            return _fill(bres.poses, scanset), bres.poses, "board"
        return None, None, "icp"
    if method == "colmap":
        return _sfm_init(scanset, notes), None, "colmap"
    return None, None, method


def _fill(poses, scanset):
    return [p if p is not None else s.camera.cam_from_world for p, s in zip(poses, scanset.scans)]


def _sfm_init(scanset, notes):
    from capture.registration import colmap as C

    sfm = C.sfm_poses(scanset, use_init_for_gauge=True)
    notes.append(f"SfM registered {sum(p is not None for p in sfm.poses)}/{len(scanset.scans)} images, "
                 f"scale {sfm.scale:.5g}, mean reprojection {sfm.reprojection_px:.3f} px")
    return _fill(sfm.poses, scanset)


def _board_gauge(scanset, out: ICP.IcpOutcome, board_init, notes) -> tuple[ICP.IcpOutcome, set]:
    """The board fixes the gauge: the ICP solution moved onto the board frame; scans ICP could
    not connect keep their board pose (PnP on the board is independent of the surface)."""
    poses = R.fit_gauge(out.cam_from_world, board_init, out.registered)
    notes.append("gauge: least-squares fit to all board poses")
    by_board = [k for k, (r, b) in enumerate(zip(out.registered, board_init)) if not r and b is not None]
    registered = list(out.registered)
    for k in by_board:
        poses[k] = board_init[k]
        registered[k] = True
    if by_board:
        notes.append(f"{len(by_board)} scans posed by the board alone (ICP could not connect them): "
                     f"{[scanset.scans[k].name for k in by_board]}")
    return replace(out, cam_from_world=poses, registered=registered), set(by_board)


def _bounded(cfg: ICP.IcpConfig, prior, scanset: ScanSet, poses) -> ICP.IcpConfig:
    """``cfg`` with the pairs' correction bound from the prior (both views of a pair may be off by
    it; a turn about the camera moves the object centre by the turn times the distance)."""
    if prior is None:
        return cfg
    c = scanset.bounds.mean(axis=0)
    dist = float(np.median([np.linalg.norm(invert_rigid(p)[:3, 3] - c) for p in poses]))
    frac = 2 * (math.radians(prior.rot_deg) + prior.trans_frac) * dist / scanset.size
    return replace(cfg, correction_bound=(min(R.MAX_CORRECTION_DEG, 2 * prior.rot_deg),
                                          min(R.MAX_CORRECTION_FRAC, frac)))


def _register_free(scanset, method, init, cfg, board, notes, pose_prior=None):
    """The per-scan-pose registration (ICP / board / SfM + ICP): (outcome, method used, board-only
    scans, the prior in force or None, the poses it bounds the result about)."""
    use_init = init == "nominal"
    init_poses, board_init, used = _initial_poses(scanset, method, board, notes)
    if init_poses is not None:
        use_init = True
    ref = init_poses or [s.camera.cam_from_world for s in scanset.scans]
    prior = (pose_prior or PR.default_prior("free", used)) if use_init else None
    out = ICP.register_icp(scanset, _bounded(cfg, prior, scanset, ref), use_init=use_init, init_poses=init_poses)
    if method == "auto" and used == "icp" and not use_init and \
            sum(not r for r in out.registered) > AUTO_SFM_FLAGGED_FRACTION * len(scanset.scans):
        notes.append("too many scans flagged from global registration: retried from SfM poses")
        ref = _sfm_init(scanset, notes)
        prior = pose_prior or PR.default_prior("free", "colmap")
        out = ICP.register_icp(scanset, _bounded(cfg, prior, scanset, ref), use_init=True, init_poses=ref)
        used = "colmap"
    by_board: set = set()
    if used == "board" and board_init is not None:
        out, by_board = _board_gauge(scanset, out, board_init, notes)
    return out, used, by_board, prior, ref


def _free_evidence(rep: R.RegistrationReport, out: ICP.IcpOutcome, cfg: ICP.IcpConfig, used: str,
                   by_board: set) -> None:
    """Per scan: the evidence that placed it in the free rig, and its residual figures."""
    for k, rec in enumerate(rep.scans):
        if not rec.registered:
            continue
        if k in by_board:
            rec.evidence = ["board"]
            continue
        mine = [p for p in out.pairs if k in (p.i, p.j) and p.status == "ok"]
        rec.evidence = ["geometry"] + (["colour"] if cfg.color_scale_frac > 0 and
                                       any(math.isfinite(p.color_rmse) for p in mine) else [])
        if used == "board":
            rec.evidence.append("board")
        rec.residuals = {"geometry": {"fitness": rec.best_fitness, "rmse_m": rec.best_inlier_rmse_m,
                                      "edge_residual_deg": rec.max_residual_deg, "edge_residual_m": rec.max_residual_m}}
        c = [p.color_rmse for p in mine if math.isfinite(p.color_rmse)]
        if "colour" in rec.evidence:
            rec.residuals["colour"] = {"chroma_rmse": float(np.median(c))}


def _register_turntable(scanset, fit, tcfg, notes, progress=None, pose_prior=None):
    """Turntable rig: (cam_from_world per scan, placed flags, report)."""
    from capture.registration import turntable_place as TP
    from capture.registration import turntable_solve as TS

    t0 = time.perf_counter()
    tcfg = tcfg or TS.TurntableConfig()
    out = TP.solve_turntable(scanset.scans, fit.model, fit.off, tcfg, scanset.size, progress, fit.axis_sigma_deg,
                             pose_prior)
    placed = out.placed
    poses_in = [s.camera.cam_from_world for s in scanset.scans]
    model_poses = [out.model.pose(k) if placed[k] else None for k in range(len(placed))]
    fitted = R.fit_gauge([p if p is not None else np.eye(4) for p in model_poses], poses_in, placed)
    poses = [fitted[k] if placed[k] else poses_in[k] for k in range(len(placed))]
    names = [s.name or f"scan{k}" for k, s in enumerate(scanset.scans)]
    rep = R.RegistrationReport(method="turntable", init="nominal", gauge="least-squares fit to the nominal poses",
                               object_size_m=scanset.size, thresholds=R.thresholds(), rig="turntable",
                               rig_detection=fit.reason)
    for k, rec in enumerate(out.records):
        rep.scans.append(R.ScanRecord(names[k], rec.placed, reason=rec.reason, evidence=list(rec.evidence),
                                      residuals=rec.residuals, angle_sigma_deg=rec.sigma_deg, angle=rec.angle))
    by_evidence = sum(r.angle.get("source") == "evidence" for r in out.records)
    notes.append(f"turntable axis {np.round(out.model.axis, 4).tolist()} through "
                 f"{np.round(out.model.point, 4).tolist()}; {sum(placed)}/{len(placed)} views on the ring"
                 + (f", {by_evidence} at the angle their evidence gives, the others at their input angle"
                    if pose_prior is not None else ""))
    if out.axis_note:
        notes.append(out.axis_note)
    notes.append("axis placed by " + ", ".join(f"{e} {v:.0%}" for e, v in
                                               sorted(out.axis_evidence.items(), key=lambda x: -x[1])))
    rep.seconds["turntable"] = time.perf_counter() - t0
    return poses, placed, rep


def choose_rig(scanset: ScanSet, rig: str, method: str, init: str, board=None):
    """(turntable fit or None, rig to use) for ``rig`` = auto / free / turntable.  ``auto`` takes
    the turntable when the nominal poses describe one, the method is auto/icp from nominal poses,
    and (method auto) no ChArUco board is seen in most images (the board then places the scans)."""
    from capture.registration.turntable import fit_turntable

    if rig not in RIGS:
        raise ValueError(f"unknown rig {rig!r}; choose from {', '.join(RIGS)}")
    if rig == "free":
        return None, "free"
    fit = fit_turntable([s.camera.cam_from_world for s in scanset.scans])
    if rig == "turntable":
        if fit.model is None:
            raise ValueError(f"rig turntable: the nominal poses allow no turntable model ({fit.reason})")
        return fit, "turntable"
    auto_ok = init == "nominal" and method in ("auto", "icp") and fit.is_turntable
    if auto_ok and method == "auto":
        from capture.registration import board as B

        seen = sum(p is not None for p in B.board_poses(scanset, board).poses)
        if seen >= AUTO_BOARD_FRACTION * len(scanset.scans):
            return replace(fit, reason=f"{fit.reason}; a board is seen in {seen} images: free rig"), "free"
    return fit, "turntable" if auto_ok else "free"


def apply_bound(scanset: ScanSet, rep: R.RegistrationReport, poses: list[np.ndarray], registered: list[bool],
                prior, reference: list[np.ndarray]) -> tuple[list[np.ndarray], list[bool]]:
    """No view further from its input (``reference``) than the stated uncertainty: a registered pose
    beyond it is replaced by the input pose (the solvers are bounded too; this is the last word)."""
    centre = scanset.bounds.mean(axis=0)
    poses, kept = list(poses), list(registered)
    for k, rec in enumerate(rep.scans):
        if not registered[k]:
            continue
        ok, text = PR.within(prior, poses[k], reference[k], centre)
        rot, trans = PR.move(poses[k], reference[k], centre)
        rec.move = {"rot_deg": round(rot, 4), "trans_frac": round(trans, 5), "within": ok}
        if not ok:
            poses[k] = scanset.scans[k].camera.cam_from_world
            rec.status, rec.reason = KEPT, text + ": kept at its input pose"
            kept[k] = False
    return poses, kept


def apply_check(scanset: ScanSet, rep: R.RegistrationReport, poses: list[np.ndarray], registered: list[bool],
                progress=None) -> list[np.ndarray]:
    """The independent check (``verify``): per view its registered pose when that explains the data
    significantly better than its input pose, else its input pose; the records say which and why."""
    from capture.registration import check as C
    from capture.registration import verify as V

    t0 = time.perf_counter()
    idx = range(len(scanset.scans))
    views = [C.prepare(scanset.scans[k]) for k in (progress(idx, "independent check") if progress else idx)]
    nominal = [s.camera.cam_from_world for s in scanset.scans]
    ver = V.verify(views, nominal, poses, registered, scanset.bounds.mean(axis=0), scanset.size)
    for rec, v in zip(rep.scans, ver.verdicts):
        if v.status == V.FLAGGED:
            continue  # not placed (flagged, or kept by the bound): the status and reason stand
        rec.check = v.to_json()
        if v.status == V.KEPT and rec.status != KEPT:
            rec.status, rec.reason = KEPT, v.reason
        elif v.status == V.REGISTERED:
            rec.status = REGISTERED
    rep.check = {"improved": ver.improved, "t_better": V.T_BETTER,
                 **{s: sum(r.status == s for r in rep.scans) for s in (REGISTERED, KEPT, FLAGGED)}}
    rep.notes.extend(ver.notes)
    rep.seconds["check"] = time.perf_counter() - t0
    return ver.poses


REGISTERED, KEPT, FLAGGED = "registered", "kept at input", "flagged"


def _solve(scanset, method, init, cfg, board, rig, turntable_config, progress, pose_prior, notes):
    """The rig's solver: (poses, placed flags, report, prior in force, the poses it bounds about)."""
    fit, use = choose_rig(scanset, rig, method, init, board)
    inputs = [s.camera.cam_from_world for s in scanset.scans]
    if use == "turntable":
        prior = None if init == "none" else (pose_prior or PR.default_prior("turntable", method, fit))
        poses, placed, rep = _register_turntable(scanset, fit, turntable_config, notes, progress, prior)
        return poses, placed, rep, prior, inputs
    out, used, by_board, prior, ref = _register_free(scanset, method, init, cfg, board, notes, pose_prior)
    rep = _report_from_icp(scanset, out, used, init)
    _free_evidence(rep, out, cfg, used, by_board)
    if fit is not None:
        rep.rig_detection = fit.reason
    return out.cam_from_world, out.registered, rep, prior, ref


def register(scanset: ScanSet, method: str = "auto", init: str = "nominal", config: ICP.IcpConfig | None = None,
             board=None, rig: str = "free", turntable_config=None, progress=None, check: bool = True,
             pose_prior: PR.PosePrior | None = None) -> tuple[ScanSet, R.RegistrationReport, list[np.ndarray]]:
    """Register ``scanset``.

    Args:
        method: one of ``METHODS``. init: ``"nominal"`` (start from the input poses) or ``"none"``
            (a global search, unbounded by the input).
        board: a ``board.BoardSpec`` for ``board``/``auto`` (None = the default synthetic board).
        rig: ``free`` (a pose per scan), ``turntable`` (one axis, one angle per scan:
            ``turntable_place``) or ``auto`` (turntable when the nominal poses describe one and
            the method is auto/icp from nominal poses).
        check: keep a registered pose only where it explains the data significantly better than
            the input pose (``verify``; ``init="nominal"`` only).
        pose_prior: the input's stated uncertainty (``prior.PosePrior``); None = the rig's default.
    Returns:
        (scan set with every input view: registered, kept at or flagged at its input pose; report;
        cam_from_world per input scan).
    """
    if method not in METHODS:
        raise ValueError(f"unknown registration method {method!r}; choose from {', '.join(METHODS)}")
    if init not in ("nominal", "none"):
        raise ValueError(f"init must be 'nominal' or 'none', got {init!r}")
    cfg = config or ICP.IcpConfig()
    t0 = time.perf_counter()
    notes: list[str] = []
    poses, registered, rep, prior, ref = _solve(scanset, method, init, cfg, board, rig, turntable_config, progress,
                                                pose_prior, notes)
    rep.notes.extend(notes)
    for rec, r in zip(rep.scans, registered):
        rec.status = REGISTERED if r else FLAGGED
    if prior is not None:
        rep.pose_prior = prior.to_json()
        rep.notes.append(f"every move bounded by {prior.rot_deg:.2f} deg / {100 * prior.trans_frac:.2f} % "
                         f"({prior.source})")
        poses, registered = apply_bound(scanset, rep, poses, registered, prior, ref)
    if check and init == "nominal":
        poses = apply_check(scanset, rep, poses, registered, progress)
    for rec in rep.scans:
        rec.registered = rec.status == REGISTERED
    rep.seconds["total"] = time.perf_counter() - t0
    result = _with_poses(scanset, poses)
    result = replace(result, metadata={**scanset.metadata, "registration": {
        "method": rep.method, "init": init, "rig": rep.rig, "flagged": rep.flagged, "gauge": rep.gauge}})
    return result, rep, poses

"""One entry point: register a scan set by a named method and build the report.

``method``: ``icp`` (geometric, ``icp.py``), ``colmap`` (SfM on the colour images + Umeyama
into the depth frame, then checked/refined by ICP), ``board`` (ChArUco PnP, then ICP
refinement), ``auto`` (board when a board is seen in most images, else ICP; with
``init="none"`` and more than a third of the scans flagged, SfM initialisation is tried).

Flagged scans are left out of the returned scan set (not merged) unless ``keep_flagged``.
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from capture.camera import Camera
from capture.registration import icp as ICP
from capture.registration import report as R
from capture.scan import Scan, ScanSet

METHODS = ("auto", "icp", "colmap", "board")
#: ``auto`` uses the board when it is detected in at least this fraction of the images.
AUTO_BOARD_FRACTION = 0.5
#: ``auto`` falls back to SfM initialisation when more than this fraction of scans is flagged.
AUTO_SFM_FLAGGED_FRACTION = 1 / 3


def _with_poses(scanset: ScanSet, poses: list[np.ndarray], keep: list[bool]) -> ScanSet:
    scans = []
    for s, p, k in zip(scanset.scans, poses, keep):
        if not k:
            continue
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


def _fit_gauge(poses: list[np.ndarray], ref: list, mask: list[bool]) -> list[np.ndarray]:
    """Right-multiply ``poses`` (cam_from_world) by the rigid G that best maps them onto the
    reference poses where both exist (chordal mean of the rotations, mean of the translations)."""
    from capture.camera import invert_rigid

    Gs = [invert_rigid(p) @ r for p, r, m in zip(poses, ref, mask) if m and r is not None]
    if not Gs:
        return poses
    M = sum(G[:3, :3] for G in Gs)
    U, _, Vt = np.linalg.svd(M)
    Rm = U @ np.diag([1, 1, np.sign(np.linalg.det(U @ Vt))]) @ Vt
    G = np.eye(4)
    G[:3, :3] = Rm
    # translation: least squares over cameras of |R_k (R t_G) ... | -> mean of the G translations
    G[:3, 3] = np.mean([g[:3, 3] for g in Gs], axis=0)
    return [p @ G for p in poses]


def register(scanset: ScanSet, method: str = "auto", init: str = "nominal", config: ICP.IcpConfig | None = None,
             keep_flagged: bool = False, board=None) -> tuple[ScanSet, R.RegistrationReport, list[np.ndarray]]:
    """Register ``scanset``.

    Args:
        method: one of ``METHODS``. init: ``"nominal"`` (start from the input poses) or ``"none"``.
        board: a ``board.BoardSpec`` for ``board``/``auto`` (None = the default synthetic board).
    Returns:
        (registered scan set (flagged scans left out unless ``keep_flagged``), report,
        cam_from_world per input scan (flagged scans keep their input pose)).
    """
    if method not in METHODS:
        raise ValueError(f"unknown registration method {method!r}; choose from {', '.join(METHODS)}")
    if init not in ("nominal", "none"):
        raise ValueError(f"init must be 'nominal' or 'none', got {init!r}")
    cfg = config or ICP.IcpConfig()
    t0 = time.perf_counter()
    notes: list[str] = []
    init_poses = None
    board_init = None
    use_init = init == "nominal"
    used = method
    if method in ("board", "auto"):
        from capture.registration import board as B

        bres = B.board_poses(scanset, board)
        frac = sum(p is not None for p in bres.poses) / len(scanset.scans)
        if method == "board" or frac >= AUTO_BOARD_FRACTION:
            if frac == 0:
                raise RuntimeError("method 'board': no ChArUco board detected in any image")
            init_poses = [p if p is not None else s.camera.cam_from_world for p, s in zip(bres.poses, scanset.scans)]
            board_init = bres.poses
            use_init = True
            used = "board"
            notes.append(f"board detected in {sum(p is not None for p in bres.poses)}/{len(scanset.scans)} images; "
                         f"median reprojection {bres.median_reprojection_px:.3f} px")
        else:
            used = "icp"
    if method == "colmap":
        from capture.registration import colmap as C

        sfm = C.sfm_poses(scanset, use_init_for_gauge=True)
        init_poses = [p if p is not None else s.camera.cam_from_world for p, s in zip(sfm.poses, scanset.scans)]
        use_init = True
        notes.append(f"SfM registered {sum(p is not None for p in sfm.poses)}/{len(scanset.scans)} images, "
                     f"scale {sfm.scale:.5g}, mean reprojection {sfm.reprojection_px:.3f} px")
    out = ICP.register_icp(scanset, cfg, use_init=use_init, init_poses=init_poses)
    if method == "auto" and used == "icp" and not use_init and \
            sum(not r for r in out.registered) > AUTO_SFM_FLAGGED_FRACTION * len(scanset.scans):
        from capture.registration import colmap as C

        notes.append("too many scans flagged from global registration: retried from SfM poses")
        sfm = C.sfm_poses(scanset, use_init_for_gauge=True)
        init_poses = [p if p is not None else s.camera.cam_from_world for p, s in zip(sfm.poses, scanset.scans)]
        out = ICP.register_icp(scanset, cfg, use_init=True, init_poses=init_poses)
        used = "colmap"
    if used == "board" and board_init is not None:
        # the board fixes the gauge: move the ICP solution (anchored on one scan) onto the
        # board frame by the rigid transform that best agrees with all board poses
        out.cam_from_world = _fit_gauge(out.cam_from_world, board_init, out.registered)
        notes.append("gauge: least-squares fit to all board poses")
        # scans ICP could not connect keep their board pose (PnP on the board is independent of
        # the object's surface: this is what makes fur registrable)
        by_board = [k for k, (r, b) in enumerate(zip(out.registered, board_init)) if not r and b is not None]
        for k in by_board:
            out.cam_from_world[k] = board_init[k]
            out.registered[k] = True
        if by_board:
            names = [scanset.scans[k].name for k in by_board]
            notes.append(f"{len(by_board)} scans posed by the board alone (ICP could not connect them): {names}")
    rep = _report_from_icp(scanset, out, used, init)
    rep.notes.extend(notes)
    rep.seconds["total"] = time.perf_counter() - t0
    keep = [True] * len(scanset.scans) if keep_flagged else list(out.registered)
    result = _with_poses(scanset, out.cam_from_world, keep)
    result = replace(result, metadata={**scanset.metadata, "registration": {
        "method": used, "init": init, "flagged": rep.flagged, "gauge": rep.gauge}})
    return result, rep, out.cam_from_world

"""``furrow register SCANS -o OUT``: refine the poses of a scan set (issue 4)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

HELP = "register scans into one frame (Open3D ICP + pose graph, pycolmap SfM, ChArUco board)"
DESCRIPTION = """Read a scan set, estimate refined camera poses and write a NEW scan set with the
refined transform_matrix and a registration.json report (per-scan fitness, inlier RMSE,
pose-graph consistency, the status of every view and why).  The input is never written over.
Every input view is written: registered, kept at its input pose, or flagged (at its input pose).

Bounded by the input (--pose-prior DEG,FRACTION): no view moves further from its input pose than
the input's stated uncertainty, DEG degrees of turn and FRACTION of the camera's distance to the
object of translation besides it.  The solvers use it as a prior and a bound; a registered pose
beyond it is replaced by the input pose.  Defaults per rig:
  turntable  3.5 x the input poses' scatter about the fitted ring (per axis), at least 1 deg / 1 %
  free       10 deg / 10 %  (ICP + pose graph from the input poses)
  board      3 deg / 3 % about the board's PnP poses;  colmap: 5 deg / 5 % about the SfM poses
--init none asks for a global search instead: no prior, no bound.

Near-symmetric objects (one uniform coat, the same from every side): a turntable view takes the
angle its evidence gives only when that angle is the one answer within the bound and fits better
than the input angle beyond the capture's own noise (a paired t over image tiles); when the input
angle fits as well, or several angles do, it keeps its input angle on the fitted ring.  The report
lists the hypotheses of every view ("angle").

Never worse than the input: every placed view is then judged by an independent check (depth and
colour agreement with its neighbours, their samples reprojected through the depth) at its
registered pose and at its input pose against the same neighbours; it keeps the registered pose
only when that explains the data better by t >= 3 over image tiles, else its input pose.  Views
agreeing with each other prove nothing: the comparison is always with the input pose
(--no-check skips the check).

Exit status: 0 = written, at least one view improved, none flagged ("kept at input" is not a
failure: the evidence could not beat the input, the report says why); 3 = some views flagged
(the registration found them wrong: a foreign object, off the rig, no accepted pair; written at
their input pose); 4 = nothing could be improved (every view kept at its input pose); 1 = error.

methods: icp   Open3D coarse ICP + projective point-to-plane ICP + pose graph (loop closure),
               FPFH+RANSAC fallback
         colmap  pycolmap SfM on the colour images, Umeyama into the depth frame, then ICP
         board   ChArUco PnP (opencv-contrib) for the initial poses, then ICP
         auto    board if seen in most images, else icp (SfM if global registration fails)

rigs:    free       a pose per scan (the methods above)
         turntable  one axis, one angle per scan, placed by all the evidence at once: the range
                    surface, the colour pattern, SIFT features (fur without a board); silhouettes
                    against the empty background check it (a foreign object is flagged)
         auto       turntable when the nominal poses lie on one circle about one axis
                    (said in the report), else free

The report (console and registration.json) says per scan its status, which evidence placed it
(geometry, colour, silhouette, features, board, input angle), with what residual, how far it moved
from its input pose, and the check's comparison."""

#: Exit status when the output was written but some scans were flagged.
EXIT_FLAGGED = 3
#: Exit status when no view could be improved on its input pose (the output keeps the input poses).
EXIT_NOT_IMPROVED = 4


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("scans", type=Path, help="input scan set (transforms.json, its folder, or a plain folder)")
    p.add_argument("-o", "--out", type=Path, required=True,
                   help="output folder (must not exist, must not be the input)")
    p.add_argument("--method", choices=["auto", "icp", "colmap", "board"], default="auto")
    p.add_argument("--init", choices=["nominal", "none"], default="nominal",
                   help="start from the input poses (nominal, bounded by --pose-prior) or from nothing (a global "
                        "search, unbounded)")
    p.add_argument("--pose-prior", default=None, metavar="DEG,FRACTION",
                   help="the input poses' stated uncertainty: no view moves further from its input pose than DEG "
                        "degrees of turn and FRACTION of its distance to the object besides (e.g. 2,0.02); default "
                        "per rig (see above)")
    p.add_argument("--rig", choices=["auto", "free", "turntable"], default="auto",
                   help="pose model: a pose per scan (free), one axis + one angle per scan (turntable), "
                        "or detected from the nominal poses (auto, default)")
    p.add_argument("--colored", action="store_true", help="coloured ICP at the finest Open3D level")
    p.add_argument("--board", default=None, metavar="NXxNY:SQUARE_M:MARKER_M[:DICT]",
                   help="ChArUco board for --method board/auto, e.g. 7x7:0.05:0.037:DICT_4X4_50 "
                        "(default: that board, lying at z = -0.13 m; use --board-z)")
    p.add_argument("--board-z", type=float, default=None, help="height of the board plane in the world (m)")
    p.add_argument("--no-check", action="store_true",
                   help="skip the independent check of the registered poses against the nominal ones")
    p.add_argument("--keep-flagged", action="store_true",
                   help="(no effect: every input view is written, flagged ones at their input pose)")
    p.add_argument("--depth-format", choices=["png", "png-0.1mm", "exr"], default="png",
                   help="depth files: png (16-bit millimetres, default), png-0.1mm, or exr (float metres)")
    p.add_argument("--frames", default=None, help="frame selection, python slices: '0::2', '1,4,7'")
    p.add_argument("--json", action="store_true", help="print the registration report as JSON on stdout")
    p.add_argument("--debug", action="store_true", help="show tracebacks")


def parse_board(text: str | None, z: float | None):
    """``NXxNY:SQUARE_M:MARKER_M[:DICT]`` -> BoardSpec (None -> default / None)."""
    from dataclasses import replace

    from capture.registration.board import BoardSpec

    if text is None and z is None:
        return None
    spec = BoardSpec()
    if text:
        try:
            parts = text.split(":")
            nx, ny = (int(v) for v in parts[0].lower().split("x"))
            spec = BoardSpec(nx, ny, float(parts[1]), float(parts[2]), parts[3] if len(parts) > 3 else spec.dictionary)
        except (ValueError, IndexError) as e:
            raise ValueError(f"--board {text!r}: {e}; expected NXxNY:SQUARE_M:MARKER_M[:DICT], "
                             "e.g. 7x7:0.05:0.037") from None
    return replace(spec, z_m=z) if z is not None else spec


def _residual_text(rec) -> str:
    """One line of a scan's residual figures, per evidence."""
    parts = []
    for e, r in rec.residuals.items():
        if e == "geometry":
            parts.append(f"geometry fit {r.get('fitness', 0):.2f} rmse {1000 * (r.get('rmse_m') or 0):.2f} mm")
        elif e == "colour":
            parts.append(f"colour {r.get('chroma_rmse', float('nan')):.3f}")
        elif e == "silhouette":
            parts.append(f"silhouette {r.get('rms_px', 0):.1f} px ({r.get('outside_frac', 0):.0%} out)")
        elif e == "features":
            parts.append(f"features {r.get('inliers', 0)}/{r.get('matches', 0)}")
    return "; ".join(parts)


def evidence_table(rep):
    """A rich table: per scan, placed or flagged, by which evidence, with what residual."""
    import math

    from rich.table import Table

    t = Table(title=f"registration ({rep.rig} rig): evidence per scan")
    for c in ("scan", "status", "evidence", "angle sigma", "moved", "check t", "residuals / reason"):
        t.add_column(c)
    for s in rep.scans:
        sig = f"{s.angle_sigma_deg:.3f} deg" if math.isfinite(s.angle_sigma_deg) else ""
        status = s.status or ("registered" if s.registered else "flagged")
        if status == "flagged":
            status = "[yellow]flagged[/]"
        moved = f"{s.move['rot_deg']:.2f} deg" if s.move else ""
        text = _residual_text(s) if s.status == "registered" else s.reason
        t.add_row(s.name, status, ", ".join(s.evidence), sig, moved, _check_text(s.check), text)
    return t


def _check_text(check: dict) -> str:
    """The independent check's t of the registered pose over the input pose."""
    c = check.get("comparison") if check else None
    return "" if not c else f"{c['t']:+.1f}" + ("" if c["better"] else " [yellow]<[/]")


def _same_or_inside(a: Path, b: Path) -> bool:
    a, b = a.resolve(), b.resolve()
    return a == b or b in a.parents or a in b.parents


def run(args, console) -> int:
    from capture import io as cio
    from capture.registration import icp as ICP
    from capture.registration import pipeline
    from capture.registration.prior import parse_prior
    from furrow.console import StageTimer, fail, track

    src = args.scans if args.scans.is_dir() else args.scans.parent
    if _same_or_inside(args.out, src):
        fail(f"{args.out}: output must be a new folder outside the input {src} (the input is never written over)")
        return 1
    if args.out.exists():
        fail(f"{args.out}: already exists; choose a new output folder")
        return 1
    try:
        prior = parse_prior(args.pose_prior) if args.pose_prior else None
    except ValueError as e:
        fail(str(e))
        return 2
    if prior is not None and args.init == "none":
        fail("--pose-prior bounds the moves from the input poses; --init none ignores them (a global search)")
        return 2
    timer = StageTimer()
    with timer.stage("read"):
        ss = cio.read_scanset(args.scans, frames=args.frames, progress=track)
    with timer.stage(f"register ({args.method}, init {args.init})"):
        cfg = ICP.IcpConfig(colored=args.colored)
        out, rep, _ = pipeline.register(ss, args.method, args.init, cfg,
                                        board=parse_board(args.board, args.board_z), rig=args.rig, progress=track,
                                        check=not args.no_check, pose_prior=prior)
    report = rep.to_json()
    report["input"] = str(args.scans)
    with timer.stage("write"):
        path = cio.write_transforms(out, args.out, depth_format=args.depth_format,
                                    extra_files={"registration.json": json.dumps(report, indent=1).encode()},
                                    progress=track)
    console.print(timer.table())
    console.print(evidence_table(rep))
    n, k = report["n_scans"], report["n_registered"]
    console.print(f"rig: {rep.rig} ({rep.rig_detection or 'not tested'})", highlight=False)
    for note in rep.notes:
        console.print(f"  {note}", highlight=False)
    flagged, kept = rep.flagged, rep.kept
    console.print(f"wrote all {n} views to {path}: {k} registered, {len(kept)} kept at their input pose, "
                  f"{len(flagged)} flagged (at their input pose) with {rep.method}", highlight=False)
    for s in rep.scans:
        if s.status == "kept at input":
            console.print(f"kept at input {s.name}: {s.reason}", highlight=False)
        elif s.status == "flagged":
            console.print(f"[yellow]flagged[/] {s.name}: {s.reason}", highlight=False)
    if args.json:
        sys.stdout.write(json.dumps(report, indent=1) + "\n")
    if flagged:
        return EXIT_FLAGGED
    if k == 0:
        console.print("[yellow]nothing could be improved[/]: every view keeps its input pose", highlight=False)
        return EXIT_NOT_IMPROVED
    return 0

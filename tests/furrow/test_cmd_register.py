"""``furrow register``: a perturbed ring with an impostor scan, and the --board option parser."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from capture.registration import perturb, scenes
from capture.registration import report as R
from tests.capture.test_registration_more import _with_poses


def test_cli_register_writes_new_set_and_flags_impostor(tmp_path):
    from capture import io as cio
    from furrow.cli import main

    mesh = scenes.control_object()
    cams = scenes.ring_cameras(8, width=128, height=96)
    ss = scenes.render_set(mesh, cams, impostor_at=5)
    gt = [c.cam_from_world for c in cams]
    c = ss.bounds.mean(0)
    pert = perturb.perturb_poses(gt, 3.0, 0.03 * ss.size, c, seed=5)
    src = tmp_path / "in"
    cio.write_transforms(_with_poses(ss, pert), src, depth_format="exr")
    before = (src / "transforms.json").read_bytes()
    out = tmp_path / "out"
    rc = main(["register", str(src), "-o", str(out), "--method", "icp"])
    assert rc == 3  # written, with a flagged scan
    assert (src / "transforms.json").read_bytes() == before  # input untouched
    rep = json.loads((out / "registration.json").read_text())
    assert [Path(f).stem for f in rep["flagged"]] == ["view005"], rep["flagged"]
    assert rep["n_registered"] == 7 and rep["n_written"] == 8
    assert set(rep["thresholds"]) >= {"MIN_FITNESS", "MAX_EDGE_RESIDUAL_DEG"}
    # rig auto: the ring is a turntable; every placed scan says what placed it and with what residual
    assert rep["rig"] == "turntable" and "one circle" in rep["rig_detection"]
    assert "turntable default" in rep["pose_prior"]["source"]
    for s in rep["scans"]:
        assert s["status"] in ("registered", "kept at input", "flagged") and (s["registered"] or s["reason"])
        assert not s["registered"] or ("geometry" in s["residuals"] and s["evidence"] and s["move"]["within"])
    got = cio.read_scanset(out)
    assert len(got.scans) == 8  # every input view, the flagged one at its input pose
    assert np.allclose(got.scans[5].camera.cam_from_world, pert[5], atol=1e-6)
    keep = [k for k in range(8) if k != 5]
    e = R.pose_errors([got.scans[k].camera.cam_from_world for k in keep], [gt[k] for k in keep], c)
    assert e["rot_median_deg"] < 0.1
    # refuses to write over the input or an existing folder
    assert main(["register", str(src), "-o", str(src), "--method", "icp"]) == 1
    assert main(["register", str(src), "-o", str(out), "--method", "icp"]) == 1


def test_cli_board_option_parses_and_rejects():
    from furrow.cmd_register import parse_board

    spec = parse_board("9x7:0.04:0.03:DICT_5X5_100", -0.2)
    assert (spec.squares_x, spec.squares_y, spec.square_m, spec.marker_m, spec.dictionary, spec.z_m) == \
        (9, 7, 0.04, 0.03, "DICT_5X5_100", -0.2)
    assert parse_board(None, None) is None
    with pytest.raises(ValueError, match="--board"):
        parse_board("7:0.05", None)
    with pytest.raises(ValueError, match="marker_m"):
        parse_board("7x7:0.03:0.05", None)


def test_cli_register_exact_poses_exit_4_and_say_kept_nominal(tmp_path, capsys):
    """Input poses that are already right: nothing can be improved (exit 4, documented in --help),
    every view says "kept nominal" with both check scores, and the poses come back unchanged."""
    from capture import io as cio
    from furrow.cli import main
    from furrow.cmd_register import DESCRIPTION, EXIT_NOT_IMPROVED

    cams = scenes.ring_cameras(8, width=128, height=96)
    ss = scenes.render_set(scenes.control_object(), cams)
    src, out = tmp_path / "in", tmp_path / "out"
    cio.write_transforms(ss, src, depth_format="exr")
    assert main(["register", str(src), "-o", str(out), "--method", "icp"]) == EXIT_NOT_IMPROVED == 4
    assert "4 = nothing could be improved" in DESCRIPTION
    assert "nothing could be improved" in capsys.readouterr().err  # the console writes to stderr
    rep = json.loads((out / "registration.json").read_text())
    assert rep["check"]["kept at input"] == 8 and rep["check"]["improved"] is False
    for s in rep["scans"]:
        assert s["status"] == "kept at input" and s["reason"]
    got = cio.read_scanset(out)
    c = ss.bounds.mean(0)
    for a, b in zip(got.scans, ss.scans):
        rot, _ = R.transform_delta(a.camera.cam_from_world, b.camera.cam_from_world, c)
        assert rot < 0.02


def test_cli_pose_prior_parses_rejects_and_bounds(tmp_path, capsys):
    """--pose-prior DEG,FRACTION: a bad value is a one-line error (exit 2), so is a prior with --init
    none (a global search); a given prior is what registration.json reports and no view moves
    further from its input pose."""
    from capture import io as cio
    from capture.registration.prior import move, parse_prior
    from furrow.cli import main
    from furrow.cmd_register import DESCRIPTION

    assert parse_prior("2,0.02").rot_deg == 2.0 and "turntable" in DESCRIPTION and "--init none" in DESCRIPTION
    for bad in ("2", "a,b", "-1,0.02", "2,0"):
        with pytest.raises(ValueError, match="--pose-prior|positive"):
            parse_prior(bad)
    cams = scenes.ring_cameras(8, width=128, height=96)
    ss = scenes.render_set(scenes.control_object(), cams)
    gt = [c.cam_from_world for c in cams]
    c = ss.bounds.mean(0)
    pert = perturb.perturb_poses(gt, 3.0, 0.03 * ss.size, c, seed=5)
    src, out = tmp_path / "in", tmp_path / "out"
    cio.write_transforms(_with_poses(ss, pert), src, depth_format="exr")
    assert main(["register", str(src), "-o", str(out), "--pose-prior", "two"]) == 2
    assert main(["register", str(src), "-o", str(out), "--pose-prior", "1,0.01", "--init", "none"]) == 2
    assert "--pose-prior" in capsys.readouterr().err
    assert main(["register", str(src), "-o", str(out), "--pose-prior", "1,0.01"]) in (0, 4)
    rep = json.loads((out / "registration.json").read_text())
    assert rep["pose_prior"] == {"rot_deg": 1.0, "trans_frac": 0.01, "source": "--pose-prior"}
    got = cio.read_scanset(out)
    assert len(got.scans) == 8
    for s, p in zip(got.scans, pert):
        rot, trans = move(s.camera.cam_from_world, p, c)
        assert rot <= 1.0 + 1e-4 and trans <= 0.01 + 1e-4


def _register_cli(tmp_path, ss, pert, name):
    from capture import io as cio
    from furrow.cli import main

    src, out = tmp_path / f"{name}_in", tmp_path / f"{name}_out"
    cio.write_transforms(_with_poses(ss, pert), src, depth_format="exr")
    rc = main(["register", str(src), "-o", str(out)])  # furrow register's defaults
    return rc, json.loads((out / "registration.json").read_text()), cio.read_scanset(out)


def test_cli_angle_fallback_fires_on_a_symmetric_ball_and_stays_off_on_an_object_it_handles(tmp_path, capsys):
    """Issue 31 through the CLI, defaults only.  A ball painted in latitude bands with a highlight
    that turns with the camera defeats the angle estimator (its best-scoring angle is a neighbour's):
    every view keeps its input angle, registration.json says why per view, the console says so, and
    no view ends worse than its input.  The asymmetric control object on the same ring is placed by
    its evidence (the fallback stays off) and ends better than its input."""
    cams = scenes.ring_cameras(8, width=96, height=72)
    gt = [c.cam_from_world for c in cams]
    ball = scenes.with_sensor(scenes.symmetric_set(cams, 0.6), seed=0)
    c = ball.bounds.mean(0)
    pert = perturb.perturb_poses(gt, 2.0, 0.02 * ball.size, c, seed=4)
    rc, rep, got = _register_cli(tmp_path, ball, pert, "ball")
    assert rc in (0, 4) and len(got.scans) == 8 and not rep["flagged"]
    assert all(s["angle"]["source"] == "input" and s["angle"]["reason"] for s in rep["scans"]), \
        [s["angle"] for s in rep["scans"]]
    assert any("0 at the angle their evidence gives" in n for n in rep["notes"]), rep["notes"]
    err = " ".join(capsys.readouterr().err.split())  # the console wraps long lines
    assert "0 at the angle their evidence gives, the others at their input angle" in err
    poses = [s.camera.cam_from_world for s in got.scans]
    e_out = [R.transform_delta(p, g, c)[0] for p, g in zip(poses, gt)]
    e_in = [R.transform_delta(p, g, c)[0] for p, g in zip(pert, gt)]
    assert max(o - i for o, i in zip(e_out, e_in)) <= 0.25, (e_out, e_in)

    ctl = scenes.render_set(scenes.control_object(), scenes.ring_cameras(8, width=128, height=96))
    c = ctl.bounds.mean(0)
    pert = perturb.perturb_poses(gt, 2.0, 0.02 * ctl.size, c, seed=4)
    rc, rep, got = _register_cli(tmp_path, ctl, pert, "control")
    assert rc == 0 and len(got.scans) == 8
    by_evidence = sum(s["angle"]["source"] == "evidence" for s in rep["scans"])
    assert by_evidence >= 6, [s["angle"] for s in rep["scans"]]
    e = R.pose_errors([s.camera.cam_from_world for s in got.scans], gt, c, gauge=None)
    assert e["rot_median_deg"] < 0.5 * np.median([R.transform_delta(p, g, c)[0] for p, g in zip(pert, gt)])

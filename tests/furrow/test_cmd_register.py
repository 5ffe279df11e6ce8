"""``furrow register``: a perturbed ring with an impostor scan, and the --board option parser."""

from __future__ import annotations

import json
from pathlib import Path

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
    assert rep["n_registered"] == 7 and set(rep["thresholds"]) >= {"MIN_FITNESS", "MAX_EDGE_RESIDUAL_DEG"}
    # rig auto: the ring is a turntable; every placed scan says what placed it and with what residual
    assert rep["rig"] == "turntable" and "one circle" in rep["rig_detection"]
    for s in rep["scans"]:
        assert bool(s["evidence"]) == s["registered"] and (s["registered"] or s["reason"])
        assert not s["registered"] or "geometry" in s["residuals"]
    got = cio.read_scanset(out)
    assert len(got.scans) == 7
    keep = [k for k in range(8) if k != 5]
    e = R.pose_errors([s.camera.cam_from_world for s in got.scans], [gt[k] for k in keep], c)
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
    assert rep["check"]["kept nominal"] == 8 and rep["check"]["improved"] is False
    for s in rep["scans"]:
        assert s["status"] == "kept nominal" and s["reason"]
        assert {"nominal", "registered"} <= set(s["check"]) and s["check"]["nominal"]["consistent"]
    got = cio.read_scanset(out)
    c = ss.bounds.mean(0)
    for a, b in zip(got.scans, ss.scans):
        rot, _ = R.transform_delta(a.camera.cam_from_world, b.camera.cam_from_world, c)
        assert rot < 0.02

"""The independent check of placed views (issue 22): a misplaced view is caught, exact input
poses come back unchanged, and no placed view ends worse than its input pose."""

from __future__ import annotations

import numpy as np
import pytest

from capture.registration import check as C
from capture.registration import perturb, pipeline
from capture.registration import report as R
from capture.registration import verify as V
from tests.capture.test_registration_turntable import _ring, _with_poses


def _errors(poses, gt, c):
    """Per view rotation error (degrees) after the rigid gauge that best fits all poses to the truth."""
    al = R.fit_gauge(poses, gt, [True] * len(poses))
    return np.array([R.transform_delta(a, g, c)[0] for a, g in zip(al, gt)])


def test_a_view_misplaced_by_3_degrees_after_registration_is_caught():
    ss, gt = _ring()
    c = ss.bounds.mean(0)
    pert = perturb.perturb_poses(gt, 3.0, 0.03 * ss.size, c, seed=4)
    inp = _with_poses(ss, pert)
    _, rep, poses = pipeline.register(inp, "icp", "nominal", rig="turntable", check=False)
    assert all(s.registered for s in rep.scans)
    bad = list(poses)
    bad[5] = perturb.perturb_poses([poses[0], poses[5]], 3.0, 0.0, c, seed=7)[1]
    views = [C.prepare(s) for s in inp.scans]
    ver = V.verify(views, pert, bad, [True] * 12, c, ss.size)
    st = [v.status for v in ver.verdicts]
    assert st[5] == V.FLAGGED, (st, ver.verdicts[5])
    assert "neither pose" in ver.verdicts[5].reason or "neighbours" in ver.verdicts[5].reason
    assert not ver.verdicts[5].registered.consistent and not ver.verdicts[5].nominal.consistent
    assert st.count(V.REGISTERED) == 11, st
    assert np.allclose(ver.poses[5], pert[5])  # a flagged view keeps its input pose
    # the correct registered poses pass the same check
    ok = V.verify(views, pert, poses, [True] * 12, c, ss.size)
    assert all(v.status == V.REGISTERED for v in ok.verdicts)


def test_exact_input_poses_come_back_unchanged():
    ss, gt = _ring()
    c = ss.bounds.mean(0)
    _, rep, poses = pipeline.register(ss, "icp", "nominal", rig="turntable")
    assert rep.check["improved"] is False and rep.check["kept nominal"] == 12, rep.check
    for p, g in zip(poses, gt):
        rot, disp = R.transform_delta(p, g, c)
        assert rot < 0.02 and disp < 1e-4 * ss.size
    js = rep.to_json()["scans"]
    assert all(s["status"] == "kept nominal" and s["check"]["nominal"]["consistent"] for s in js)


@pytest.mark.parametrize("rig", ["turntable", pytest.param("free", marks=pytest.mark.slow)])
def test_no_placed_view_is_worse_than_its_input(rig):
    ss, gt = _ring()
    c = ss.bounds.mean(0)
    pert = perturb.perturb_poses(gt, 2.0, 0.02 * ss.size, c, seed=3)
    pert[4] = gt[4]  # one exact input pose: registration must not make it worse
    _, rep, poses = pipeline.register(_with_poses(ss, pert), "icp", "nominal", rig=rig)
    placed = [k for k, s in enumerate(rep.scans) if s.registered]
    assert len(placed) >= 11
    e_out, e_in = _errors(poses, gt, c), _errors(pert, gt, c)
    for k in placed:
        assert e_out[k] <= e_in[k] + 0.1, (k, e_out[k], e_in[k], rep.scans[k].status)
    assert rep.check["improved"]

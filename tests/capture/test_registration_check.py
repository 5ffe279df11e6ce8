"""The independent check of placed views (issues 22, 31): a registered pose is kept only where it
explains the data significantly better than the input pose; a misplaced view goes back to its
input pose, exact input poses come back unchanged, and no view ends worse than its input."""

from __future__ import annotations

import numpy as np
import pytest

from capture.registration import check as C
from capture.registration import perturb, pipeline
from capture.registration import report as R
from capture.registration import verify as V
from capture.registration.angles import paired_t
from capture.registration.turntable import rotation_about_line
from tests.capture.test_registration_turntable import _ring, _with_poses


def _errors(poses, gt, c):
    """Per view rotation error (degrees) after the rigid gauge that best fits all poses to the truth."""
    al = R.fit_gauge(poses, gt, [True] * len(poses))
    return np.array([R.transform_delta(a, g, c)[0] for a, g in zip(al, gt)])


def test_paired_t_is_the_mean_difference_over_its_standard_error():
    a = np.array([3.0, 4.0, 5.0, 6.0])
    assert paired_t(a, a - 1.0) == np.inf and paired_t(a - 1.0, a) == -np.inf
    d = np.array([1.0, 2.0, 3.0, 2.0])
    assert paired_t(d, np.zeros(4)) == pytest.approx(2.0 / (np.std(d, ddof=1) / 2.0))
    assert paired_t(np.zeros(4), np.zeros(4)) == 0.0


def test_a_view_misplaced_after_registration_goes_back_to_its_input_pose():
    ss, gt = _ring()
    c = ss.bounds.mean(0)
    pert = perturb.perturb_poses(gt, 3.0, 0.03 * ss.size, c, seed=4)
    pert[5] = gt[5]  # an exact input pose ...
    inp = _with_poses(ss, pert)
    bad = list(gt)
    bad[5] = perturb.perturb_poses([gt[0], gt[5]], 3.0, 0.0, c, seed=7)[1]  # ... misplaced by the registration
    views = [C.prepare(s) for s in inp.scans]
    ver = V.verify(views, pert, bad, [True] * 12, c, ss.size)
    st = [v.status for v in ver.verdicts]
    assert st[5] == V.KEPT, (st, ver.verdicts[5])
    assert "not explain the data significantly better" in ver.verdicts[5].reason
    assert ver.verdicts[5].comparison.t < V.T_BETTER
    assert st[0] == V.KEPT and "left it at its input" in ver.verdicts[0].reason  # view 0's input is exact
    assert st.count(V.REGISTERED) == 10, st
    assert np.allclose(ver.poses[5], pert[5])  # kept at its input pose
    # the right poses pass the same check, each with its t over the input pose
    ok = V.verify(views, pert, gt, [True] * 12, c, ss.size)
    assert all(v.status == V.REGISTERED and v.comparison.t >= V.T_BETTER
               for k, v in enumerate(ok.verdicts) if k not in (0, 5))


def test_a_group_placed_wrong_together_is_no_proof():
    """Four neighbouring views turned 15 degrees together about the axis agree with each other;
    the input's bound (and the comparison with the input pose) keeps them at their input poses."""
    ss, gt = _ring()
    c = ss.bounds.mean(0)
    pert = perturb.perturb_poses(gt, 2.0, 0.02 * ss.size, c, seed=3)
    wrong = list(gt)
    turn = rotation_about_line(np.array([0.0, 0.0, 1.0]), np.zeros(3), np.radians(15.0))
    for k in (3, 4, 5, 6):
        wrong[k] = gt[k] @ turn
    inp = _with_poses(ss, pert)
    rep = R.RegistrationReport("turntable", "nominal", "", ss.size, {},
                               scans=[R.ScanRecord(s.name, True, status="registered") for s in ss.scans])
    prior = pipeline.PR.PosePrior(4.0, 0.04)
    poses, placed = pipeline.apply_bound(inp, rep, wrong, [True] * 12, prior, pert)
    assert [k for k in range(12) if not placed[k]] == [3, 4, 5, 6]
    assert all("beyond the stated uncertainty" in rep.scans[k].reason for k in (3, 4, 5, 6))
    poses = pipeline.apply_check(inp, rep, poses, placed)
    st = [s.status for s in rep.scans]
    # view 0's input pose is exact (nothing to register): kept
    assert st == ["kept at input"] + ["registered"] * 2 + ["kept at input"] * 4 + ["registered"] * 5, st
    for k in range(12):
        assert np.allclose(poses[k], pert[k] if st[k] == "kept at input" else gt[k])


def test_exact_input_poses_come_back_unchanged():
    ss, gt = _ring()
    c = ss.bounds.mean(0)
    out, rep, poses = pipeline.register(ss, "icp", "nominal", rig="turntable")
    assert rep.check["improved"] is False and rep.check["kept at input"] == 12, rep.check
    assert len(out.scans) == 12
    for p, g in zip(poses, gt):
        rot, disp = R.transform_delta(p, g, c)
        assert rot < 0.02 and disp < 1e-4 * ss.size
    js = rep.to_json()["scans"]
    assert all(s["status"] == "kept at input" and s["reason"] for s in js)


@pytest.mark.parametrize("rig", ["turntable", pytest.param("free", marks=pytest.mark.slow)])
def test_no_view_is_worse_than_its_input(rig):
    ss, gt = _ring()
    c = ss.bounds.mean(0)
    pert = perturb.perturb_poses(gt, 2.0, 0.02 * ss.size, c, seed=3)
    pert[4] = gt[4]  # one exact input pose: registration must not make it worse
    out, rep, poses = pipeline.register(_with_poses(ss, pert), "icp", "nominal", rig=rig)
    assert len(out.scans) == 12 and not rep.flagged
    e_out, e_in = _errors(poses, gt, c), _errors(pert, gt, c)
    assert (e_out <= e_in + 0.1).all(), (e_out, e_in, [s.status for s in rep.scans])
    assert np.median(e_out) < 0.2 < np.median(e_in)
    assert rep.check["improved"] and rep.check["registered"] >= 10

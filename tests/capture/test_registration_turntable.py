"""The turntable rig (issue 16): model, detection from nominal poses, placement, failure flags."""

from __future__ import annotations

import numpy as np
import pytest

from capture.camera import invert_rigid
from capture.registration import perturb, pipeline, scenes
from capture.registration import report as R
from capture.registration import turntable as TT


def _ring(n=12, width=160, height=120, impostor_at=None):
    cams = scenes.ring_cameras(n, width=width, height=height)
    ss = scenes.render_set(scenes.control_object(), cams, impostor_at=impostor_at)
    return scenes.with_sensor(ss, seed=0), [c.cam_from_world for c in cams]


def _with_poses(ss, poses):
    from capture.camera import Camera
    from capture.scan import Scan, ScanSet

    return ScanSet(tuple(Scan(s.rgb, s.depth, Camera(s.camera.K, p, s.camera.width, s.camera.height, s.camera.name),
                              s.name) for s, p in zip(ss.scans, poses)), ss.bounds, ss.metadata)


def test_fit_turntable_reads_the_ring_off_exact_poses():
    cams = scenes.ring_cameras(12)
    gt = [c.cam_from_world for c in cams]
    fit = TT.fit_turntable(gt)
    assert fit.is_turntable and not fit.off
    assert abs(abs(fit.model.axis @ [0, 0, 1]) - 1) < 1e-9
    assert fit.model.radius == pytest.approx(0.5 * np.cos(np.radians(20)), rel=1e-6)
    for k in range(12):
        rot, disp = R.transform_delta(fit.model.pose(k), gt[k], np.zeros(3))
        # the reference pose is fitted to the ring now (not copied): rotation_angle_deg's acos
        # resolves no better than sqrt(2 eps) rad = 1.2e-6 degrees
        assert rot < 1e-5 and disp < 1e-9
        assert np.allclose(fit.model.relative(3, k), gt[3] @ invert_rigid(gt[k]), atol=1e-9)


def test_fit_turntable_names_a_view_off_by_90_degrees_and_rejects_a_random_set():
    gt = [c.cam_from_world for c in scenes.ring_cameras(12)]
    pert = perturb.perturb_poses(gt, 3.0, 0.01, np.zeros(3), seed=2)
    pert[7] = perturb.perturb_poses([gt[0], gt[7]], 90.0, 0.0, np.zeros(3), seed=3)[1]
    fit = TT.fit_turntable(pert)
    assert fit.is_turntable and list(fit.off) == [7]
    assert "off the turntable" in fit.off[7]
    rng = np.random.default_rng(0)
    from capture.camera import look_at

    scattered = [look_at(rng.normal(size=3) * 0.5 + [0, 0, 0.1], (0, 0, 0)) for _ in range(12)]
    assert not TT.fit_turntable(scattered).is_turntable


def test_pair_jacobian_moves_the_pair_like_the_model():
    gt = [c.cam_from_world for c in scenes.ring_cameras(8)]
    m = TT.fit_turntable(gt).model
    J = m.pair_jacobian(1, 2, 0.3)
    dx = np.zeros(4 + 8)
    h = 1e-5
    dx[4 + 2] = h  # turn view 2 a little: the pair moves by the angle column (to first order)
    D = m.updated(dx, 0.3).relative(1, 2) @ invert_rigid(m.relative(1, 2))
    w = 0.5 * np.array([D[2, 1] - D[1, 2], D[0, 2] - D[2, 0], D[1, 0] - D[0, 1]])
    assert np.linalg.norm(w) == pytest.approx(h, rel=1e-6)  # a turn by h about the axis
    assert np.allclose(w, J[:3, 4] * h, atol=1e-3 * h)
    assert np.allclose(D[:3, 3], J[3:, 4] * h, atol=1e-3 * h)


@pytest.mark.parametrize("rig", ["turntable", "free"])
def test_foreign_object_and_a_90_degree_view_are_flagged_by_name(rig):
    ss, gt = _ring(impostor_at=4)
    c = ss.bounds.mean(0)
    pert = perturb.perturb_poses(gt, 3.0, 0.03 * ss.size, c, seed=4)
    pert[9] = perturb.perturb_poses([gt[0], gt[9]], 90.0, 0.0, c, seed=5)[1]
    _, rep, poses = pipeline.register(_with_poses(ss, pert), "icp", "nominal", rig=rig)
    assert rep.rig == rig
    assert sorted(rep.flagged) == ["view004", "view009"], rep.flagged
    by = {s.name: s for s in rep.scans}
    assert by["view004"].reason and by["view009"].reason
    placed = [k for k in range(12) if k not in (4, 9)]
    e = R.pose_errors([poses[k] for k in placed], [gt[k] for k in placed], c, gauge=None)
    assert e["rot_median_deg"] < 0.15, e
    assert all(by[ss.scans[k].name].evidence for k in placed)

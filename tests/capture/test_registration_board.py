"""The synthetic ChArUco board (datasets_synthetic/board.py) agrees with the detector's board."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from capture.registration import board as B
from capture.registration import report as R


def test_board_mesh_cells_match_the_board_texture():
    from datasets_synthetic.board import board_mesh

    spec = B.BoardSpec(z_m=-0.1)
    m = board_mesh(spec, px_per_square=8)
    tex = B.board_texture_fn(spec, px_per_square=8)
    cells = m.vertices.reshape(-1, 4, 3)  # every cell / paper strip is one quad of 4 own vertices
    centres = cells.mean(axis=1)
    cols = m.colors.reshape(-1, 4, 3)[:, 0]
    assert np.allclose(m.vertices[:, 2], -0.1)
    inside = (np.abs(centres[:, 0]) < spec.size_m[0] / 2) & (np.abs(centres[:, 1]) < spec.size_m[1] / 2)
    assert inside.sum() == (8 * spec.squares_x) * (8 * spec.squares_y)
    assert np.allclose(cols[inside], tex(centres[inside]), atol=1e-6)
    assert np.allclose(cols[~inside], 1.0)  # white paper


@pytest.mark.slow
@pytest.mark.gl
def test_synthetic_furball_on_a_board_gives_board_poses():
    from datasets_synthetic.board import add_board
    from datasets_synthetic.scenes import build_scene
    from datasets_synthetic.synth import SMALL_RIG, SynthConfig, synthesize

    scene, spec = add_board(build_scene("furball"))
    rig = dataclasses.replace(SMALL_RIG, views_per_ring=4, width=480, height=360, elevations_deg=(50.0,),
                              distance=0.65, fov_y_deg=40.0)
    cap = synthesize(SynthConfig(scene="furball", rig=rig, supersample=2), scene=scene)
    res = B.board_poses(cap.scanset, spec)
    for p, c in zip(res.poses, cap.true_cameras):
        assert p is not None
        assert R.transform_delta(p, c.cam_from_world, np.zeros(3))[0] < 0.5

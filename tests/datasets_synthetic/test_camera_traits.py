"""Synthetic real-camera traits: auto exposure of the kept views, rendering through a lens."""

from __future__ import annotations

import json

import numpy as np
import pytest

from capture.io import read_scanset
from datasets_synthetic.camera_traits import (
    FISHEYE_LENS,
    OPENCV_LENS,
    exposure_gains,
    exposure_jump_gains,
    exposure_record,
    margin_camera,
)
from datasets_synthetic.rig import TurntableRig
from datasets_synthetic.synth import SynthConfig, synthesize, write_capture

TINY = TurntableRig(views_per_ring=12, width=96, height=72)


def test_exposure_jitters_kept_views_only():
    g = exposure_gains(36, 0.35, 0.06, seed=0, holdout=2)
    assert np.all(g[1::2] == 1.0) and np.all(g[::2] != 1.0)
    ev = np.log2(g[::2]).mean(axis=1)
    assert 0.2 < ev.std() < 0.5
    assert np.array_equal(g, exposure_gains(36, 0.35, 0.06, seed=0, holdout=2))
    rec = json.loads(exposure_record([f"v{i}" for i in range(36)], g, 0.35, 0.06, 2))
    assert rec["views"][0]["jittered"] and not rec["views"][1]["jittered"]
    assert np.allclose(np.exp2(rec["views"][0]["ev"]) * np.array(rec["views"][0]["wb"]), g[0])


def test_exposure_jumps_in_a_few_kept_views_only():
    """The hard case conifer_room_turntable_jump_ae: the exposure jumps in ``count`` kept views, the rest at 1."""
    g = exposure_jump_gains(36, 0.5, 3, seed=0, holdout=2)
    jumped = np.flatnonzero(np.any(g != 1.0, axis=1))
    assert len(jumped) == 3 and np.all(jumped % 2 == 0)
    assert np.allclose(np.log2(g[jumped]), 0.5)
    assert np.array_equal(g, exposure_jump_gains(36, 0.5, 3, seed=0, holdout=2))
    assert not np.array_equal(g, exposure_jump_gains(36, 0.5, 3, seed=1, holdout=2))
    with pytest.raises(ValueError, match="count"):
        exposure_jump_gains(36, 0.5, 19, seed=0, holdout=2)


def test_margin_camera_covers_the_distorted_field():
    cam = TINY.cameras(0.1)[0]
    for lens in (OPENCV_LENS, FISHEYE_LENS):
        big = margin_camera(cam, lens)
        assert big.width > cam.width and big.height > cam.height
        assert np.allclose(big.K[0, 0], cam.K[0, 0])


def test_lens_capture_reads_back_as_its_pinhole(tmp_path, gl_ctx):
    """A torus rendered through the OPENCV lens, written with camera_model OPENCV and read back
    (undistorted, crop) has the depth and coverage of a pinhole render of the undistorted camera."""
    from render.mesh.raster.gl import MeshRasterizer

    rig = TurntableRig(views_per_ring=12, width=192, height=144)
    cfg = SynthConfig(scene="torus", rig=rig, views=(0,), lens=OPENCV_LENS, supersample=2)
    cap = synthesize(cfg, gl_ctx)
    write_capture(cap, tmp_path / "lens", depth_format="exr")
    assert json.loads((tmp_path / "lens/transforms.json").read_text())["camera_model"] == "OPENCV"
    ss = read_scanset(tmp_path / "lens")
    with MeshRasterizer(gl_ctx) as r:
        r.set_mesh(cap.scene.mesh)
        for s in ss.scans:
            ref = r.render(s.camera).depth
            both = (ref > 0) & (s.depth > 0)
            # the same silhouette up to the nearest-sample quantisation of its edge (two resamplings)
            assert both.sum() > 0.98 * max((ref > 0).sum(), (s.depth > 0).sum())
            assert np.median(np.abs(ref - s.depth)[both]) < 2e-4                 # same depth (metres)

"""Synthetic captures that look like real ones: background, support in colour and depth, true matte on disk."""

from __future__ import annotations

import json

import numpy as np
import pytest

from capture.io import read_scanset
from datasets_synthetic.backdrop import support_layer, upward_radiance
from datasets_synthetic.lighting import resolve_env
from datasets_synthetic.rig import TurntableRig
from datasets_synthetic.synth import SynthConfig, synthesize, write_capture

TINY = TurntableRig(views_per_ring=6, width=96, height=72)


def test_support_depth_lies_on_its_plane():
    cam = TINY.cameras(0.12)[0]
    rad = upward_radiance(resolve_env("studio"), 1.0)
    col, cov, depth = support_layer(cam, "table", -0.1, 0.1, rad, supersample=2)
    pts = cam.depth_to_points(depth)[0]
    assert len(pts) > 0.3 * depth.size  # a table top fills the lower part of a 15-degree view
    assert np.abs(pts[:, 2] + 0.1).max() < 1e-6
    assert np.all(cov[depth > 0] > 0) and np.all(col[cov == 0] == 0)
    _, cov_disc, depth_disc = support_layer(cam, "disc", -0.1, 0.1, rad, supersample=2)
    r = np.hypot(*cam.depth_to_points(depth_disc)[0][:, :2].T)
    assert r.max() <= 0.16 + 1e-9 and cov_disc.sum() < cov.sum()


def test_room_capture_with_table_and_true_matte(tmp_path, gl_ctx):
    cfg = SynthConfig(scene="torus", rig=TINY, supersample=2, background="clutter", support="table",
                      background_frames="0::2")
    black = synthesize(SynthConfig(scene="torus", rig=TINY, supersample=2), gl_ctx)
    cap = synthesize(cfg, gl_ctx)
    z0 = cap.info["support"]["z0"]
    for i, (s, b) in enumerate(zip(cap.scanset.scans, black.scanset.scans, strict=True)):
        assert s.alpha is not None and np.array_equal(s.alpha, b.alpha)  # the matte is the object's alone
        if i % 2:  # held-out style: exactly the black capture
            assert np.array_equal(s.rgb, b.rgb) and np.array_equal(s.depth, b.depth)
            continue
        table = (s.depth > 0) & (b.depth == 0)
        assert table.mean() > 0.2
        assert np.abs(s.camera.depth_to_points(np.where(table, s.depth, 0))[0][:, 2] - z0).max() < 1e-4
        bg = s.alpha == 0
        assert s.linear_rgb[bg].mean() > 0.02  # the room or the table is visible behind the object
        assert np.allclose(s.rgb[s.alpha == 1], b.rgb[s.alpha == 1], atol=1e-5)
    # the matte of the object is partial on its rim, and written / read back as 8-bit mask_path
    a = cap.scanset.scans[0].alpha
    assert np.any((a > 0.05) & (a < 0.95))
    out = write_capture(cap, tmp_path / "room")
    meta = json.loads(out.read_text())
    assert all(fr["mask_path"].startswith("masks/") for fr in meta["frames"])
    back = read_scanset(out)
    for s, r in zip(cap.scanset.scans, back.scans, strict=True):
        assert np.abs(r.alpha - s.alpha).max() <= 0.5 / 255 + 1e-6
    # with a support the bounds come from the depth (table included), as a reader derives them
    assert back.bounds[1][0] - back.bounds[0][0] > 0.5


def test_config_rejects_unknown_background_and_support():
    with pytest.raises(ValueError, match="background must be one of"):
        SynthConfig(background="room")
    with pytest.raises(ValueError, match="support must be one of"):
        SynthConfig(support="chair")

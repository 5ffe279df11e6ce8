"""Relighting ground truth (datasets_synthetic/relight.py, furrow synth --relight-env)."""

from __future__ import annotations

import json

import numpy as np

from capture.io import read_scanset
from datasets_synthetic.lighting import LightingConfig
from datasets_synthetic.relight import relight_images, relit_files
from datasets_synthetic.rig import TurntableRig
from datasets_synthetic.sensor import SENSORS
from datasets_synthetic.synth import SynthConfig, synthesize, write_capture

TINY = TurntableRig(views_per_ring=12, width=96, height=72)


def _cfg(**kw):
    return SynthConfig(scene="furball", seed=1, rig=TINY, views=(0, 6), scene_params={"strands": 1500},
                       supersample=1, lighting=LightingConfig(env="studio", hair_env_lights=8), **kw)


def test_relit_under_the_capture_map_is_the_capture(gl_ctx):
    """Same scene, cameras, exposure: under its own map the relit images are the captured ones."""
    cfg = _cfg()
    cap = synthesize(cfg, gl_ctx)
    same, info = relight_images(cap, cfg, "studio", gl_ctx)
    for s, im in zip(cap.scanset.scans, same):
        np.testing.assert_allclose(im, s.rgb, atol=1e-6)
    assert info["exposure"] == cap.info["lighting"]["exposure"]
    other, info2 = relight_images(cap, cfg, "forest", gl_ctx)
    for s, im in zip(cap.scanset.scans, other):
        fg = s.depth > 0
        assert np.array_equal(im.sum(-1) > 0, s.rgb.sum(-1) > 0)  # same silhouette on black
        assert np.abs(im[fg] - s.rgb[fg]).mean() > 0.02 * s.rgb[fg].mean()  # different light
    assert info2["env"] != info["env"] and 0 <= info2["clipped_fraction"] <= 1


def test_relit_layout_reads_as_a_scan_set(tmp_path, gl_ctx):
    cfg = _cfg(sensor=SENSORS["d435"])
    cap = synthesize(cfg, gl_ctx)
    images, info = relight_images(cap, cfg, "sunset", gl_ctx)
    out = tmp_path / "cap"
    write_capture(cap, out, extra_files=relit_files(cap, images, info, "sunset"))
    main = read_scanset(out)
    relit = read_scanset(out / "relit" / "sunset")
    assert json.loads((out / "relit" / "sunset" / "lighting.json").read_text())["exposure"] == info["exposure"]
    for a, b, im in zip(main.scans, relit.scans, images):
        assert a.name == b.name
        assert np.array_equal(a.depth, b.depth)  # the capture's own depth files
        assert np.allclose(a.camera.cam_from_world, b.camera.cam_from_world) and np.allclose(a.camera.K, b.camera.K)
        from capture.scan import to_uint8_srgb

        assert np.array_equal(b.rgb, to_uint8_srgb(im))


def test_cli_relight_env(tmp_path, capsys):
    from furrow.cli import main

    out = tmp_path / "t"
    assert main(["synth", "torus", "-o", str(out), "--small", "--views", "4", "--relight-env", "forest"]) == 0
    ss = read_scanset(out / "relit" / "forest")
    assert len(ss) == 4 and ss.scans[0].rgb.shape == (120, 160, 3)
    assert main(["synth", "torus", "-o", str(tmp_path / "u"), "--small", "--relight-env", "nowhere"]) != 0
    assert "unknown environment" in capsys.readouterr().err

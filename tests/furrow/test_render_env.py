"""``furrow render --env`` composites the microfacet image into an environment map."""

from __future__ import annotations

import numpy as np

from capture.imageio import read_color
from capture.scan import to_uint8_srgb
from furrow.cli import main
from render.composite.pipeline import tonemap
from render.shading.envmap import bundled_envmap
from tests import scenes as scene
from tests.conftest import image_diff_stats
from tests.furrow.test_cmd_render import _transforms
from volume.model import save_model


def test_render_env_object_over_background(tmp_path):
    cams = scene.ring_cameras(12)
    model = scene.build_model(cams)
    save_model(model, tmp_path / "model")
    tj = _transforms(cams, tmp_path / "transforms.json")
    assert main(["render", str(tmp_path / "model"), "--cameras", str(tj), "--frames", "4",
                 "-o", str(tmp_path / "plain")]) == 0
    assert main(["render", str(tmp_path / "model"), "--cameras", str(tj), "--frames", "4", "-o", str(tmp_path / "env"),
                 "--env", "sunset", "--no-glare"]) == 0
    plain = read_color(tmp_path / "plain" / "cam_004.png")
    env = read_color(tmp_path / "env" / "cam_004.png")
    fg = model.rgbz.depth[4] > 0
    inner = fg & np.roll(fg, 2, 0) & np.roll(fg, -2, 0) & np.roll(fg, 2, 1) & np.roll(fg, -2, 1)
    # the object keeps its captured colour (through the same tone map) ...
    obj = to_uint8_srgb(tonemap(model.rgbz.rgb[4].astype(np.float64)))
    st = image_diff_stats(env, obj, inner)
    assert st["psnr"] > 35.0, st
    # ... and the background is the environment seen through the camera, not black
    bg = ~fg & ~np.roll(fg, 3, 0) & ~np.roll(fg, -3, 0) & ~np.roll(fg, 3, 1) & ~np.roll(fg, -3, 1)
    cam = cams[4]
    dirs = cam.pixel_rays(cam.pixel_grid()) @ cam.world_from_cam[:3, :3].T
    dirs /= np.linalg.norm(dirs, axis=-1, keepdims=True)
    from capture.orbit import estimate_up
    from render.composite.pipeline import rotation_to_z

    R = rotation_to_z(estimate_up(cams))
    expect = to_uint8_srgb(tonemap(bundled_envmap("sunset").sample(dirs @ R.T)))
    st_bg = image_diff_stats(env, expect, bg)
    assert st_bg["mean"] < 4.0, st_bg       # 8-bit levels; bilinear sampling differences only
    assert plain[bg].max() == 0


def test_env_options_need_env(tmp_path, capsys):
    assert main(["render", str(tmp_path / "m"), "--cameras", str(tmp_path / "t.json"), "-o", str(tmp_path / "o"),
                 "--ground"]) == 1
    assert "need --env" in capsys.readouterr().err

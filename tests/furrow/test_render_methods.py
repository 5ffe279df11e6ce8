"""``furrow render --method NAME``: every registered method through the one interface."""

from __future__ import annotations

import json

import numpy as np
import pytest

from capture.imageio import read_color
from capture.scan import to_uint8_srgb
from furrow.cli import main
from render.methods import METHODS, method_spec
from tests import scenes as scene
from tests.conftest import image_diff_stats
from tests.furrow.test_cmd_render import _transforms
from volume.model import save_model


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("methods")
    cams = scene.ring_cameras(12)
    model = scene.build_model(cams)
    save_model(model, tmp / "model")
    return tmp, model, _transforms(cams, tmp / "transforms.json")


@pytest.mark.parametrize("method", list(METHODS))
def test_every_method_renders_the_input_pose(setup, method):
    tmp, model, tj = setup
    out = tmp / method
    ss = 2 if method_spec(method).supersample else 1  # gather, points: one sample per pixel
    flags = ["--supersample", "2"] if ss == 2 else []
    assert main(["render", str(tmp / "model"), "--cameras", str(tj), "--frames", "4", "--method", method,
                 *flags, "-o", str(out)]) == 0
    img = read_color(out / "cam_004.png")
    fg = model.rgbz.depth[4] > 0
    # the object's input image, away from the silhouette (the mesh methods draw a marching-cubes mesh)
    inner = fg & np.roll(fg, 2, 0) & np.roll(fg, -2, 0) & np.roll(fg, 2, 1) & np.roll(fg, -2, 1)
    st = image_diff_stats(img, to_uint8_srgb(model.rgbz.rgb[4]), inner)
    assert st["psnr"] > 25.0, (method, st)
    stats = json.loads((out / "render_stats.json").read_text())
    assert stats["method"] == method
    assert stats["frames"][0]["supersample"] == ss and stats["frames"][0].get("facets", 1) > 0


def test_options_a_method_ignores_are_rejected(setup, capsys):
    tmp, _, tj = setup
    base = ["render", str(tmp / "model"), "--cameras", str(tj), "-o", str(tmp / "bad")]
    assert main(base + ["--method", "mesh-colour", "--tolerance", "4"]) == 1
    assert "--tolerance does not apply to --method mesh-colour" in capsys.readouterr().err
    assert main(base + ["--method", "mesh-vdtm", "--level", "8"]) == 1
    assert main(base + ["--method", "points", "--supersample", "2"]) == 1
    assert "--supersample does not apply to --method points" in capsys.readouterr().err
    assert not (tmp / "bad").exists()

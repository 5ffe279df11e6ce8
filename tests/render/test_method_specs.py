"""Adding a method is one folder and one registry line (docs/design.md "Adding a method"): a toy
method in a temporary package (on sys.path), registered by one line of render.methods.METHODS,
appears with its summary and its flag in ``furrow render --help``, renders through ``furrow render``
with that flag, is in the viewer's method list with its control, and in ``furrow eval``'s method
list, table and JSON; nothing else is edited."""

from __future__ import annotations

import json
import textwrap

import cv2
import numpy as np
import pytest

from capture.scan import linear_to_srgb
from furrow.cli import main
from render.methods import METHODS, eval_methods, method_names
from tests import scenes as scene
from tests.furrow.test_cmd_render import _transforms
from volume.model import save_model

#: The toy's own option: the grey level of its disc, and the value the tests set.
GREY_DEFAULT, GREY_SET = 0.5, 0.25

TOY_FILES = {
    "__init__.py": '''
        """The ``toy`` method (a test): ``gl.py`` its renderer, ``spec.py`` its spec; no ``reference.py``
        twin is needed for a numpy-only toy."""
        ''',
    "spec.py": f'''
        from dataclasses import dataclass

        from render.methods import Control, MethodSpec, option


        @dataclass(frozen=True)
        class ToyOptions:
            """The toy's own options."""

            #: Grey level (linear) of the toy's disc.
            grey: float = option({GREY_DEFAULT}, "grey level of the toy's disc", flag="--toy-grey",
                                 control=Control("slider", "toy grey", 0.0, 1.0, 0.05))


        SPEC = MethodSpec("toy", "toypkg.gl:ToyRenderer", "a grey disc in the middle of the frame",
                          options=ToyOptions)
        ''',
    "gl.py": '''
        import numpy as np

        from render.frame import Frame, FrameStats
        from render.methods import Renderer


        class ToyRenderer(Renderer):
            name = "toy"

            @classmethod
            def from_model(cls, ctx, model, options=None):
                return cls(ctx, options)

            def _render(self, camera, options, read):
                h, w = camera.height, camera.width
                y, x = np.mgrid[:h, :w]
                disc = ((x - w / 2) ** 2 + (y - h / 2) ** 2 < (min(w, h) / 3) ** 2).astype(np.float32)
                rgb = disc[..., None] * np.full(3, options.of(self.name).grey, np.float32)
                return Frame(rgb, disc, disc, FrameStats(0.0, 0.0, supersample=1))
        ''',
}


@pytest.fixture
def toy(tmp_path, monkeypatch):
    """The toy package written to a temporary folder on sys.path, and its one registry line."""
    pkg = tmp_path / "toypkg"
    pkg.mkdir()
    for name, text in TOY_FILES.items():
        (pkg / name).write_text(textwrap.dedent(text).lstrip())
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setitem(METHODS, "toy", "toypkg.spec:SPEC")  # the one line
    return pkg


def _help(capsys, command: str) -> str:
    with pytest.raises(SystemExit):
        main([command, "--help"])
    return capsys.readouterr().out


def test_toy_method_in_render_help_and_rendered_with_its_flag(toy, tmp_path, capsys):
    text = _help(capsys, "render")
    assert "toy" in text and "a grey disc in the middle of the frame" in text and "--toy-grey" in text
    cams = scene.ring_cameras(4)
    save_model(scene.build_model(cams), tmp_path / "model")
    tj = _transforms(cams, tmp_path / "transforms.json")
    base = ["render", str(tmp_path / "model"), "--cameras", str(tj), "--frames", "1"]
    assert main(base + ["--method", "toy", "--toy-grey", str(GREY_SET), "-o", str(tmp_path / "r")]) == 0
    img = cv2.imread(str(tmp_path / "r" / "cam_001.png"), cv2.IMREAD_UNCHANGED)  # BGRA, straight alpha
    h, w = img.shape[:2]
    want = round(255 * float(linear_to_srgb(np.float32(GREY_SET))))
    assert abs(int(img[h // 2, w // 2, 0]) - want) <= 1 and img[h // 2, w // 2, 3] == 255 and img[0, 0, 3] == 0
    stats = json.loads((tmp_path / "r" / "render_stats.json").read_text())
    assert stats["options"]["toy"] == {"grey": GREY_SET} and "facets" not in stats["frames"][0]
    capsys.readouterr()
    assert main(base + ["--method", "gather", "--toy-grey", "0.3", "-o", str(tmp_path / "bad")]) == 1
    assert "--toy-grey does not apply to --method gather" in capsys.readouterr().err


def test_toy_method_in_the_viewer(toy):
    from render.viewer import gui
    from render.viewer.settings import ViewSettings
    from tests.render.viewer.fake_gui import FakeGui

    assert "toy" in method_names()
    fake = FakeGui()
    controls = gui.build_controls(fake, ViewSettings(), env_names=())  # methods: the registry's
    assert "toy" in fake.handles["method"].options and not fake.handles["toy grey"].visible
    applied = []
    gui.on_settings_change(controls, applied.append, lambda msg: None)
    fake.handles["method"].set("toy")
    assert fake.handles["toy grey"].visible and fake.handles["supersampling"].disabled
    fake.handles["toy grey"].set(0.8)
    assert applied[-1].method == "toy" and applied[-1].options.of("toy").grey == 0.8


def test_toy_method_in_eval(toy, tmp_path, capsys):
    from capture.io import write_transforms
    from tests.scenes import make_scanset, scan_ring, sphere_scene

    assert "toy" in eval_methods()
    text = _help(capsys, "eval")
    assert "a grey disc in the middle of the frame" in text and "--toy-grey" in text and "`toy`" in text
    cap = tmp_path / "sphere"
    write_transforms(make_scanset(sphere_scene(), scan_ring(8, 64, 48)), cap)
    js = tmp_path / "e.json"
    rc = main(["eval", str(cap), "--holdout", "2", "--max-res", "16", "--mesh-level", "16", "--max-views", "1",
               "--methods", "toy,gather", "--toy-grey", str(GREY_SET), "--json", str(js), "-o", str(tmp_path / "e")])
    out = capsys.readouterr()
    assert rc == 0, out.err
    res = json.loads(js.read_text())
    assert res["methods"] == ["toy", "gather"] and np.isfinite(res["toy"]["psnr"])
    assert np.isnan(res["toy"]["facets"]) and res["options"]["toy"] == {"grey": GREY_SET}
    table = out.out + out.err
    assert any(line.strip("│┃ ").startswith("toy") for line in table.splitlines()), table

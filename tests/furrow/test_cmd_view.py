"""``furrow view`` without a browser: bad input gives a one-line error and a non-zero exit; the
GL thread serves jobs, drops unwanted ones and releases everything on close."""

from __future__ import annotations

import socket

import numpy as np
import pytest

from furrow.cli import main
from tests import scenes as scene
from volume.model import save_model


@pytest.fixture(scope="module")
def model_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("viewcli") / "model"
    save_model(scene.build_model(scene.ring_cameras(6, 64, 48)), d)
    return d


def one_line_error(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert "Traceback" not in err
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:"), err
    return lines[0]


def test_missing_and_corrupt_model(tmp_path, capsys):
    assert main(["view", str(tmp_path / "nope"), "--port", "0"]) == 1
    assert "no such model folder" in one_line_error(capsys)
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "model.json").write_text("{not json")
    assert main(["view", str(bad), "--port", "0"]) == 1
    assert "model.json" in one_line_error(capsys)


def test_port_in_use(model_dir, capsys):
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        assert main(["view", str(model_dir), "--port", str(port)]) == 1
    assert f"port {port}" in one_line_error(capsys)


def test_unknown_map_and_method(model_dir, tmp_path, capsys):
    assert main(["view", str(model_dir), "--port", "0", "--env", "nosuchmap"]) == 1
    assert "nosuchmap" in one_line_error(capsys)
    assert main(["view", str(model_dir), "--port", "0", "--env", str(tmp_path / "missing.exr")]) == 1
    assert "missing.exr" in one_line_error(capsys)
    assert main(["view", str(model_dir), "--port", "0", "--method", "nosuch"]) == 1
    assert "nosuch" in one_line_error(capsys)


@pytest.mark.gl
def test_gl_worker_jobs_and_release(model_dir):
    from capture.camera import Camera
    from render.viewer.gl_worker import GLWorker
    from render.viewer.settings import ViewSettings
    from render.viewer.views import draw
    from volume.model import load_model

    model = load_model(model_dir)
    cam = model.rgbz.cameras[0]
    w = GLWorker(model)
    drawn = w.call(lambda sc: draw(sc, cam, ViewSettings(), 1))
    # the viewer's picture of an input camera is that camera's image (8-bit sRGB)
    from capture.scan import to_uint8_srgb

    ref = to_uint8_srgb(model.rgbz.rgb[0])
    mask = (model.rgbz.depth[0] > 0) | (drawn.image.max(-1) > 0)
    assert np.abs(drawn.image.astype(float) - ref)[mask].mean() < 6.0
    assert w.submit(lambda sc: 1, wanted=lambda: False).result() is None   # unwanted: dropped unrun
    depth = w.call(lambda sc: draw(sc, cam, ViewSettings(view="depth"), 1)).image
    assert (depth.max(-1) > 0).sum() == (drawn.image.max(-1) > 0).sum() or depth.any()
    assert isinstance(cam, Camera)
    assert w.close() and w.released
    with pytest.raises(RuntimeError, match="closed"):
        w.submit(lambda sc: 1).result()


@pytest.mark.gl
def test_viewer_starts_and_closes(model_dir, tmp_path):
    import json

    from render.viewer.server import Viewer
    from volume.model import load_model

    model = load_model(model_dir)
    v = Viewer(model, model.rgbz.cameras, port=0, out_dir=tmp_path)
    assert v.url.startswith("http://127.0.0.1:") and v.port > 0
    specs = v.frustum_specs()
    assert len(specs) == len(model.rgbz.cameras)
    cam = model.rgbz.cameras[3]
    from viser.transforms import SO3

    # viser's frustum pose is R_world_camera in OpenCV axes, as furrow's: no flip
    np.testing.assert_allclose(SO3(specs[3]["wxyz"]).as_matrix(), cam.world_from_cam[:3, :3], atol=1e-9)
    np.testing.assert_allclose(specs[3]["position"], cam.center)
    assert specs[3]["image"].dtype == np.uint8 and specs[3]["aspect"] == cam.width / cam.height
    assert v.close(tmp_path / "stats.json")
    assert json.loads((tmp_path / "stats.json").read_text()) == {"frames": []}


@pytest.mark.gl
def test_screenshot_and_turntable_export(model_dir, tmp_path, monkeypatch):
    """The screenshot button's PNG and the MP4 export (progress shown, frames at full size), as
    files under --out and as downloads sent to the client."""
    from types import SimpleNamespace

    import imageio_ffmpeg
    from viser.transforms import SO3

    from capture.imageio import read_color
    from render.viewer.server import Viewer
    from render.viewer.session import Session, ViewCamera
    from volume.model import load_model

    model = load_model(model_dir)
    v = Viewer(model, model.rgbz.cameras, port=0, out_dir=tmp_path)
    try:
        downloads = []
        client = SimpleNamespace(send_file_download=lambda name, data: downloads.append((name, data)))
        session = Session(v.worker, send=lambda *a: None)
        cam = model.rgbz.cameras[2]
        fov = 2 * np.arctan(0.5 * cam.height / cam.K[1, 1])
        session.update_camera(ViewCamera(tuple(SO3.from_matrix(cam.world_from_cam[:3, :3]).wxyz), tuple(cam.center),
                                         fov, 64, 48))
        notes = []
        png = v.screenshot(client, session, notes.append)
        assert notes == [] and png is not None and downloads[0][0] == png.name
        img = read_color(png)
        assert img.shape[:2] == (48, 64) and img.max() > 0
        progress = []
        widget = lambda: SimpleNamespace(value=None, visible=False, disabled=False)
        controls = SimpleNamespace(export_kind=SimpleNamespace(value="turntable"),
                                   export_frames=SimpleNamespace(value=5), export_fps=SimpleNamespace(value=10),
                                   export=widget(), progress=widget())
        orig = Viewer._render_full

        def spy(self, *a):
            progress.append(controls.progress.visible)
            return orig(self, *a)

        monkeypatch.setattr(Viewer, "_render_full", spy)
        mp4 = v.export(client, session, controls, notes.append)
        assert notes == [] and mp4 is not None and mp4.suffix == ".mp4" and downloads[-1][0] == mp4.name
        assert progress == [True] * 5 and controls.progress.value == 100.0 and not controls.progress.visible
        gen = imageio_ffmpeg.read_frames(str(mp4))
        meta = next(gen)
        assert meta["size"] == (64, 48) and len(list(gen)) == 5
    finally:
        assert v.close()


def test_llvmpipe_thread_cap(monkeypatch):
    """``furrow view`` leaves a core to the browser: LP_NUM_THREADS = the cores less one (at least
    1) unless asked otherwise, for the block that makes the GL context; a value already in the
    environment wins; nothing is left behind."""
    import os

    from render.viewer.gl_worker import llvmpipe_threads

    monkeypatch.delenv("LP_NUM_THREADS", raising=False)
    monkeypatch.setattr(os, "cpu_count", lambda: 2)
    with llvmpipe_threads() as n:
        assert n == 1 and os.environ["LP_NUM_THREADS"] == "1"
    assert "LP_NUM_THREADS" not in os.environ
    monkeypatch.setattr(os, "cpu_count", lambda: 1)
    with llvmpipe_threads() as n:
        assert n == 1
    with llvmpipe_threads(3) as n:
        assert n == 3 and os.environ["LP_NUM_THREADS"] == "3"
        with llvmpipe_threads(5) as inner:
            assert inner == 3                                          # the environment's wins
        assert os.environ["LP_NUM_THREADS"] == "3"
    assert "LP_NUM_THREADS" not in os.environ
    with pytest.raises(ValueError):
        with llvmpipe_threads(0):
            pass


def test_software_rasteriser_is_told_from_the_renderer_name():
    """The viewer models frame cost in CPU time on a software rasteriser only."""
    from types import SimpleNamespace

    from render.viewer.gl_worker import is_software

    assert is_software(SimpleNamespace(info={"GL_RENDERER": "llvmpipe (LLVM 15.0.6, 256 bits)"}))
    assert not is_software(SimpleNamespace(info={"GL_RENDERER": "NVIDIA H200/PCIe/SSE2"}))
    assert not is_software(SimpleNamespace(info={}))

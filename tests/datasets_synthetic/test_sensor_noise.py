"""scripts/add_sensor_noise.py: a capture's kept frames with independent sensor noise of a stated sigma, the
other frames and every other entry untouched (docs/matting.md "Sensor noise behind the object")."""

from __future__ import annotations

import importlib.util
import json

import numpy as np
import pytest

from capture.imageio import read_color, write_png
from tests.conftest import REPO_DIR


def _script():
    spec = importlib.util.spec_from_file_location("add_sensor_noise", REPO_DIR / "scripts" / "add_sensor_noise.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _capture(root, n=4):
    (root / "images").mkdir(parents=True)
    (root / "depth").mkdir()
    rng = np.random.default_rng(0)
    frames = []
    for i in range(n):
        write_png(root / "images" / f"v{i}.png", rng.integers(20, 236, (60, 80, 3)).astype(np.uint8))
        frames.append({"file_path": f"images/v{i}.png"})
    (root / "transforms.json").write_text(json.dumps({"frames": frames}))
    return frames


def test_the_kept_frames_get_noise_of_the_stated_sigma_and_the_rest_stay(tmp_path):
    """sigma 2: each kept frame's difference from the original has sd within 5 % of 2 (measured 2.01-2.03 over
    14,400 values: rounding adds 1/12 of a step in variance) and mean within 0.1; the held-out frames are copied
    bit for bit; a second run with the same seed gives the same images; depth is linked, not copied."""
    src, out, out2 = tmp_path / "cap", tmp_path / "noisy", tmp_path / "noisy2"
    frames = _capture(src)
    ns = _script()
    ns.main([str(src), str(out), "--sigma", "2"])
    ns.main([str(src), str(out2), "--sigma", "2"])
    for i, fr in enumerate(frames):
        a, b = read_color(src / fr["file_path"]).astype(float), read_color(out / fr["file_path"]).astype(float)
        if i % 2:
            assert np.array_equal(a, b)
        else:
            d = b - a
            assert abs(d.std() - 2.0) <= 0.1 and abs(d.mean()) <= 0.1
        assert np.array_equal(b, read_color(out2 / fr["file_path"]).astype(float))
    assert (out / "depth").is_symlink() and (out / "transforms.json").is_symlink()


@pytest.mark.parametrize("argv, message", [(["--sigma", "0"], "--sigma must be > 0"),
                                           (["--sigma", "1", "--frames", "x"], "bad frame spec")])
def test_bad_arguments_say_what_is_wrong(tmp_path, argv, message):
    src = tmp_path / "cap"
    _capture(src)
    with pytest.raises(SystemExit, match=message):
        _script().main([str(src), str(tmp_path / "o"), *argv])


def test_a_capture_without_transforms_is_refused(tmp_path):
    with pytest.raises(SystemExit, match="no transforms.json"):
        _script().main([str(tmp_path), str(tmp_path / "o"), "--sigma", "1"])


def test_camera_noise_is_correlated_as_a_camera_leaves_it(tmp_path):
    """--camera on mid grey (sRGB 124, linear about CAMERA_GREY): the kept frames' difference has an sd between 0.4
    and 1.0 x sigma 3 (bilinear demosaicing leaves 0.75-0.8 x an independent noise, JPEG takes some more), its
    mean within 0.5 step; capture.noise's finest level reads it under a step and the two-scale reading at least 1.5
    (the correlation a demosaicing and JPEG leave); the held-out frames stay bit for bit."""
    from capture import noise

    src, out = tmp_path / "cap", tmp_path / "cam"
    (src / "images").mkdir(parents=True)
    frames = []
    for i in range(2):
        write_png(src / "images" / f"v{i}.png", np.full((96, 128, 3), 124, np.uint8))
        frames.append({"file_path": f"images/v{i}.png"})
    (src / "transforms.json").write_text(json.dumps({"frames": frames}))
    _script().main([str(src), str(out), "--sigma", "3", "--camera"])
    kept = read_color(out / "images" / "v0.png")
    d = kept.astype(float) - 124.0
    assert 1.2 <= d.std() <= 3.0 and abs(d.mean()) <= 0.5, (d.std(), d.mean())
    assert noise._level(kept.astype(np.int16), [None], 2) < 1.0 <= 1.5 <= noise.frame_noise(kept)
    assert np.array_equal(read_color(out / "images" / "v1.png"), read_color(src / "images" / "v1.png"))

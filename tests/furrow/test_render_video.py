"""`furrow render --orbit N --video out.mp4`: an H.264 MP4 of N frames of the right size, decoded here by
OpenCV (not the library that wrote it), whose frames match the PNG renders of the same orbit."""

from __future__ import annotations

import json

import cv2
import numpy as np

from capture.imageio import read_color
from furrow.cli import main
from tests import scenes as scene
from volume.model import save_model

#: Mean absolute difference (8-bit levels) between a decoded H.264 frame and its PNG (quality 8, yuv420p).
MEAN_ABS_TOL = 4.0
ORBIT = 10


def _decode(path):
    cap = cv2.VideoCapture(str(path))
    frames = []
    while True:
        ok, bgr = cap.read()
        if not ok:
            break
        frames.append(bgr[..., ::-1])
    fourcc = int(cap.get(cv2.CAP_PROP_FOURCC))
    cap.release()
    return frames, "".join(chr((fourcc >> 8 * i) & 0xFF) for i in range(4))


def test_orbit_video(tmp_path, capsys):
    cams = scene.ring_cameras(8, 64, 48)
    save_model(scene.build_model(cams), tmp_path / "model")
    tj = tmp_path / "transforms.json"
    tj.write_text(json.dumps({"frames": [{"file_path": f"images/{c.name}", **c.to_nerfstudio()} for c in cams]}))
    video = tmp_path / "orbit.mp4"
    assert main(["render", str(tmp_path / "model"), "--cameras", str(tj), "--orbit", str(ORBIT), "--video", str(video),
                 "-o", str(tmp_path / "png"), "--fps", "12"]) == 0
    assert f"wrote{ORBIT}framesto{video}" in "".join(capsys.readouterr().err.split())   # however rich wraps it
    frames, codec = _decode(video)
    assert len(frames) == ORBIT and codec.lower() in ("avc1", "h264")
    assert all(f.shape == (48, 64, 3) for f in frames)
    pngs = sorted((tmp_path / "png").glob("*.png"))
    assert len(pngs) == ORBIT
    errs = [np.abs(f.astype(float) - read_color(p).astype(float)).mean() for f, p in zip(frames, pngs)]
    assert max(errs) < MEAN_ABS_TOL, errs
    # the order is right: frame 0 matches PNG 0 better than PNG 5 (the orbit moves)
    assert np.abs(frames[0].astype(float) - read_color(pngs[5]).astype(float)).mean() > 2 * errs[0]


def test_video_only_and_bad_arguments(tmp_path, capsys):
    cams = scene.ring_cameras(4, 32, 24)
    save_model(scene.build_model(cams), tmp_path / "model")
    tj = tmp_path / "transforms.json"
    tj.write_text(json.dumps({"frames": [{"file_path": f"images/{c.name}", **c.to_nerfstudio()} for c in cams]}))
    base = ["render", str(tmp_path / "model"), "--cameras", str(tj)]
    assert main([*base, "--orbit", "3", "--video", str(tmp_path / "v.mp4")]) == 0
    assert len(_decode(tmp_path / "v.mp4")[0]) == 3 and sorted(p.name for p in tmp_path.iterdir()) == [
        "model", "transforms.json", "v.mp4"]
    assert main(base) == 1
    assert "-o DIR" in capsys.readouterr().err
    assert main([*base, "--video", str(tmp_path / "v.avi")]) == 1
    assert "mp4" in capsys.readouterr().err

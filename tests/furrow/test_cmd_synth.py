"""``furrow synth``: the small capture, refusals with clear errors, and the ChArUco board option."""

from __future__ import annotations

import pytest

from capture.io import read_scanset


def test_cli_synth_small(tmp_path, capsys):
    from furrow.cli import main

    out = tmp_path / "torus"
    assert main(["synth", "torus", "-o", str(out), "--small", "--preview"]) == 0
    ss = read_scanset(out)
    assert len(ss) == 12 and ss.scans[0].rgb.shape == (120, 160, 3)
    assert (out / "preview.png").is_file() and (out / "gt" / "mesh.ply").is_file()
    assert main(["synth", "torus", "-o", str(out), "--small"]) != 0  # exists, no --overwrite
    assert main(["synth", "teapot", "-o", str(tmp_path / "x")]) != 0
    assert main(["synth", "torus", "-o", str(tmp_path / "y"), "--views", "7", "--elevations", "10,40"]) != 0
    err = capsys.readouterr().err
    assert "already exists" in err and "unknown scene" in err and "multiple" in err


def test_cli_synth_board_is_in_the_ground_truth(tmp_path):
    import json

    from furrow.cli import main

    out = tmp_path / "b"
    assert main(["synth", "torus", "-o", str(out), "--small", "--views", "2", "--board"]) == 0
    scene = json.loads((out / "gt" / "scene.json").read_text())
    board = scene["params"]["board"] if "params" in scene else scene["board"]
    assert board["squares"] == [7, 7] and board["z_m"] < 0


def test_cli_synth_renderer_choice_is_recorded(tmp_path, capsys):
    """--synth-renderer gl (default) and numpy both write a capture; gt/scene.json says which."""
    import json

    from furrow.cli import main

    for kind in ("gl", "numpy"):
        out = tmp_path / kind
        args = ["synth", "furball", "-o", str(out), "--small", "--views", "2", "--strands", "300"]
        assert main(args + ([] if kind == "gl" else ["--synth-renderer", kind])) == 0
        scene = json.loads((out / "gt" / "scene.json").read_text())
        assert scene["renderer"] == kind and scene["hair"]["renderer"] == kind
    with pytest.raises(SystemExit):  # argparse: invalid choice
        main(["synth", "torus", "-o", str(tmp_path / "z"), "--synth-renderer", "cuda"])

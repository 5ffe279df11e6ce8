"""`furrow batch` on a local Ray cluster with 2 workers: three small synthetic captures, one with a
corrupt depth PNG -- two complete, the third reported by name, exit status 1, batch.json complete;
a second run skips the two complete captures and does not touch their outputs."""

from __future__ import annotations

import json

import cv2
import pytest

from furrow.batch import STEPS, CaptureConfig, is_complete, parse_steps, run_capture
from furrow.cli import main
from volume.pipeline.config import FuseConfig, PipelineConfig
from volume.pyramid import LoptConfig

pytest.importorskip("ray", reason="furrow batch needs the cluster extra (make test installs it)")

ORBIT_FRAMES = 4
BATCH_ARGS = ["--workers", "2", "--max-res", "32", "--orbit-frames", str(ORBIT_FRAMES)]


@pytest.fixture(scope="module")
def captures(tmp_path_factory):
    root = tmp_path_factory.mktemp("batch")
    for name in ("fur", "plant", "torus"):
        scene = {"fur": "furball"}.get(name, name)
        assert main(["synth", scene, "-o", str(root / name), "--small", "--views", "8"]) == 0
    bad = sorted((root / "plant" / "depth").glob("*.png"))[3]
    bad.write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(40))   # a truncated PNG: corrupt depth
    return root, bad


def test_batch_two_done_one_failed_then_skipped(captures, capsys):
    root, bad = captures
    out = root / "out"
    caps = [str(root / n) for n in ("fur", "plant", "torus")]
    assert main(["batch", *caps, "-o", str(out), *BATCH_ARGS]) == 1
    err = capsys.readouterr().err
    assert "failed plant: ScanIOError:" in err and bad.name in err and "2 done, 0 skipped, 1 failed" in err
    batch = json.loads((out / "batch.json").read_text())
    recs = batch["captures"]
    assert set(recs) == {"fur", "plant", "torus"} and batch["summary"]["failed"] == 1
    for name in ("fur", "torus"):
        r = recs[name]
        assert r["status"] == "done" and set(r["stages"]) == {"read", *STEPS}
        assert r["scores"]["microfacet"]["psnr"] > 10 and r["orbit_frames"] == ORBIT_FRAMES
        assert (out / name / "model" / "model.json").is_file() and (out / name / "eval.json").is_file()
        cap = cv2.VideoCapture(str(out / name / "orbit.mp4"))
        assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == ORBIT_FRAMES
        cap.release()
        assert is_complete(out / name, STEPS)
    failed = recs["plant"]
    assert failed["status"] == "failed" and str(bad) in failed["reason"] and "\n" not in failed["reason"]
    assert not (out / "plant" / "done.json").exists()
    # one process per capture (max_calls=1 recycles the two workers)
    assert len({recs[n]["pid"] for n in recs}) == 3
    # second run: the complete captures are skipped, their files untouched
    stamp = {n: (out / n / "done.json").stat().st_mtime_ns for n in ("fur", "torus")}
    assert main(["batch", *caps, "-o", str(out), *BATCH_ARGS]) == 1
    err = capsys.readouterr().err
    assert "0 done, 2 skipped, 1 failed" in err
    again = json.loads((out / "batch.json").read_text())["captures"]
    assert [again[n]["status"] for n in ("fur", "plant", "torus")] == ["skipped", "failed", "skipped"]
    assert {n: (out / n / "done.json").stat().st_mtime_ns for n in ("fur", "torus")} == stamp


def test_run_capture_is_a_plain_function(captures, tmp_path):
    """The task body without Ray: steps in order, done.json last, a failure leaves no done.json."""
    root, bad = captures
    small = CaptureConfig(pipeline=PipelineConfig(fuse=FuseConfig(lopt=LoptConfig(max_res=32))))
    rec = run_capture(root / "torus", tmp_path / "t", ("model",), small)
    assert rec["status"] == "done" and set(rec["stages"]) == {"read", "model"}
    assert is_complete(tmp_path / "t", ("model",)) and not is_complete(tmp_path / "t", ("model", "orbit"))
    partial: dict = {}
    with pytest.raises(ValueError, match=bad.name):
        run_capture(root / "plant", tmp_path / "p", ("model",), small, record=partial)
    assert "read" in partial["stages"] and not (tmp_path / "p" / "done.json").exists()


def test_flagged_registration_and_bad_steps(captures, tmp_path):
    root, _ = captures
    import shutil

    shutil.copytree(root / "torus", tmp_path / "reg")
    (tmp_path / "reg" / "registration.json").write_text(json.dumps({"flagged": ["images/r0_v002.png"]}))
    with pytest.raises(ValueError, match="registration flagged 1 scan"):
        run_capture(tmp_path / "reg", tmp_path / "o", ("model",))
    assert parse_steps("orbit, model") == ("model", "orbit")
    with pytest.raises(ValueError, match="unknown mesh"):
        parse_steps("model,mesh")

"""`furrow check`: a capture's first stages only, a table of checks, exit 1 when one fails."""

from __future__ import annotations

import json
import shutil

import pytest

from capture.io import write_transforms
from furrow.cli import main
from tests.scenes import make_scanset, scan_ring, sphere_scene


@pytest.fixture(scope="module")
def scan_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("check") / "sphere"
    write_transforms(make_scanset(sphere_scene(), scan_ring(8, 64, 48), noise=0.0005), out)
    return out


def _check(path, capsys, *flags):
    rc = main(["check", str(path), *flags])
    out = capsys.readouterr()
    return rc, out.out, " ".join(out.err.split()) + " " + " ".join(out.out.split())


def test_a_right_capture_passes_every_check(scan_dir, capsys, tmp_path):
    rc, out, said = _check(scan_dir, capsys, "--json")
    rec = json.loads(out.strip().splitlines()[-1])
    assert rc == 0, said
    assert [c["check"] for c in rec["checks"]] == ["frames", "views", "depth against poses", "depth against colour",
                                                   "depth files against frames"]
    fr = rec["records"]["frames"]
    assert fr["views"] == 8 and fr["size"] == [64, 48] and 0.05 < fr["depth_share"] < 1
    assert 0.2 < fr["depth_median_m"] < 2.0  # the ring's sphere, metres
    assert all(c["passed"] for c in rec["checks"]) and "FAIL" not in said
    assert rec["records"]["depth agreement"]["status"] == "agree"
    assert "furrow check: stage timings" in said and "extent" not in said  # the first stages only
    assert not (tmp_path / "model").exists()


def test_focal_lengths_off_fail_with_what_to_fix(scan_dir, capsys, tmp_path):
    """fl_x, fl_y x 1.3: exit 1, the depth-against-poses row fails with the factor that undoes it."""
    d = shutil.copytree(scan_dir, tmp_path / "focal")
    meta = json.loads((d / "transforms.json").read_text())
    for f in [meta, *meta["frames"]]:
        for key in ("fl_x", "fl_y"):
            if key in f:
                f[key] *= 1.3
    (d / "transforms.json").write_text(json.dumps(meta))
    rc, out, said = _check(d, capsys)
    assert rc == 1 and "FAIL" in said and "every focal length (fl_x, fl_y) is 0.7" in said, said


def test_an_unreadable_capture_is_an_error_naming_the_file(tmp_path, capsys):
    (tmp_path / "transforms.json").write_text("{not json")
    rc, out, said = _check(tmp_path, capsys)
    assert rc == 1 and "transforms.json" in said and "Traceback" not in said, said


def test_inverted_mattes_fail_and_fix_turns_them(scan_dir, capsys, tmp_path):
    """Masks written white where the object is not (mask_path): furrow check fails them against the depth; furrow
    model --depth-agreement fix turns them over (and says so), the default only warns."""
    import cv2
    import numpy as np

    from volume.model import load_model

    d = shutil.copytree(scan_dir, tmp_path / "masked")
    meta = json.loads((d / "transforms.json").read_text())
    (d / "masks").mkdir()
    for f in meta["frames"]:
        z = cv2.imread(str(d / f["depth_file_path"]), cv2.IMREAD_UNCHANGED)
        cv2.imwrite(str(d / "masks" / (f["file_path"].split("/")[-1].rsplit(".", 1)[0] + ".png")),
                    np.where(z > 0, 0, 255).astype(np.uint8))  # inverted: the object black
        f["mask_path"] = "masks/" + f["file_path"].split("/")[-1].rsplit(".", 1)[0] + ".png"
    (d / "transforms.json").write_text(json.dumps(meta))
    rc, out, said = _check(d, capsys)
    assert rc == 1 and "given mattes against depth" in said and "are they inverted" in said, said
    for flags, applied in (((), None), (("--depth-agreement", "fix"), True)):
        m = tmp_path / f"m{len(flags)}"
        rc = main(["model", str(d), "-o", str(m), "--max-res", "16", *flags])
        said = " ".join(capsys.readouterr().err.split())
        rec = load_model(m).params["depth_agreement"]["given_matte"]
        assert rc == 0 and rec["inverted"] and rec.get("inverted_applied") == applied, (rec, said)
        assert ("every given matte inverted" in said) == bool(flags)


def test_depth_files_of_the_next_frame_fail(tmp_path, capsys):
    """Three spheres, each frame given the next frame's depth file (a stream that dropped a frame): the depths still
    agree with the poses (a ring's views i + 1, j + 1 stand as i, j do), the colour's edges do not; the right
    capture passes the row."""
    from tests.scenes import spheres_scene

    d = tmp_path / "spheres"
    write_transforms(make_scanset(spheres_scene(), scan_ring(16, 128, 96), noise=0.0005), d)
    rc, out, said = _check(d, capsys, "--json")
    row = {c["check"]: c for c in json.loads(out.strip().splitlines()[-1])["checks"]}["depth files against frames"]
    assert rc == 0 and row["passed"], said
    frames = json.loads((d / "transforms.json").read_text())["frames"]
    data = [(d / f["depth_file_path"]).read_bytes() for f in frames]
    for i, f in enumerate(frames):
        (d / f["depth_file_path"]).write_bytes(data[(i + 1) % len(frames)])
    rc, out, said = _check(d, capsys, "--json")
    rec = json.loads(out.strip().splitlines()[-1])
    row = {c["check"]: c for c in rec["checks"]}["depth files against frames"]
    assert rc == 1 and not row["passed"] and "depth_file_path" in row["found"], said
    assert rec["records"]["depth agreement"]["status"] == "agree"  # the poses alone see nothing

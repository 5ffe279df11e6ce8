"""`furrow model` on depth stored the wrong way (capture/depth_readings.py, capture/depth_pairing.py,
capture/colour_flip.py): flipped, along the rays, paired with another frame, colour flipped against it; each
warned, and undone by --depth-agreement fix where it can be (docs/capture_formats.md)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from capture.io import write_transforms
from tests.furrow.test_cmd_model import _copy, _run
from tests.scenes import make_scanset, scan_ring
from volume.model import load_model


@pytest.fixture(scope="module")
def spheres_dir(tmp_path_factory):
    """Three spheres of a ring of 12 views (one sphere alone looks the same flipped, and spans too narrow an angle
    for depth along the rays to differ from z-depth by more than the check's 1 %)."""
    from tests.scenes import spheres_scene

    out = tmp_path_factory.mktemp("scans") / "spheres"
    write_transforms(make_scanset(spheres_scene(), scan_ring(12, 96, 72), noise=0.0005), out)
    return out


def _ranged(z, f, meta):
    """A 16-bit z-depth map as the distance along each pixel's ray (transforms.json's corner-origin cx, cy)."""
    from capture.camera import cv_from_corner

    fx, fy = f.get("fl_x", meta.get("fl_x")), f.get("fl_y", meta.get("fl_y"))
    cx, cy = cv_from_corner(f.get("cx", meta.get("cx"))), cv_from_corner(f.get("cy", meta.get("cy")))
    ys, xs = np.mgrid[0:z.shape[0], 0:z.shape[1]]
    r = z * np.sqrt(1 + ((xs - cx) / fx) ** 2 + ((ys - cy) / fy) ** 2)
    return np.clip(np.rint(r), 0, 65535).astype(z.dtype)


@pytest.mark.parametrize("name, said", [("range", "distances along each pixel's ray"),
                                        ("upside down", "stored upside down")])
def test_depth_stored_as_range_or_upside_down_is_named_and_fixed(spheres_dir, tmp_path, capsys, name, said):
    """Every depth pixel the distance along its ray (a ray tracer's hit distance), or every depth map stored bottom
    row first: furrow model names the reading, and --depth-agreement fix reads the depth as it was meant."""
    import cv2

    d = _copy(spheres_dir, tmp_path / "stored")
    meta = json.loads((d / "transforms.json").read_text())
    for f in meta["frames"]:
        p = d / f["depth_file_path"]
        z = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
        cv2.imwrite(str(p), _ranged(z, f, meta) if name == "range" else np.ascontiguousarray(z[::-1]))
    for flags in ((), ("--depth-agreement", "fix")):
        out = tmp_path / f"r{len(flags)}"
        rc, _, err = _run(["model", str(d), "-o", str(out), "--max-res", "16", *flags], capsys)
        flat = " ".join(err.split())
        rec = load_model(out).params["depth_agreement"]
        assert rc == 0 and rec["status"] == "depth reading", (rec["reading"], flat)
        assert rec["reading"]["reading"] == name, rec["reading"]
        assert said in flat and "This model may be wrong" in flat, flat
        assert rec.get("reading_applied") == (name if flags else None), rec
        assert ("were read as z-depth" in flat or "were flipped back (upside down" in flat) == bool(flags), flat
    rc, _, err = _run(["model", str(spheres_dir), "-o", str(tmp_path / "right"), "--max-res", "16"], capsys)
    rec = load_model(tmp_path / "right").params["depth_agreement"]
    assert rc == 0 and rec["status"] == "agree" and rec["reading"]["status"] == "as stored", rec["reading"]


def test_colour_stored_upside_down_is_named_and_no_shift_is_made(spheres_dir, tmp_path, capsys):
    """Every colour image stored bottom row first, the depth and poses right: furrow model says the colour and the
    depth sit flipped against each other, judges no shift of the colour's edges, and --depth-agreement fix makes
    none (it had moved the depth by a shift the flip left)."""
    import cv2

    d = _copy(spheres_dir, tmp_path / "stored")
    for f in json.loads((d / "transforms.json").read_text())["frames"]:
        p = d / f["file_path"]
        cv2.imwrite(str(p), np.ascontiguousarray(cv2.imread(str(p), cv2.IMREAD_UNCHANGED)[::-1]))
    for flags in ((), ("--depth-agreement", "fix")):
        out = tmp_path / f"c{len(flags)}"
        rc, _, err = _run(["model", str(d), "-o", str(out), "--max-res", "16", *flags], capsys)
        flat = " ".join(err.split())
        rec = load_model(out).params["depth_agreement"]
        flip = rec.get("colour_flip") or {}
        assert rc == 0 and rec["status"] == "agree" and flip.get("flipped") and flip["flip"] == "upside down", rec
        assert "mirrored (upside down), fit the colour images" in flat, flat
        assert not rec["colour_offset"] and "colour_offset_applied" not in rec, rec


def _agreed_depths(path, fix: bool) -> dict:
    """Each view's depth (name -> array) after the depth-agreement stage of ``path``, with or without its fix."""
    from dataclasses import replace

    from capture.depth_agreement import AgreementConfig
    from capture.sources import open_source
    from volume.pipeline import runner
    from volume.pipeline.config import PipelineConfig
    from volume.pipeline.stages import STAGES

    upto = STAGES[: [s.name for s in STAGES].index("depth agreement") + 1]
    run = runner.run_pipeline(open_source(path), replace(PipelineConfig(), agreement=AgreementConfig(fix=fix)),
                              stages=upto)
    try:
        return {s.name: np.asarray(s.depth, np.float32).copy() for s in run.work.scans}
    finally:
        run.close()


def test_depth_files_of_the_next_frame_are_paired_again_by_fix(tmp_path, capsys):
    """Each frame of a ring of three spheres given the next frame's depth file: furrow model warns with the shift,
    and --depth-agreement fix gives each frame the file one place back (the first frame, without one, left out):
    every depth map then the right capture's."""
    from tests.scenes import spheres_scene

    right = tmp_path / "right"
    write_transforms(make_scanset(spheres_scene(), scan_ring(16, 128, 96), noise=0.0005), right)
    d = _copy(right, tmp_path / "shifted")
    frames = json.loads((d / "transforms.json").read_text())["frames"]
    data = [(d / f["depth_file_path"]).read_bytes() for f in frames]
    for i, f in enumerate(frames):
        (d / f["depth_file_path"]).write_bytes(data[(i + 1) % len(frames)])
    for flags in ((), ("--depth-agreement", "fix")):
        out = tmp_path / f"p{len(flags)}"
        rc, _, err = _run(["model", str(d), "-o", str(out), "--max-res", "16", *flags], capsys)
        rec = load_model(out).params["depth_agreement"]
        assert rc == 0 and rec["mispaired"] and rec["pairing_shift"] == -1, rec
        applied = rec.get("pairing_applied")
        assert (applied == {"shift": -1, "left_out": [frames[0]["file_path"]]}) == bool(flags), rec
    want, got = _agreed_depths(right, False), _agreed_depths(d, True)
    assert sorted(got) == sorted(want)[1:] and all(np.array_equal(got[n], want[n]) for n in got)


def test_depth_stored_as_disparity_is_named_and_read_by_fix(spheres_dir, tmp_path, capsys):
    """Every depth map 1000 / z in metres (an iPhone's disparity written as if millimetres): furrow model names it
    with its constant (1 m squared) in its error (the spheres read inside out leave no surface), and
    --depth-agreement fix reads each map as k / value: within the 16-bit rounding of the right capture's depth."""
    import cv2

    d = _copy(spheres_dir, tmp_path / "stored")
    for f in json.loads((d / "transforms.json").read_text())["frames"]:
        p = d / f["depth_file_path"]
        z = cv2.imread(str(p), cv2.IMREAD_UNCHANGED).astype(np.float64)
        cv2.imwrite(str(p), np.where(z > 0, np.rint(1e6 / np.maximum(z, 1)), 0).astype(np.uint16))
    rc, _, err = _run(["model", str(d), "-o", str(tmp_path / "d0"), "--max-res", "16"], capsys)
    flat = " ".join(err.split())  # as stored, the spheres inside out: no surface, and the error says why
    assert rc != 0 and "before that, the views' depths agree with their poses read as disparity" in flat, flat
    rc, _, err = _run(["model", str(d), "-o", str(tmp_path / "d1"), "--max-res", "16", "--depth-agreement", "fix"],
                      capsys)
    flat = " ".join(err.split())
    rec = load_model(tmp_path / "d1").params["depth_agreement"]
    assert rc == 0 and rec["status"] == "disparity" and "read as disparity" in flat, (rec, flat)
    assert rec["disparity"]["constant"] == pytest.approx(1.0, rel=0.01), rec["disparity"]
    assert rec["disparity_applied"] == rec["disparity"]["constant"], rec
    assert "were read as disparity, depth = " in flat, flat
    want, got = _agreed_depths(spheres_dir, False), _agreed_depths(d, True)
    assert sorted(got) == sorted(want)
    for n, z in want.items():
        v = z > 0
        assert np.array_equal(got[n] > 0, v) and np.allclose(got[n][v], z[v], rtol=0.012), n  # k within 1 %, 16 bits


def test_depth_drifting_from_view_to_view_is_named_and_rescaled_by_fix(spheres_dir, tmp_path, capsys):
    """Each view's depth times its own factor within 15 % (a monocular network's): furrow model names it, and
    --depth-agreement fix scales each view's depth by its factor: within 1.5 % of the right capture's (the factors'
    fit, 16-bit rounding)."""
    import cv2

    d = _copy(spheres_dir, tmp_path / "stored")
    frames = json.loads((d / "transforms.json").read_text())["frames"]
    drift = np.exp(np.random.default_rng(5).uniform(np.log(0.85), np.log(1.15), len(frames)))
    for f, k in zip(frames, drift):
        p = d / f["depth_file_path"]
        z = cv2.imread(str(p), cv2.IMREAD_UNCHANGED).astype(np.float64)
        cv2.imwrite(str(p), np.clip(np.rint(z * k), 0, 65535).astype(np.uint16))
    for flags in ((), ("--depth-agreement", "fix")):
        out = tmp_path / f"v{len(flags)}"
        rc, _, err = _run(["model", str(d), "-o", str(out), "--max-res", "16", *flags], capsys)
        flat = " ".join(err.split())
        rec = load_model(out).params["depth_agreement"]
        assert rc == 0 and rec["status"] == "view scales" and "each at its own scale" in flat, (rec, flat)
        assert bool(rec.get("view_scales_applied")) == bool(flags), rec
        assert ("Each view's depth was scaled by its own factor" in flat) == bool(flags), flat
    want, got = _agreed_depths(spheres_dir, False), _agreed_depths(d, True)
    for n, z in want.items():
        v = (z > 0) & (got[n] > 0)
        assert np.array_equal(got[n] > 0, z > 0) and np.allclose(got[n][v], z[v], rtol=0.015), n

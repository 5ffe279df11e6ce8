"""`furrow model` with a table in the depth: --keep-support, --no-extent, --matte, --backdrop (issue 20)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from capture.io import write_transforms
from capture.scan import Scan, ScanSet
from furrow.cli import main
from tests.scenes import make_scanset, ring_cameras, sphere_scene
from volume.model import load_model

#: The table top: z of the plane (the 7 cm sphere's bottom) and half its size (metres).
TABLE_Z = -0.07
TABLE_HALF = 0.4


def _with_table(ss: ScanSet) -> ScanSet:
    """The scans with a table top under the sphere in the depth (nearer surface wins) and in grey colour."""
    scans = []
    for s in ss.scans:
        cam = s.camera
        d = cam.pixel_rays(cam.pixel_grid()) @ cam.world_from_cam[:3, :3].T
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.where(d[..., 2] < 0, (TABLE_Z - cam.center[2]) / d[..., 2], 0.0)
        p = cam.center + t[..., None] * d
        on = (t > 0) & np.all(np.abs(p[..., :2]) < TABLE_HALF, axis=-1)
        depth = np.where((s.depth > 0) & ((s.depth < t) | ~on), s.depth, np.where(on, t, 0.0)).astype(np.float32)
        rgb = np.where((on & (depth == t))[..., None], np.uint8(90), s.srgb8)
        scans.append(Scan(rgb, depth, cam, s.name))
    pts = np.concatenate([s.points() for s in scans])
    return ScanSet(tuple(scans), np.stack([pts.min(0) - 0.01, pts.max(0) + 0.01]))


@pytest.fixture(scope="module")
def table_dir(tmp_path_factory):
    cams = ring_cameras(8, 64, 48, elevations=(15.0, 30.0), fov_deg=32.0)  # all above the table top
    ss = _with_table(make_scanset(sphere_scene(), cams, noise=0.0005))
    out = tmp_path_factory.mktemp("scans") / "sphere_table"
    write_transforms(ss, out)
    return out


def _model(argv, capsys):
    rc = main(["model", *argv, "--max-res", "32", "--json"])
    out = capsys.readouterr()
    return rc, (json.loads(out.out) if rc == 0 else None), out.err


def test_table_is_removed_and_kept_on_request(table_dir, tmp_path, capsys):
    rc, s, err = _model([str(table_dir), "-o", str(tmp_path / "m")], capsys)
    assert rc == 0, err
    ex = s["surroundings"]["extent"]
    assert ex["plane"] is not None and abs(ex["plane"][3] - 0.07) < 0.003 and ex["removed_fraction"]["support"] > 0.2
    assert "extent" in s["seconds"] and "matte warm-up" in s["seconds"] and "extent: support plane" in err
    m = load_model(tmp_path / "m")
    assert np.all(m.bounds[1] - m.bounds[0] < 0.2)  # the sphere's box, not the table's
    assert m.rgbz.alpha is not None and m.params["surroundings"]["matte"]["mode"] == "auto"
    rc, kept, err = _model([str(table_dir), "-o", str(tmp_path / "k"), "--keep-support", "--matte", "off"], capsys)
    assert rc == 0, err
    assert kept["surroundings"]["extent"]["kept_support"] and kept["surroundings"]["extent"]["removed_fraction"][
        "support"] == 0.0
    k = load_model(tmp_path / "k")
    assert k.rgbz.alpha is None and np.ptp(k.mesh_vertices[:, 0]) > 0.3  # the table is modelled
    rc, raw, err = _model([str(table_dir), "-o", str(tmp_path / "r"), "--no-extent", "--matte", "off"], capsys)
    assert rc == 0, err and "extent" not in raw["surroundings"]


def test_flags_are_explained_and_checked(table_dir, tmp_path, capsys):
    with pytest.raises(SystemExit):
        main(["model", "--help"])
    text = capsys.readouterr().out
    for flag in ("--keep-support", "--no-extent", "--matte", "--backdrop"):
        assert flag in text
    with pytest.raises(SystemExit):
        main(["model", str(table_dir), "-o", str(tmp_path / "x"), "--backdrop", "mauve"])
    assert "bad colour 'mauve'" in capsys.readouterr().err
    rc = main(["model", str(table_dir), "-o", str(tmp_path / "y"), "--matte", "backdrop"])
    assert rc != 0 and "needs --backdrop" in capsys.readouterr().err


def test_the_report_says_when_the_object_colour_is_the_mattes_mean():
    """furrow model's report names the colour across views' fallback (capture.matting_global.MEAN_CHECK) when a
    pass took the matte's mean colour, with the crossing and the gap, and says nothing of it otherwise."""
    from io import StringIO

    from rich.console import Console

    from furrow.cmd_model import _print_surroundings

    def report(first_taken: bool, last_taken: bool) -> str:
        mean = {"colour": [0.03, 0.029, 0.011], "gap": 0.77}
        glob = {"colour": [0.005, 0.01, 0.0], "mean": {**mean, "taken": last_taken},
                "recross": {"first": {"colour": [0.004, 0.009, 0.0], "mean": {**mean, "taken": first_taken}}}}
        out = StringIO()
        _print_surroundings(Console(file=out, width=200), {"matte": {"mode": "off", "cells": {"global": glob}}})
        return out.getvalue()

    said = report(True, True)
    assert said.count("the mean taken") == 1 and "(0.004, 0.009, 0.000)" in said and "0.77" in said
    assert "the mean taken" in report(False, True) and "(0.005, 0.010, 0.000)" in report(False, True)
    assert "mean" not in report(False, False)


def test_the_report_says_when_the_colour_came_from_the_opaque_pixels():
    """furrow model's report names capture.matting_known.OPAQUE_SOURCES (too few sure pixels before a known
    background: the colour before a blown-out or unseen background from the opaque pixels) when a view took it."""
    from io import StringIO

    from rich.console import Console

    from furrow.cmd_model import _print_surroundings

    def report(opq: dict | None) -> str:
        out = StringIO()
        matte = {"mode": "auto", "methods": {"plate": 18}, "seconds_per_view": 0.1, "seconds_per_view_max": 0.2,
                 "unknown_fraction_mean": 0.1, "partial_fraction_mean": 0.1}
        _print_surroundings(Console(file=out, width=250), {"matte": {**matte, **({"opaque_sources": opq} if opq
                                                                                 else {})}})
        return out.getvalue()

    said = report({"views": 18, "pixels": 20321})
    assert "in 18 view(s)" in said and "20321 pixels" in said and "OPAQUE_SOURCES" in said
    assert "OPAQUE_SOURCES" not in report({"views": 0, "pixels": 0}) and "OPAQUE_SOURCES" not in report(None)


def test_the_report_says_when_the_thin_branches_opaque_pixels_were_opened():
    """furrow model's report names capture.matting_rim when a view's depth-opaque pixels of thin branches were
    solved against the background the other views saw, and says nothing when none was."""
    from io import StringIO

    from rich.console import Console

    from furrow.cmd_model import _print_surroundings

    def report(rim: dict | None) -> str:
        out = StringIO()
        matte = {"mode": "auto", "methods": {"plate": 18}, "seconds_per_view": 0.1, "seconds_per_view_max": 0.2,
                 "unknown_fraction_mean": 0.1, "partial_fraction_mean": 0.1}
        _print_surroundings(Console(file=out, width=250), {"matte": {**matte, **({"rim": rim} if rim else {})}})
        return out.getvalue()

    said = report({"views": 17, "pixels": 4120})
    assert "4120 depth-opaque pixels" in said and "in 17 view(s)" in said and "matting_rim" in said
    assert "matting_rim" not in report({"views": 0, "pixels": 0}) and "matting_rim" not in report(None)


def test_the_report_says_how_many_pixels_kept_their_part_across_the_line():
    """furrow model's report counts the partial pixels that kept the photo's part across their line
    (capture.matting_cells.KEEP_ACROSS) and says nothing when none did."""
    from io import StringIO

    from rich.console import Console

    from furrow.cmd_model import _print_surroundings

    def report(across: int | None) -> str:
        out = StringIO()
        cells = {"global": {}} if across is None else {"global": {}, "across": across}
        _print_surroundings(Console(file=out, width=250), {"matte": {"mode": "off", "cells": cells}})
        return out.getvalue()

    said = report(412345)
    assert "412345 partial pixels" in said and "across_line" in said
    assert "across_line" not in report(0) and "across_line" not in report(None)


def test_the_report_names_the_views_whose_plate_was_refused():
    """furrow model's report names, by frame, the views whose background plate was refused
    (capture.plate_gate: the background changed between frames), says that they lent the others nothing,
    names the views whose plate was dropped on one side only, and says nothing of either when none was."""
    from io import StringIO

    from rich.console import Console

    from furrow.cmd_model import _print_surroundings

    def report(refused: list, sectors: dict) -> str:
        per_view = [{"name": f"r0_v{i:03d}.png", "refused": "the plate is closer ... (under 50%)" if i in refused
                     else None, "gate": {"sectors_refused": sectors[i]} if i in sectors else {}} for i in range(6)]
        plate = {"mode": "fixed", "error_median": 0.002, "band_known_mean": 0.9, "band_known_min": 0.0,
                 "per_view": per_view, "refused": refused, "dropped_sources": refused}
        out = StringIO()
        _print_surroundings(Console(file=out, width=400), {"plate": plate})
        return out.getvalue()

    said = report([1, 4], {1: [0, 1, 2], 2: [5]})
    assert "refused in 2 of 6 view(s)" in said and "r0_v001.png: the plate is closer" in said
    assert "r0_v004.png" in said and "lent the other views nothing" in said
    assert "dropped in part of 1 view(s)" in said and "(r0_v002.png)" in said  # view 1 counts as refused only
    quiet = report([], {})
    assert "refused" not in quiet and "dropped in part" not in quiet and "background plate (fixed)" in quiet


def test_noisy_frames_are_measured_and_the_plate_reads_them_smoothed(table_dir, tmp_path, capsys):
    """capture.noise through `furrow model`: frames with sensor noise of 3 8-bit steps are measured (within 10 %)
    and the plate stage smooths its copy (the record and the console say so); `--plate-denoise off` reads them as
    they are; the clean capture measures under 1 step and is not smoothed."""
    from capture.io import read_scanset

    ss = read_scanset(str(table_dir))
    rng = np.random.default_rng(5)
    noisy = [Scan(np.clip(np.round(s.srgb8 + rng.normal(0, 3.0, s.srgb8.shape)), 0, 255).astype(np.uint8),
                  s.depth, s.camera, s.name) for s in ss.scans]
    out = tmp_path / "noisy"
    write_transforms(ScanSet(tuple(noisy), ss.bounds), out)
    runs = {}
    for name, cap, extra in (("noisy", out, []), ("off", out, ["--plate-denoise", "off"]), ("clean", table_dir, [])):
        rc, s, err = _model([str(cap), "-o", str(tmp_path / f"m_{name}"), "--matte", "plate", *extra], capsys)
        assert rc == 0, err
        runs[name] = (s["surroundings"]["plate"], err)
    plate, err = runs["noisy"]
    assert abs(plate["frame_noise"] - 3.0) <= 0.3 and plate["frame_smoothing"] > 0, plate
    assert "the frames' noise 3." in err and "smoothed" in err
    assert "frame_noise" not in runs["off"][0] and "smoothed" not in runs["off"][1]
    assert runs["clean"][0]["frame_noise"] < 1.0 and runs["clean"][0]["frame_smoothing"] == 0.0
    assert "smoothed" not in runs["clean"][1] and "frame_noise_note" not in runs["clean"][0]


def test_jpeg_frames_and_unmeasured_noise_are_said(table_dir, tmp_path, capsys):
    """capture.noise.noise_note through `furrow model`: the table capture's frames as JPEG files (quality 95) measure
    under a step, and the record and the console say that JPEG frames may read low."""
    import shutil

    import cv2

    jpg = tmp_path / "jpeg"
    shutil.copytree(table_dir, jpg)
    meta = json.loads((jpg / "transforms.json").read_text())
    for fr in meta["frames"]:
        png = jpg / fr["file_path"]
        new = png.with_suffix(".jpg")
        cv2.imwrite(str(new), cv2.imread(str(png), cv2.IMREAD_UNCHANGED), [cv2.IMWRITE_JPEG_QUALITY, 95])
        png.unlink()
        fr["file_path"] = str(Path(fr["file_path"]).with_suffix(".jpg"))
    (jpg / "transforms.json").write_text(json.dumps(meta))
    rc, s, err = _model([str(jpg), "-o", str(tmp_path / "m"), "--matte", "plate"], capsys)
    assert rc == 0, err
    plate = s["surroundings"]["plate"]
    assert plate["frame_noise"] < 1.0 and "JPEG frames (8 of 8)" in plate["frame_noise_note"], plate
    assert "may read low" in " ".join(err.split())


def test_a_textured_room_is_not_smoothed_as_noise(table_dir, tmp_path, capsys):
    """capture.noise.TEXTURE_RATIO through `furrow model`: every frame of the table capture given the same grain of
    6 8-bit steps (a room's texture, fixed in the image): the frames' own detail reads it as noise, the noise between
    frames does not, so the plate is made from the frames as they are and the record and the console say why."""
    from capture.io import read_scanset

    ss = read_scanset(str(table_dir))
    grain = np.random.default_rng(9).normal(0, 6.0, ss.scans[0].srgb8.shape)
    rough = [Scan(np.clip(np.round(s.srgb8 + grain), 0, 255).astype(np.uint8), s.depth, s.camera, s.name)
             for s in ss.scans]
    out = tmp_path / "grain"
    write_transforms(ScanSet(tuple(rough), ss.bounds), out)
    rc, s, err = _model([str(out), "-o", str(tmp_path / "m"), "--matte", "plate"], capsys)
    assert rc == 0, err
    plate = s["surroundings"]["plate"]
    assert plate["frame_detail"] > 3.0 and plate["frame_noise"] < 1.0 and plate["frame_texture"], plate
    assert plate["frame_smoothing"] == 0.0 and "is the room's texture" in " ".join(err.split())


def test_the_report_says_when_the_smoothing_was_refused():
    """The plate line's noise words (capture.noise_check): a refused smoothing is a yellow line with both held-back
    errors; a kept one is named on the plate line with its RMS before and after; an unchecked one (errors None) is
    named without them."""
    from io import StringIO

    from rich.console import Console

    from furrow.cmd_model import _print_surroundings

    def report(smoothing: float, check: dict) -> str:
        plate = {"mode": "panorama", "error_median": 0.002, "band_known_mean": 0.9, "band_known_min": 0.8,
                 "frame_noise": 2.1, "frame_smoothing": smoothing, "frame_detail": 2.1, "smoothing_check": check}
        out = StringIO()
        _print_surroundings(Console(file=out, width=400), {"plate": plate})
        return out.getvalue()

    chk = {"mode": "panorama", "rms_raw": 0.0055, "rms_smoothed": 0.0063, "median_raw": 0.0024,
           "median_smoothed": 0.0034, "views": 12, "smoothed": False}
    said = report(0.0, chk)
    assert "predicted 12 views' held-back background worse (RMS 0.0063 against 0.0055)" in said
    assert "made from them smoothed" not in said
    said = report(8.4, {**chk, "rms_smoothed": 0.0050, "smoothed": True})
    assert "worse" not in said and "made from them smoothed (bilateral filter; held-back RMS on 12 views 0.0055 -> " \
        "0.0050)" in said
    said = report(8.4, {**chk, "rms_raw": None, "rms_smoothed": None, "smoothed": True})
    assert "made from them smoothed (bilateral filter)" in said


def test_the_report_warns_when_the_background_has_the_objects_colour():
    """furrow model warns (yellow) when the matte record's weak share (capture.matting_blind: the band's pixels with a
    weak data term before a background of nearly the object's colour) reaches capture.matting_guide.WEAK_GATE (the
    share from which the Laplacian's guide is brightened), with the share; below it, or without the field (a model
    built before), it says nothing of it."""
    from io import StringIO

    from rich.console import Console

    from capture.matting_guide import WEAK_GATE as WEAK_WARN_SHARE
    from furrow.cmd_model import _print_surroundings

    def report(share) -> str:
        out = StringIO()
        matte = {"mode": "auto", "methods": {"plate": 18}, "seconds_per_view": 0.1, "seconds_per_view_max": 0.2,
                 "unknown_fraction_mean": 0.1, "partial_fraction_mean": 0.1,
                 "blind_prior": {"weak_pixels": 301305, **({} if share is None else {"weak_share": share})}}
        _print_surroundings(Console(file=out, width=250), {"matte": matte})
        return out.getvalue()

    said = report(0.3579)
    assert "36% of the matting band" in said and "comes out soft" in said
    assert "comes out soft" in report(WEAK_WARN_SHARE)
    for share in (WEAK_WARN_SHARE - 0.01, 0.0023, None):
        assert "comes out soft" not in report(share) and "301305 pixels" in report(share)
        assert "guide was brightened" not in report(share)  # no view counted (a model built before: no field)
    out = StringIO()
    _print_surroundings(Console(file=out, width=250), {"matte": {
        "mode": "auto", "methods": {"plate": 18}, "seconds_per_view": 0.1, "seconds_per_view_max": 0.2,
        "unknown_fraction_mean": 0.1, "partial_fraction_mean": 0.1,
        "blind_prior": {"weak_pixels": 3, "weak_share": 0.05, "views": 18, "guided_views": 2}}})
    assert "guide was brightened in 2 of 18 view(s)" in out.getvalue()


@pytest.mark.parametrize("error, warned", [(0.59269, True), (0.2, False), (0.19999, False)])
def test_the_report_warns_when_the_spheres_miss_their_target(error, warned):
    """furrow model's closing lines say (yellow) when the occluder spheres' 1 - IoU is above --sphere-error
    (volume.spheres.fit_spheres returns its best cover and its error when it cannot reach the target)."""
    from io import StringIO

    from rich.console import Console

    from furrow.cmd_model import print_report

    out = StringIO()
    summary = {"holes": [], "surroundings": {}, "photometric": None,
               "views": {"kept": 36, "of": 36, "mode": "auto"}, "resolution": {"reason": "full resolution"},
               "l_opt": 8, "levels": [8], "surface_voxels": {"8": 282}, "spheres": 1452, "sphere_error": error,
               "sphere_target": 0.2}
    print_report(Console(file=out, width=250), summary, "OUT")
    said = out.getvalue()
    assert f"spheres 1452 (1 - IoU {error})" in said
    assert ("misses the target 0.2 (--sphere-error)" in said) is warned


def test_the_report_says_where_the_empty_depth_rule_was_refused_and_why():
    """furrow model's report names capture.matting_blind.EMPTY_MAX_HOLES when views refused EMPTY_PRIOR: the hole
    rates above the threshold, or too little depth to check it, with the pixels left to the Laplacian; nothing when
    no view refused it."""
    from io import StringIO

    from rich.console import Console

    from furrow.cmd_model import _print_surroundings

    def report(bp: dict) -> str:
        out = StringIO()
        matte = {"mode": "auto", "methods": {"plate": 18}, "seconds_per_view": 0.1, "seconds_per_view_max": 0.2,
                 "unknown_fraction_mean": 0.1, "partial_fraction_mean": 0.1, "blind_prior": bp}
        _print_surroundings(Console(file=out, width=400), {"matte": matte})
        return out.getvalue()

    holes = report({"empty_refused_pixels": 59789, "empty_refused_views": 8, "depth_holes": [0.2, 0.35, 0.4],
                    "empty_refused_reasons": ["the depth has holes"]})
    assert "in 8 view(s) the depth has holes (35%-40% of its interior" in holes and "59789 weak pixels" in holes
    assert "too little" not in holes
    little = report({"empty_refused_pixels": 12, "empty_refused_views": 1, "depth_holes": [0.1],
                     "empty_refused_reasons": ["too little depth to check it"]})
    assert "in 1 view(s) too little depth to check it" in little and "12 weak pixels" in little
    assert "EMPTY_MAX_HOLES" not in report({"empty_refused_pixels": 0, "empty_refused_views": 0, "depth_holes": []})


def test_the_report_says_the_fringe_fill_and_a_black_backdrop():
    """furrow model's report names capture.matting_fringe when partial pixels took the view's measured fringe, and
    warns when views were matted against a black backdrop (capture.matting.DARK_BACKDROP); silent otherwise."""
    from io import StringIO

    from rich.console import Console

    from furrow.cmd_model import _print_surroundings

    def report(extra: dict) -> str:
        out = StringIO()
        matte = {"mode": "auto", "methods": {"backdrop": 18}, "seconds_per_view": 0.1, "seconds_per_view_max": 0.2,
                 "unknown_fraction_mean": 0.1, "partial_fraction_mean": 0.1}
        _print_surroundings(Console(file=out, width=400), {"matte": {**matte, **extra}})
        return out.getvalue()

    said = report({"fringe": {"views": 8, "pixels": 92763}, "dark_backdrop_views": 18})
    assert "92763 partial pixels" in said and "in 8 view(s)" in said and "matting_fringe" in said
    assert "18 view(s) matted against a black backdrop" in said
    quiet = report({"fringe": {"views": 0, "pixels": 0}, "dark_backdrop_views": 0})
    assert "matting_fringe" not in quiet and "black backdrop" not in quiet


def test_the_report_says_when_the_mean_was_far_but_less_sure():
    """capture.matting_global.MEAN_BIAS_CHECK: a mean far from the crossing but refused for its error from the
    alpha's gets its own line (the crossing kept), not "the mean taken"."""
    from io import StringIO

    from rich.console import Console

    from furrow.cmd_model import _print_surroundings

    glob = {"colour": [0.016, 0.018, 0.0], "sigma": 0.027,
            "mean": {"colour": [0.057, 0.066, 0.05], "gap": 0.8, "taken": False, "mean_error": 0.038}}
    out = StringIO()
    _print_surroundings(Console(file=out, width=400), {"matte": {"mode": "off", "cells": {"global": glob}}})
    said = out.getvalue()
    assert "the crossing kept" in said and "0.038" in said and "0.027" in said and "the mean taken" not in said

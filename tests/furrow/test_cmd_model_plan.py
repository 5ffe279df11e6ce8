"""`furrow model SCANS -o M --plan`: the stages in order with their settings, on / off with the
given flags; exit 0; nothing written (not M, not a temporary folder)."""

from __future__ import annotations

import re
import tempfile

import pytest

from capture.io import write_transforms
from furrow.cli import main
from tests.scenes import make_scanset, scan_ring, sphere_scene
from volume.pipeline.plan import NAME_WIDTH

#: Stages --plan must list, in this order (issue 29).
MUST = ("read", "undistort", "extent", "matte", "photometric", "fuse", "RGBz")


@pytest.fixture(scope="module")
def scan_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("plan") / "sphere"
    write_transforms(make_scanset(sphere_scene(), scan_ring(4, 32, 24)), out)
    return out


def _plan(scan_dir, tmp_path, capsys, monkeypatch, *flags):
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    before = sorted(p.name for p in tmp_path.iterdir())
    out = tmp_path / "M"
    rc = main(["model", str(scan_dir), "-o", str(out), "--plan", *flags])
    text = capsys.readouterr().err
    assert rc == 0, text
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == before  # nothing written
    assert not list(scratch.iterdir())  # not even a spill folder
    rows = {}
    for line in text.splitlines():
        m = re.match(rf" *(\d+)\. (.{{{NAME_WIDTH}}}) (on |off)  ", line)
        if m:
            rows[m.group(2).strip()] = (int(m.group(1)), m.group(3).strip(), line)
    return rows, text


def test_plan_lists_the_stages_in_order_and_writes_nothing(scan_dir, tmp_path, capsys, monkeypatch):
    rows, text = _plan(scan_dir, tmp_path, capsys, monkeypatch)
    assert [rows[n][0] for n in MUST] == sorted(rows[n][0] for n in MUST)
    assert all(rows[n][1] == "on" for n in MUST)
    assert "transforms.json, 4 frames" in text and "max_res=256" in rows["fuse"][2]


def test_plan_follows_the_flags(scan_dir, tmp_path, capsys, monkeypatch):
    rows, _ = _plan(scan_dir, tmp_path, capsys, monkeypatch, "--no-extent", "--no-photometric", "--matte", "off",
                    "--max-res", "64", "--undistort", "full")
    assert rows["extent"][1] == "off" and rows["photometric"][1] == "off"
    assert "mode='off'" in rows["matte"][2] and "max_res=64" in rows["fuse"][2]
    assert "mode='full'" in rows["undistort"][2]

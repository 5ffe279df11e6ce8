"""The matte stage's colour across views (volume.surroundings.cell_colour_stage; issue 30 seventh round):
each view's partial pixels take their 3D cell's colour at the indices capture.matting_lines gives, the
rest of the view and its alpha untouched."""

from __future__ import annotations

import numpy as np
import pytest

from capture.camera import Camera, make_K
from capture.scan import Scan
from tests.capture.test_matting_lines import _cells
from volume.surroundings import cell_colour_stage


@pytest.fixture(autouse=True)
def _no_sigma_gate(monkeypatch):
    """These tests exercise the cubes' colours on seeded scenes whose lines scatter more than the shipped
    capture.matting_cells.MAX_OBJECT_SIGMA lets through (SIGMA_GATE has its own test in test_matting_cells.py)."""
    monkeypatch.setattr("capture.matting_cells.SIGMA_GATE", False)


def test_the_cells_colour_goes_to_its_pixels_and_nothing_else_changes():
    pts, C, B, A, F = _cells(1, 6, textured=True)
    pts = np.floor(pts) + 0.5 + np.random.default_rng(1).uniform(-0.01, 0.01, pts.shape)  # one stage cube a cell
    h, w = 40, 48
    cam = Camera(make_K(50, 50, (w - 1) / 2, (h - 1) / 2), np.eye(4), w, h)
    half = len(A) // 2
    scans, samples = [], []
    rng = np.random.default_rng(0)
    for k in (slice(0, half), slice(half, len(A))):
        idx = np.sort(rng.choice(h * w, k.stop - k.start, replace=True))
        samples.append({"index": idx, "pts": pts[k], "C": C[k], "B": B[k], "a": A[k], "F0": F[k],
                        "usable": np.ones(k.stop - k.start, bool)})
        scans.append(Scan(np.full((h, w, 3), 0.5, np.float32), np.ones((h, w), np.float32), cam, "v",
                          np.full((h, w), 0.3, np.float32)))
    out, rec = cell_colour_stage(tuple(scans), samples, [0.1, None], None, lambda s: s)
    assert rec["coloured"] > 0 and rec["views_without_alpha_error"] == 1
    assert out[1] is scans[1]  # no alpha error measured: the view keeps its colour
    got = out[0].rgb.reshape(-1, 3)
    changed = np.flatnonzero(np.abs(got - 0.5).max(-1) > 1e-6)
    assert set(changed) <= set(samples[0]["index"]) and len(changed) > 0
    assert np.array_equal(out[0].alpha, scans[0].alpha)


def test_the_rule_skips_where_the_plate_says_the_lines_cannot_cross():
    from capture.matting import MatteConfig
    from capture.matting_cells import MIN_CROSSING
    from volume.surroundings import across_skipped

    dark, lit = {"band_crossing_mean": 0.5 * MIN_CROSSING}, {"band_crossing_mean": 2 * MIN_CROSSING}
    assert across_skipped(MatteConfig(), lit) is None
    assert "auto" in across_skipped(MatteConfig(), dark) and "MIN_CROSSING" in across_skipped(MatteConfig(), dark)
    assert across_skipped(MatteConfig(across="on"), dark) is None
    assert across_skipped(MatteConfig(across="off"), lit).startswith("off")
    assert across_skipped(MatteConfig(), {}) is None  # a plate record without the share: as before



def test_the_band_share_counts_seen_lit_unclipped_backgrounds_only():
    from capture.matting_cells import CROSSING_DARK, band_crossing

    h, w = 10, 20
    band = np.zeros((h, w), bool)
    band[2:8] = True  # 120 pixels
    img = np.full((h, w, 3), 0.3, np.float32)
    B = np.full((h, w, 3), 0.4, np.float32)
    known = np.ones((h, w), bool)
    assert band_crossing(img, band, B, known) == 1.0
    assert band_crossing(img, np.zeros((h, w), bool), B, known) == 0.0
    est = np.zeros((h, w), bool)
    est[2:5] = True  # half the band estimated, not seen
    assert band_crossing(img, band, B, known, est) == 0.5
    dark = B.copy()
    dark[2:8, :5] = 0.5 * CROSSING_DARK / np.sqrt(3)  # a quarter of the band before a dark room
    assert band_crossing(img, band, dark, known) == 0.75
    hot = img.copy()
    hot[2:8, 15:] = 1.0  # a quarter blown out in the photo
    assert band_crossing(hot, band, B, known) == 0.75
    unknown = known.copy()
    unknown[2:8, 10:] = False
    assert band_crossing(img, band, B, unknown) == 0.5


def test_the_plate_record_carries_the_band_share():
    from capture.matting_cells import MIN_CROSSING
    from capture.plate import PlateConfig, background_plates
    from tests import plate_scenes as ps

    views, room, _, _ = ps.turntable_capture(n=4)
    lit, rec = background_plates(views, PlateConfig(mode="user"), user=[room] * len(views))
    _, rec_dark = background_plates(views, PlateConfig(mode="user"), user=[0.0 * room] * len(views))
    assert rec["band_crossing_mean"] >= MIN_CROSSING and rec_dark["band_crossing_mean"] == 0.0
    assert [p["band_crossing"] for p in rec["per_view"]] == [round(p.band_crossing, 4) for p in lit]
    assert lit[0].cropped().full().band_crossing == lit[0].band_crossing


def test_the_band_share_asks_the_background_brighter_than_the_object():
    from capture.matting_cells import band_crossing

    h, w = 10, 20
    band = np.zeros((h, w), bool)
    band[2:8] = True
    opaque = np.zeros((h, w), bool)
    opaque[8:] = True
    img = np.full((h, w, 3), 0.3, np.float32)
    B = np.full((h, w, 3), 0.4, np.float32)
    B[2:8, :10] = 0.2  # half the band's room darker than the object (0.3)
    known = np.ones((h, w), bool)
    assert band_crossing(img, band, B, known) == 1.0  # no object named: only CROSSING_DARK
    assert band_crossing(img, band, B, known, opaque=opaque) == 0.5
    assert band_crossing(img, band, B, known, opaque=opaque, over=2.0) == 0.0

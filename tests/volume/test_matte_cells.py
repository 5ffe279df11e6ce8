"""The matte stage's colour across views (volume.surroundings.cell_colour_stage; issue 30 seventh round):
each view's partial pixels take their 3D cell's colour at the indices capture.matting_lines gives, the
rest of the view and its alpha untouched."""

from __future__ import annotations

import numpy as np

from capture.camera import Camera, make_K
from capture.scan import Scan
from tests.capture.test_matting_lines import _cells
from volume.surroundings import cell_colour_stage


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

"""capture.matting_rim: the depth's opaque pixels of thin branches opened where the plate saw behind them."""

from __future__ import annotations

import numpy as np
import pytest

from capture import matting_rim
from capture.camera import Camera, make_K
from capture.matting import FG, UNKNOWN, MatteConfig, depth_trimap, matte_scan
from capture.matting_rim import open_rim
from capture.plate import Plate
from capture.scan import Scan, srgb_to_linear, to_uint8_srgb
from tests import plate_scenes as ps

#: The true coverage of the branches: dense clusters of needles the depth sees at every pixel centre.
BRANCH_ALPHA = 0.7
#: With the rim opened the alpha MSE at the branches' depth-opaque pixels falls to at most this fraction
#: of the depth's word (alpha 1 there: (1 - 0.7)^2 = 0.09; measured 0.082 -> 0.0025 / 0.0034, seeds 0 / 1) ...
RIM_BEATS = 0.1
#: ... and the premultiplied colour's mean error there to at most this fraction (0.122 -> 0.012 / 0.016).
RIM_BEATS_PREMUL = 0.25


def _branches(h: int = 96, w: int = 320, seed: int = 0):
    """(C, B, true alpha, F, depth): six horizontal branches 5 px thick, each pixel BRANCH_ALPHA covered
    (depth at every pixel of a branch), a green foliage colour over the seeded room."""
    A = np.zeros((h, w), np.float32)
    for k in range(6):
        y0 = 8 + 14 * k
        A[y0:y0 + 5, 40:280] = BRANCH_ALPHA
    y, x = np.mgrid[0:h, 0:w] / h
    F = np.stack([0.08 + 0.03 * np.sin(3 * x), 0.30 + 0.05 * np.cos(2 * y), 0.06 + 0.0 * x], -1).astype(np.float32)
    B = ps.room_image(w, h, seed).astype(np.float32)
    C = A[..., None] * F + (1 - A[..., None]) * B
    C = srgb_to_linear(to_uint8_srgb(C) / np.float32(255.0))
    return C, B, A, F, np.where(A > 0, 0.5, 0.0).astype(np.float32)


def _scan(C, D):
    h, w = D.shape
    return Scan(np.asarray(C, np.float32), D, Camera(make_K(100, 100, (w - 1) / 2, (h - 1) / 2), np.eye(4), w, h), "v")


def test_thin_opaque_pixels_before_a_seen_plate_are_opened_and_nothing_else():
    C, B, A, _, D = _branches()
    tri = depth_trimap(D)
    plate = Plate(B, np.ones(A.shape, bool), 0.004, "panorama", 1.0, 0.0, 0.0)
    out, n = open_rim(tri, C, plate)
    fg = tri >= FG
    assert fg.sum() > 1000
    sep = np.linalg.norm(C - B, axis=-1) >= matting_rim.RIM_SEPARATION
    assert np.all(out[fg & sep] == UNKNOWN) and np.all(out[fg & ~sep] == FG) and n == int((fg & sep).sum())
    assert np.array_equal(out[~fg], tri[~fg])
    # a background the frames' lines estimated, or none: the depth's word stays
    est = Plate(B, np.ones(A.shape, bool), 0.004, "panorama", 1.0, 0.0, 0.0, estimated=np.ones(A.shape, bool))
    assert np.array_equal(open_rim(tri, C, est)[0], tri)
    # a fixed camera's plate (matting_rim.RIM_METHODS): as the depth says
    assert open_rim(tri, C, Plate(B, np.ones(A.shape, bool), 0.004, "fixed", 1.0, 0.0, 0.0))[1] == 0
    assert open_rim(tri, C, Plate(B, np.zeros(A.shape, bool), 0.004, "panorama", 0.0, 0.0, 0.0))[1] == 0
    # a blown-out plate: as the depth says
    hot = Plate(np.ones_like(B), np.ones(A.shape, bool), 0.004, "panorama", 1.0, 0.0, 0.0)
    assert open_rim(tri, C, hot) == (tri, 0)


def test_a_solid_body_keeps_its_opaque_pixels():
    """A fur ball's depth-opaque pixels are a solid disc: the rule leaves the trimap as the depth gives it."""
    h, w = 96, 320
    yy, xx = np.mgrid[0:h, 0:w]
    D = np.where((yy - 48) ** 2 + (xx - 160) ** 2 <= 40 ** 2, 0.5, 0.0).astype(np.float32)
    tri = depth_trimap(D)
    B = ps.room_image(w, h, 0).astype(np.float32)
    C = np.where(D[..., None] > 0, np.float32(0.05), B)
    assert open_rim(tri, C, Plate(B, np.ones((h, w), bool), 0.004, "panorama", 1.0, 0.0, 0.0)) == (tri, 0)


@pytest.mark.parametrize("seed", [0, 1])
def test_the_opened_branches_get_their_alpha_and_premultiplied_colour(monkeypatch, seed):
    C, B, A, F, D = _branches(seed=seed)
    plate = Plate(B, np.ones(A.shape, bool), 0.004, "panorama", 1.0, 0.0, 0.0)
    fg = depth_trimap(D) >= FG
    res = {}
    for on, measured in ((False, False), (True, False), (False, True)):
        monkeypatch.setattr(matting_rim, "OPEN_RIM", on)
        # the sources' coverage (capture.matting_sources, given here as the truth) also reads the branches' 0.7
        m = matte_scan(_scan(C, D), cfg=MatteConfig(source_coverage=BRANCH_ALPHA if measured else None), plate=plate)
        assert m.method == "plate"
        res[on, measured] = (float(np.mean((m.alpha - A)[fg] ** 2)),
                             float(np.abs(m.alpha[..., None] * m.foreground - A[..., None] * F)[fg].mean()))
    depth = res[False, False]
    assert depth[0] >= 0.07  # the depth's word: alpha 1 where the truth is 0.7
    for k in ((True, False), (False, True)):
        assert res[k][0] <= RIM_BEATS * depth[0], res
        assert res[k][1] <= RIM_BEATS_PREMUL * depth[1], res


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_opening_on_the_box_is_the_whole_frames(seed):
    """matting_rim._opening on the box around the opaque pixels against the whole frame's (the reference):
    the same mask, also for a mask touching the frame's edges."""
    rng = np.random.default_rng(seed)
    fg = np.zeros((60, 90), bool)
    for _ in range(6):
        y, x, h, w = rng.integers(0, 55), rng.integers(0, 85), rng.integers(2, 20), rng.integers(2, 30)
        fg[y:y + h, x:x + w] = True
    for r in (1, 3, 6):
        assert np.array_equal(matting_rim._opening(fg, r), matting_rim._opening(fg, r, box=False))

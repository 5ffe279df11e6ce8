"""The colour across the views in bounded memory (capture.matting_cells; issue 30 seventh round, issue 32):
where no view is drawn from, the two passes (fit the cubes' table, apply it view by view) give the
reference's colours (capture.matting_lines.cell_colours, every view at once) bit for bit; drawn, the
cubes are the same and the colours near.  The stage's two passes (volume.surroundings.cell_colour_passes,
each view's samples recomputed from its photo, plate and matte) against the reference stage
(cell_colour_stage with every view's samples): the same scans, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from capture import matting_cells as mc
from capture import matting_contrast as mk
from capture import matting_lines as ml
from capture.camera import Camera, make_K
from capture.plate import Plate
from capture.scan import Scan
from capture.view_map import serial_map
from tests.capture.test_matting_lines import _cells
from volume.surroundings import cell_colour_passes, cell_colour_stage


@pytest.fixture(autouse=True)
def _no_sigma_gate(monkeypatch):
    """These tests exercise the cubes' colours on seeded scenes whose lines scatter more than the shipped
    capture.matting_cells.MAX_OBJECT_SIGMA lets through (SIGMA_GATE has its own test in test_matting_cells.py)."""
    monkeypatch.setattr("capture.matting_cells.SIGMA_GATE", False)


#: Drawn to a third of the lines: median |F - F_reference| of the pixels both colour at most this
#: (the cells' own tolerance against the truth, tests/capture/test_matting_lines.py).
DRAWN_TOL = 0.01


def _views(seed: int = 1):
    """Three views' samples as capture.matting_lines.line_samples gives them (float32, with ``sb``)."""
    pts, C, B, A, F = _cells(seed, 6, textured=True)
    rng = np.random.default_rng(seed)
    a = np.clip(A + rng.normal(0, 0.05, A.shape), 0.01, 0.84)
    part = np.array_split(rng.permutation(len(A)), 3)
    f32 = np.float32
    return [{"index": np.sort(rng.choice(10 ** 5, len(k), replace=False)), "pts": pts[k].astype(f32),
             "C": C[k].astype(f32), "B": B[k].astype(f32), "a": a[k].astype(f32), "F0": F[k].astype(f32),
             "usable": rng.uniform(size=len(k)) > 0.05, "sb": rng.uniform(0, 0.02, len(k)).astype(f32)}
            for k in (np.sort(p) for p in part)]


def _two_passes(samples, sa, gains, cap):
    fits = [mc.fit_sample(s, cap, k) for k, s in enumerate(samples)]
    table, rec = mc.fit_cells(fits, gains, cells=2)
    g = [None] * len(samples) if gains is None else gains
    out = [mc.apply_cells(s, table, sa[k], g[k], view=k) for k, s in enumerate(samples)]
    return [c for c, _ in out], sum(n["coloured"] for _, n in out), sum(n["crossed"] for _, n in out), rec


def test_the_two_passes_give_the_references_colours_when_nothing_is_drawn(monkeypatch):
    monkeypatch.setattr(mk, "POOL_ALPHA_ERROR", False)  # the view without an alpha error keeps its colour
    samples = _views()
    gains = [np.ones(3), np.array([1.6, 1.3, 1.1]), np.array([0.8, 0.9, 1.0])]
    sa = [0.1, None, 0.05]
    ref, rrec = ml.cell_colours(samples, sa, gains, cells=2)
    got, coloured, crossed, rec = _two_passes(samples, sa, gains, cap=10 ** 6)
    assert rrec["coloured"] > 0 and ref[1] is None and got[1] is None
    assert (coloured, crossed, rec["pixels"], rec["sigma_median"]) == \
        (rrec["coloured"], rrec["crossed"], rrec["pixels"], rrec["sigma_median"])
    for r, c in zip(ref, got, strict=True):
        assert (r is None) == (c is None)
        if r is not None:
            assert all(np.array_equal(x, y) and x.dtype == y.dtype for x, y in zip(r, c, strict=True))


def test_a_drawn_fit_keeps_the_cubes_and_near_colours():
    samples = _views()
    sa = [0.1, 0.1, 0.1]
    cap = len(samples[0]["a"]) // 3
    fits = [mc.fit_sample(s, cap, k) for k, s in enumerate(samples)]
    assert all(len(f["a"]) == cap for f in fits)
    again = mc.fit_sample(samples[0], cap, 0)
    assert np.array_equal(fits[0]["pts"], again["pts"])  # seeded
    assert not np.array_equal(fits[0]["pts"], mc.fit_sample(samples[0], cap, 1)["pts"])
    whole = [mc.fit_sample(s, 10 ** 6, k) for k, s in enumerate(samples)]
    assert all(np.array_equal(x, y) for x, y in zip(mc.cell_grid(fits, 2), mc.cell_grid(whole, 2), strict=True))
    ref, _ = ml.cell_colours(samples, sa, cells=2)
    got, coloured, _, rec = _two_passes(samples, sa, None, cap)
    assert rec["fitted"] == 3 * cap < rec["pixels"] and coloured > 0.9 * sum(len(r[0]) for r in ref)
    for r, c in zip(ref, got, strict=True):
        both, i, j = np.intersect1d(r[0], c[0], return_indices=True)
        assert len(both) > 0.9 * len(r[0])
        assert np.median(np.abs(r[1][i] - c[1][j]).max(-1)) <= DRAWN_TOL


def test_the_fit_is_bounded_whatever_the_views():
    assert mc.fit_cap(18) * 18 <= mc.MAX_FIT_LINES and mc.fit_cap(18) >= 60_000  # conifer views: not drawn
    assert mc.fit_cap(200) * 200 <= mc.MAX_FIT_LINES and mc.fit_cap(1) == mc.MAX_FIT_LINES_PER_VIEW


def _scene(n_views: int = 3, h: int = 36, w: int = 44):
    """Matted views of a plane of cells (each one colour), each view before its own textured background:
    (photos, plates, matted scans)."""
    rng = np.random.default_rng(3)
    photos, plates, matted = [], [], []
    for v in range(n_views):
        pose = np.eye(4)
        pose[0, 3] = 0.05 * v
        cam = Camera(make_K(40, 40, (w - 1) / 2, (h - 1) / 2), pose, w, h)
        depth = np.where(rng.uniform(size=(h, w)) > 0.1, 1.0 + 0.3 * rng.uniform(size=(h, w)), 0).astype(np.float32)
        x = cam.depth_to_points(depth)[0]
        cols = np.array([[0.1, 0.2, 0.05], [0.3, 0.1, 0.1], [0.05, 0.05, 0.25], [0.2, 0.2, 0.1]])
        F = np.zeros((h, w, 3))
        F[depth > 0] = cols[(np.floor(x[:, 0] * 4) % 2 * 2 + np.floor(x[:, 2] * 4) % 2).astype(int)]
        B = rng.uniform(0.4, 0.9, (h, w, 3))
        a = np.where(depth > 0, rng.uniform(0.45, 0.84, (h, w)), 0.0)
        C = a[..., None] * F + (1 - a[..., None]) * B + rng.normal(0, 0.003, B.shape)
        photos.append(Scan(np.clip(C, 0, 1).astype(np.float32), depth, cam, f"v{v}"))
        known = rng.uniform(size=(h, w)) > 0.05
        est = known & (rng.uniform(size=(h, w)) > 0.7)
        plates.append(Plate(B.astype(np.float32), known, 0.01, "fixed", 1.0, 0.0, 0.0, 0.0, estimated=est,
                            sigma=np.where(est, 0.02, 0).astype(np.float32)))
        F0 = np.clip(B + (C - B) / np.maximum(a, 1e-6)[..., None], 0, 1).astype(np.float32)
        matted.append(Scan(F0, depth, cam, f"v{v}", (a + rng.normal(0, 0.03, a.shape)).astype(np.float32)))
    return photos, plates, matted


def test_the_stages_two_passes_give_the_reference_stages_scans(monkeypatch):
    monkeypatch.setattr(mk, "POOL_ALPHA_ERROR", False)  # pooled: tests/capture/test_matting_contrast.py
    photos, plates, matted = _scene()
    sa, gains = [0.1, 0.08, None], np.array([[1.0, 1.0, 1.0], [1.2, 1.1, 1.0], [1.0, 0.9, 1.1]])

    def samples(k, s):
        p = plates[k]
        return ml.line_samples(s.camera, photos[k].linear_rgb, p.background, p.known, s.alpha, s.rgb, s.depth,
                               p.estimated, p.sigma)

    whole = [samples(k, s) for k, s in enumerate(matted)]
    ref, rrec = cell_colour_stage(tuple(matted), whole, sa, gains, lambda s: s)
    fits = [mc.fit_sample(s, 10 ** 6, k) for k, s in enumerate(whole)]
    got, rec = cell_colour_passes(matted, (plates, photos), fits, sa, gains, serial_map)
    assert rrec["coloured"] > 0 and rec["coloured"] == rrec["coloured"] and rec["crossed"] == rrec["crossed"]
    assert rec["views_without_alpha_error"] == rrec["views_without_alpha_error"] == 1
    for r, g in zip(ref, got, strict=True):
        assert np.array_equal(r.rgb, g.rgb) and np.array_equal(r.alpha, g.alpha)
    assert got[2] is matted[2] and not np.array_equal(got[0].rgb, matted[0].rgb)


def _lines(photos, plates, matted):
    """Every matted view's line samples (capture.matting_lines.line_samples) and its whole fit sample."""
    whole = [ml.line_samples(s.camera, photos[k].linear_rgb, plates[k].background, plates[k].known, s.alpha, s.rgb,
                             s.depth, plates[k].estimated, plates[k].sigma) for k, s in enumerate(matted)]
    return whole, [mc.fit_sample(s, 10 ** 6, k) for k, s in enumerate(whole)]


@pytest.mark.parametrize("gate", [True, False])
def test_lines_that_do_not_agree_give_no_pixel_its_cubes_colour(monkeypatch, gate):
    """AGREEING_GATE: where fewer than MIN_AGREEING of the lines agree with the matte's alpha, the stage and its
    reference colour nothing and say why; with the bar at the scene's own share plus a little, both skip; at the
    share minus a little, both colour as before.  Gate off: the bar does not matter."""
    monkeypatch.setattr(mk, "POOL_ALPHA_ERROR", False)
    monkeypatch.setattr(mc, "AGREEING_GATE", gate)
    photos, plates, matted = _scene()
    sa, gains = [0.1, 0.08, None], None
    whole, fits = _lines(photos, plates, matted)
    _, rec = cell_colour_passes(matted, (plates, photos), fits, sa, gains, serial_map)
    share = rec["global"]["gate" if mc.AGREEING_BEFORE else "agreeing"]["share"]
    assert 0 < share <= 1 and rec["coloured"] > 0
    monkeypatch.setattr(mc, "MIN_AGREEING", share + 0.01)
    got, rec = cell_colour_passes(matted, (plates, photos), fits, sa, gains, serial_map)
    _, rrec = cell_colour_stage(tuple(matted), whole, sa, gains, lambda s: s)
    if gate:
        assert rec["coloured"] == rrec["coloured"] == 0 and "agree" in rec["reason"] and "agree" in rrec["reason"]
        assert all(g is m for g, m in zip(got, matted, strict=True))
    else:
        assert rec["coloured"] > 0 and rrec["coloured"] > 0
    monkeypatch.setattr(mc, "MIN_AGREEING", share - 0.01)
    _, rec = cell_colour_passes(matted, (plates, photos), fits, sa, gains, serial_map)
    assert rec["coloured"] > 0


@pytest.mark.parametrize("gate", [True, False])
def test_a_scattered_crossing_gives_no_pixel_its_cubes_colour(monkeypatch, caplog, gate):
    """SIGMA_GATE: where the object's crossing errs by more than MAX_OBJECT_SIGMA, the stage and its reference colour
    nothing and say why, and the scans are the matte's; with the bar a little under the scene's own sigma both skip,
    a little over it both colour as before.  Gate off: the bar does not matter."""
    monkeypatch.setattr(mk, "POOL_ALPHA_ERROR", False)
    monkeypatch.setattr(mc, "SIGMA_GATE", gate)
    photos, plates, matted = _scene()
    sa, gains = [0.1, 0.08, None], None
    whole, fits = _lines(photos, plates, matted)
    monkeypatch.setattr(mc, "MAX_OBJECT_SIGMA", 1.0)
    _, rec = cell_colour_passes(matted, (plates, photos), fits, sa, gains, serial_map)
    sigma = rec["global"]["sigma"]
    assert 0 < sigma < 1.0 and rec["coloured"] > 0
    monkeypatch.setattr(mc, "MAX_OBJECT_SIGMA", 0.99 * sigma)
    with caplog.at_level("INFO", logger="furrow.capture"):
        got, rec = cell_colour_passes(matted, (plates, photos), fits, sa, gains, serial_map)
    _, rrec = cell_colour_stage(tuple(matted), whole, sa, gains, lambda s: s)
    if gate:
        assert rec["coloured"] == rrec["coloured"] == 0
        assert "scattered" in rec["reason"] and "scattered" in rrec["reason"]
        assert any("keeps its own colour" in r.getMessage() and "scattered" in r.getMessage() for r in caplog.records)
        assert all(g is m for g, m in zip(got, matted, strict=True))
    else:
        assert rec["coloured"] > 0 and rrec["coloured"] > 0
    monkeypatch.setattr(mc, "MAX_OBJECT_SIGMA", 1.01 * sigma)
    _, rec = cell_colour_passes(matted, (plates, photos), fits, sa, gains, serial_map)
    assert rec["coloured"] > 0


def test_a_capture_the_gate_skips_crosses_no_cube(monkeypatch):
    """AGREEING_BEFORE: the gate reads the first pass's share before any crossing, so a capture it skips never
    crosses its cubes (the phone captures' 1.5 s), in the stage and its reference; the share is the one the first
    pass finds (capture.matting_contrast.agreeing_lines on the same arguments)."""
    monkeypatch.setattr(mk, "POOL_ALPHA_ERROR", False)
    photos, plates, matted = _scene()
    sa = [0.1, 0.08, None]
    whole, fits = _lines(photos, plates, matted)
    _, rec = cell_colour_passes(matted, (plates, photos), fits, sa, None, serial_map)
    share = rec["global"]["gate"]["share"]
    monkeypatch.setattr(mc, "MIN_AGREEING", share + 0.01)

    def no_crossing(*args, **kwargs):
        raise AssertionError("crossed the cubes of a capture the gate skips")

    monkeypatch.setattr(mc, "cross_cells", no_crossing)
    import capture.matting_global as mg
    monkeypatch.setattr(mg, "cross_cells", no_crossing)
    got, rec = cell_colour_passes(matted, (plates, photos), fits, sa, None, serial_map)
    _, rrec = cell_colour_stage(tuple(matted), whole, sa, None, lambda s: s)
    assert rec["coloured"] == rrec["coloured"] == 0 and rec["global"]["agreeing"]["share"] == share
    assert all(g is m for g, m in zip(got, matted, strict=True))


def _across_scene(seed: int = 3, n: int = 4000):
    """Partial pixels of needles whose true colours scatter about their cube's colour, before a seen background:
    (C, B, the cube's colour F_c, the true alpha and colour)."""
    rng = np.random.default_rng(seed)
    F_c = np.array([0.05, 0.12, 0.04])
    F_t = np.clip(F_c + rng.normal(0, 0.03, (n, 3)), 0.0, 1.0)
    a_t = rng.uniform(0.2, 0.8, n)
    B = rng.uniform(0.2, 0.6, (n, 3))
    C = a_t[:, None] * F_t + (1 - a_t[:, None]) * B
    return C, B, np.tile(F_c, (n, 1)), a_t, F_t


def test_the_photos_part_across_the_line_brings_back_the_needles_colour_where_the_plate_saw_b():
    C, B, F_c, a_t, F_t = _across_scene()
    imp = np.clip(ml._implied(C, B, F_c), 0.0, 1.0)
    sig2 = np.full(len(C), 3 * 0.03 ** 2)  # the cube colour's expected error: the needles' own scatter
    seen = np.zeros(len(C))
    every = np.ones(len(C), bool)
    out, n = mc.across_line(C, B, F_c, imp, sig2, seen, every)
    before = np.sqrt(((imp[:, None] * F_c - a_t[:, None] * F_t) ** 2).sum(-1).mean())
    after = np.sqrt(((imp[:, None] * out - a_t[:, None] * F_t) ** 2).sum(-1).mean())
    # what is left is the error along the line, (a_t - imp) B: the implied alpha of the cube's colour (0.029 -> 0.019)
    assert n == len(C) and after < 0.75 * before, (before, after)
    # an unsure cube colour: the premultiplied colour is the photo's, C - (1 - imp) B, where nothing is clipped
    out, _ = mc.across_line(C, B, F_c, imp, np.full(len(C), 1e6), seen, every)
    inside = np.all((out > 0) & (out < 1), -1)
    assert inside.mean() > 0.5
    np.testing.assert_allclose((imp[:, None] * out)[inside], (C - (1 - imp[:, None]) * B)[inside], atol=1e-6)


def test_the_part_across_the_line_is_left_out_where_the_plate_is_unsure_or_the_sample_unusable():
    C, B, F_c, _, _ = _across_scene()
    imp = np.clip(ml._implied(C, B, F_c), 0.0, 1.0)
    sig2 = np.full(len(C), 3 * 0.03 ** 2)
    out, _ = mc.across_line(C, B, F_c, imp, sig2, np.ones(len(C)), np.ones(len(C), bool))  # sigma_B 1
    assert np.abs(out - F_c).max() < 0.01
    out, n = mc.across_line(C, B, F_c, imp, sig2, np.zeros(len(C)), np.zeros(len(C), bool))  # not crossed / usable
    assert n == 0 and np.array_equal(out, F_c)


def test_the_switch_off_gives_the_cubes_colours(monkeypatch):
    monkeypatch.setattr(mk, "POOL_ALPHA_ERROR", False)
    samples = _views()
    sa = [0.1, None, 0.05]
    on, _ = ml.cell_colours(samples, sa, cells=2)
    monkeypatch.setattr(mc, "KEEP_ACROSS", False)
    off, rec = ml.cell_colours(samples, sa, cells=2)
    got, *_ = _two_passes(samples, sa, None, cap=10 ** 6)
    assert rec["across"] == 0
    changed = 0
    for r, c, o in zip(off, got, on, strict=True):
        if r is not None:
            assert all(np.array_equal(x, y) for x, y in zip(r, c, strict=True))  # both paths: the cube colours
            assert np.array_equal(r[0], o[0]) and np.array_equal(r[2], o[2])  # the same pixels and alphas
            changed += int(np.count_nonzero(np.any(r[1] != o[1], -1)))
    assert changed > 0


def test_the_object_colours_error_is_its_crossings_sigma_squared(monkeypatch):
    F_obj = np.array([0.05, 0.1, 0.03])
    assert mc.object_sig2(F_obj, {"sigma": 0.012}) == pytest.approx(0.012 ** 2)
    assert mc.object_sig2(None, {"sigma": 0.012}) is None  # no object colour: its pixels keep theirs
    assert mc.object_sig2(F_obj, {"reason": "the object's lines do not cross"}) is None
    monkeypatch.setattr(mc, "OBJECT_ACROSS", False)
    assert mc.object_sig2(F_obj, {"sigma": 0.012}) is None

"""Round 14's passes of the plate stage against their references, bit for bit: capture.plate_fast (the
need masks' union, the lines' samples), the compiled box weights (capture.plate_weight), the lines'
channel maxima (capture.plate_lines), the band's crossing share by one flat index
(capture.matting_cells)."""

from __future__ import annotations

import numpy as np
import pytest

import capture.matting_cells as mc
import capture.plate_fast as pf
import capture.plate_lines as pl
import capture.plate_weight as pw
from capture.plate_fixed import _near_weight
from capture.plate_threads import thread_map


def _bits(a: np.ndarray) -> bytes:
    return np.ascontiguousarray(a).tobytes()


def _switch(monkeypatch, mod, name, on, fn, *args):
    """``fn(*args)`` with ``mod.name`` set to ``on``."""
    monkeypatch.setattr(mod, name, on)
    return fn(*args)


@pytest.mark.parametrize("n", [1, 2, 9])
def test_the_union_is_numpys(n, monkeypatch):
    rng = np.random.default_rng(n)
    masks = [rng.random((37, 53)) < p for p in np.linspace(0.001, 0.3, n)]
    got = _switch(monkeypatch, pf, "DRAW_IN_PLACE", True, lambda: pf.union(masks))
    want = _switch(monkeypatch, pf, "DRAW_IN_PLACE", False, lambda: pf.union(masks))
    assert got.dtype == want.dtype == bool
    np.testing.assert_array_equal(got, want)
    assert not np.shares_memory(got, masks[0])  # the first mask is not or-ed into


def _own(rng, k=7, n=1001):
    """float16 colour codes with the edge cases: subnormal, negative, NaN, +-inf, 0 and -0, above 1."""
    own = rng.uniform(-0.05, 1.3, (k, n, 3)).astype(np.float16)
    flat = own.reshape(-1)
    specials = np.array([np.nan, np.inf, -np.inf, 0.0, -0.0, 6e-8, 1.0, 65504.0], np.float16)
    flat[rng.choice(flat.size, 200, replace=False)] = rng.choice(specials, 200)
    return own


@pytest.mark.parametrize("threads", [1, 2])
def test_the_lines_samples_are_numpys(threads, monkeypatch):
    rng = np.random.default_rng(4)
    own = _own(rng)
    gains = np.exp(rng.normal(0.0, 0.4, (11, 3)))
    gains[3] = [1e-300, 1e300, 1.0]  # a float64 product outside float32 (0 and inf after rounding)
    frames = [0, 3, 4, 6, 7, 9, 10]
    tm = lambda fn, items: thread_map(fn, items, threads)
    got = _switch(monkeypatch, pf, "DRAW_IN_PLACE", True, lambda: pf.scaled_samples(own, gains, frames, tm))
    want = _switch(monkeypatch, pf, "DRAW_IN_PLACE", False, lambda: pf.scaled_samples(own, gains, frames, tm))
    assert got.dtype == want.dtype == np.float32 and got.shape == want.shape
    assert _bits(got) == _bits(want)
    # the test can fail: the product taken in float32 rounds differently somewhere
    f32 = np.stack([own[k].astype(np.float32) * gains[f].astype(np.float32) for k, f in enumerate(frames)])
    assert _bits(f32) != _bits(want)


@pytest.mark.parametrize("shape", [(894, 1192), (120, 97)])
def test_the_compiled_box_weights_are_numpys(shape, monkeypatch):
    rng = np.random.default_rng(shape[0])
    H, W = shape
    for band, exclude in [(17, 4), (3, 0), (40, 39)]:
        for m in (rng.random(shape) < 3e-4, np.pad(np.ones((H // 3, W // 4), bool), ((H // 3, H - 2 * (H // 3)),
                                                                                      (5, W - 5 - W // 4)))):
            got = _switch(monkeypatch, pw, "WEIGHT_COMPILED", True, pw.near_weight_box, m, band, exclude)
            ref = _switch(monkeypatch, pw, "WEIGHT_COMPILED", False, pw.near_weight_box, m, band, exclude)
            assert _bits(got) == _bits(ref)
            assert _bits(got) == _bits(_near_weight(m, band, exclude))


def test_the_compiled_box_weights_can_differ(monkeypatch):
    """The comparison can fail: a band one pixel narrower in the compiled pass changes weights."""
    m = np.zeros((80, 90), bool)
    m[30:40, 40:50] = True
    ref = _switch(monkeypatch, pw, "WEIGHT_COMPILED", False, lambda: pw.near_weight_box(m, 12, 3))
    import cv2

    from capture.matting_scale import object_box

    out = np.ones(m.shape, np.float32)
    box = object_box(m, 12 + pw.BOX_MARGIN_PX)
    d32 = cv2.distanceTransform(np.logical_not(m[box]).view(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    pw._box_weights(d32, 11, 3, out[box])
    assert _bits(out) != _bits(ref)


def _line_samples(rng, K: int, N: int):
    """(palette (4, 3), samples (K, N, 3) float64): K frames of N pixels, each a mix of a palette colour over
    the pixel's background at alpha 0-0.9 (the first two frames clean), clipped to [0, 1], 5 % NaN."""
    pal = rng.uniform(0.02, 0.3, (4, 3))
    B = rng.uniform(0.1, 1.2, (N, 3))
    a = rng.uniform(0.0, 0.9, (K, N))
    a[:2] = 0.0
    s = np.clip(a[..., None] * pal[rng.integers(0, 4, (K, N))] + (1 - a[..., None]) * B[None], 0.0, 1.0)
    s[rng.random((K, N)) < 0.05] = np.nan
    return pal, s


def test_the_lines_channel_maxima_are_numpys(monkeypatch):
    """unseen_background (censored and not) and line_vertex with LINES_CHANNEL_MAX on and off: the same
    backgrounds, bounds and sigma bit for bit, on samples with NaN, +-inf and blown-out frames."""
    rng = np.random.default_rng(12)
    K, N = 12, 3000
    pal, s = _line_samples(rng, K, N)
    s[0, :5] = [np.inf, 0.2, 0.3]
    opaque = rng.random((K, N)) < 0.1
    covered = opaque | (rng.random((K, N)) < 0.1)
    hot = np.nan_to_num(s).max(-1) >= 0.975

    def run():
        out = []
        for h in (None, hot):
            bound, sigma = np.zeros(N, bool), np.zeros(N)
            out += [pl.unseen_background(s, pal, opaque, covered, h, bound, sigma), bound, sigma]
        out += list(pl.line_vertex(s, pal))
        return out

    got = _switch(monkeypatch, pl, "LINES_CHANNEL_MAX", True, run)
    want = _switch(monkeypatch, pl, "LINES_CHANNEL_MAX", False, run)
    assert np.isfinite(want[0][:, 0]).mean() > 0.5 and want[4].any()  # the scene fills and bounds
    for g, w in zip(got, want, strict=True):
        assert _bits(g) == _bits(w)


def test_the_band_crossing_by_one_index_is_the_boolean_ones(monkeypatch):
    rng = np.random.default_rng(3)
    H, W = 70, 90
    img = rng.uniform(0.0, 1.0, (H, W, 3)).astype(np.float16)
    B = rng.uniform(0.0, 1.0, (H, W, 3)).astype(np.float32)
    B[rng.random((H, W)) < 0.1] = 0.99  # blown out
    band = rng.random((H, W)) < 0.4
    known, est, opaque = (rng.random((H, W)) < p for p in (0.7, 0.2, 0.2))
    for args in [(img, band, B, known), (img, band, B, known, est, opaque), (img, band, B, known, None, opaque, 0.3)]:
        got = _switch(monkeypatch, mc, "CROSSING_FLAT", True, mc.band_crossing, *args)
        want = _switch(monkeypatch, mc, "CROSSING_FLAT", False, mc.band_crossing, *args)
        assert 0.0 < want < 1.0 and got == want


@pytest.mark.parametrize("with_hot", [False, True])
def test_the_lines_chunks_taking_their_columns_are_the_copied_ones(with_hot, monkeypatch):
    """unseen_at against capture.plate_fixed._unseen_chunks of the copied columns: the same backgrounds,
    bounds and sigma bit for bit (chunks of 97 pixels and the module's)."""
    from capture import plate_fixed

    rng = np.random.default_rng(21)
    K, N = 10, 1500
    pal, s = _line_samples(rng, K, N)
    s = s.astype(np.float32)
    opaque, covered = rng.random((K, N)) < 0.1, rng.random((K, N)) < 0.2
    hot = (np.nan_to_num(s).max(-1) >= 0.975) if with_hot else None
    idx = np.flatnonzero(rng.random(N) < 0.6)
    for chunk in (97, plate_fixed.FILL_CHUNK):
        monkeypatch.setattr(plate_fixed, "FILL_CHUNK", chunk)
        b1, s1 = np.zeros(len(idx), bool), np.zeros(len(idx))
        b2, s2 = np.zeros(len(idx), bool), np.zeros(len(idx))
        got = pf.unseen_at(s, idx, pal, opaque, covered, hot, b1, s1, chunk)
        want = plate_fixed._unseen_chunks(s[:, idx], pal, opaque[:, idx], covered[:, idx],
                                          None if hot is None else hot[:, idx], b2, s2)
        assert np.isfinite(want[:, 0]).mean() > 0.3
        for g, w in ((got, want), (b1, b2), (s1, s2)):
            assert _bits(g) == _bits(w)
    shifted = pf.unseen_at(s, idx[::-1].copy(), pal, opaque, covered, hot, b1, s1, 97)  # the test can fail
    assert _bits(shifted) != _bits(want)


def test_the_room_test_counted_is_numpys(monkeypatch):
    """room_counts are the masks' sums; room_depth with DRAW_IN_PLACE on and off the same (None or the depth)."""
    from capture.plate_reproject import ROOM_MIN_FRACTION, room_depth

    rng = np.random.default_rng(8)
    H, W = 60, 80
    depth = rng.uniform(0.5, 3.0, (H, W)).astype(np.float32)
    depth[rng.random((H, W)) < 0.2] = 0.0
    depth[0, :4] = np.nan
    ring = rng.random((H, W)) < 0.3
    for p_off in (0.05, 0.9):
        off = rng.random((H, W)) < p_off
        counts = _switch(monkeypatch, pf, "DRAW_IN_PLACE", True, pf.room_counts, ring, off, depth)
        assert counts == (int(ring.sum()), int((ring & off & (depth > 0)).sum()))
        got = _switch(monkeypatch, pf, "DRAW_IN_PLACE", True, room_depth, depth, ring, off)
        want = _switch(monkeypatch, pf, "DRAW_IN_PLACE", False, room_depth, depth, ring, off)
        assert (got is None) == (want is None) == (counts[1] < ROOM_MIN_FRACTION * counts[0])
        assert got is None or _bits(got) == _bits(want)
    monkeypatch.setattr(pf, "DRAW_IN_PLACE", True)
    assert pf.room_counts(np.zeros((H, W), bool), off, depth) == (0, 0)
    assert pf.room_counts(ring.astype(np.uint8), off, depth) is None

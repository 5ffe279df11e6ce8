"""capture.matting_interior: before a blown-out plate, the object's interior keeps its photo's colour."""

import numpy as np

import capture.matting_interior as mi
import capture.matting_known as mk
from capture.matting_scale import _full_colour

BODY_MEAN = np.array([0.07, 0.04, 0.02])
WINDOW = 4.0  # the window's true radiance: the plate holds it clipped at 1


def _body_before_window(seed: int = 0):
    """A 60 x 80 crop: an opaque textured body (rows 15-44, columns 15-64; colour BODY_MEAN +- 0.015 per pixel)
    with a fringe of alpha 0.9 one pixel wide around it, before a dark wall (0.05, known) in columns < 30 and a
    window the plate holds blown out (1.0) from column 30 on.  The photo: the body's colour, but in the fringe
    0.9 F + 0.1 B and, before the window, 0.9 F + 0.1 x WINDOW; the body within INTERIOR_PX of the fringe gets 0.05
    of the window's light more (the camera's spread; the plate, clipped at 1, cannot take it out).  (C, alpha,
    plate B, known, the true colour F)."""
    rng = np.random.default_rng(seed)
    h, w = 60, 80
    a = np.zeros((h, w))
    a[14:46, 14:66] = 0.9
    a[15:45, 15:65] = 1.0
    F = np.clip(BODY_MEAN + rng.uniform(-0.015, 0.015, (h, w, 3)), 0, 1)
    B = np.full((h, w, 3), 0.05)
    B[:, 30:] = 1.0
    behind = np.where((np.arange(w) >= 30)[None, :, None], WINDOW, B)
    C = a[..., None] * F + (1 - a[..., None]) * behind
    _, near = _rings()
    C[near & (np.arange(w) >= 30)] += 0.05
    return np.clip(C, 0.0, 1.0), a, B, np.ones((h, w), bool), F


def _fallback(image, alpha, need):
    return image


def _rings():
    """(interior, the body's pixels within INTERIOR_PX of its edge) of :func:`_body_before_window`, before the
    window (columns >= 30)."""
    r = mi.INTERIOR_PX
    inner = np.zeros((60, 80), bool)
    inner[15 + r:45 - r, 15 + r:65 - r] = True
    edge = np.zeros((60, 80), bool)
    edge[15:45, 15:65] = True
    window = np.arange(80) >= 30
    return inner & window, edge & ~inner & window


def test_the_interior_is_named_and_the_body_near_its_edge_is_not():
    C, a, B, known, _ = _body_before_window()
    got = mi.interior(C, a, B, known, mk.OPAQUE_ALPHA, mk.CLIP_LEVEL)
    inner, near = _rings()
    assert np.array_equal(got, inner) and not (got & near).any()


def test_interior_pixels_take_their_photo_and_the_rest_the_fill():
    """Before the window the interior's colour is the true colour exactly (the photo); the body within 2 px of the
    fringe keeps the fill from the body before the wall (its photo holds the window's light)."""
    C, a, B, known, F_true = _body_before_window()
    rec = {}
    F = mk.foreground_colour(C, a, B, known, _fallback, rec)
    inner, near = _rings()
    np.testing.assert_allclose(F[inner], F_true[inner], atol=1e-12)
    assert rec["interior"] == int(inner.sum())
    assert np.abs(F[near] - F_true[near]).mean() < 0.02 < np.abs(C[near] - F_true[near]).mean()


def test_switch_off_fills_the_interior(monkeypatch):
    """As before this step: the interior before the window is the fill from the body before the wall."""
    C, a, B, known, F_true = _body_before_window()
    monkeypatch.setattr(mi, "INTERIOR_PHOTO", False)
    F = mk.foreground_colour(C, a, B, known, _fallback)
    inner, _ = _rings()
    assert np.abs(F[inner] - F_true[inner]).max() > 0.005


def test_a_clipped_photo_or_a_partial_neighbour_is_not_interior():
    C, a, B, known, _ = _body_before_window()
    C[30, 40] = 1.0  # clipped: no colour in it
    a[25, 40] = 0.99  # a gap: no pixel within 2 px of it is interior
    got = mi.interior(C, a, B, known, mk.OPAQUE_ALPHA, mk.CLIP_LEVEL)
    assert not got[30, 40] and not got[23:28, 38:43].any() and got[30, 50]


def test_the_working_resolution_colour_keeps_the_interior_too():
    """capture.matting_scale._full_colour (the working resolution's colour at full size) gives the interior its
    photo, as capture.matting_known.foreground_colour does, and the fill it was handed elsewhere before the
    window; the same with the compiled pass and numpy."""
    C, a, B, known, F_true = _body_before_window()
    f_up = np.full(C.shape, 0.5, np.float32)
    inner, near = _rings()
    out = _full_colour(C.astype(np.float32), a, B.astype(np.float32), known, f_up)
    np.testing.assert_allclose(out[inner], F_true[inner], atol=1e-7)  # float32 photo
    assert np.all(out[near] == 0.5)


def _all_before_window():
    """:func:`_body_before_window` with the window behind the whole crop (no sure pixel anywhere: the fill's sources
    are the opaque pixels, capture.matting_known.OPAQUE_SOURCES); the body within INTERIOR_PX of the fringe holds
    0.05 of the window's light on every side."""
    C, a, B, known, F = _body_before_window()
    B[:] = 1.0
    C = np.clip(a[..., None] * F + (1 - a[..., None]) * WINDOW, 0.0, 1.0)
    inner = np.zeros(a.shape, bool)
    inner[15 + mi.INTERIOR_PX:45 - mi.INTERIOR_PX, 15 + mi.INTERIOR_PX:65 - mi.INTERIOR_PX] = True
    near = (a >= 1.0) & ~inner
    C[near] += 0.05
    return C, a, B, known, F, inner, near


def test_with_no_sure_pixel_the_fill_comes_from_the_interior_not_the_lit_edge(monkeypatch):
    """No sure pixel: the opaque pixels are the fill's sources; before the window only the interior's count, so the
    body's lit edge takes the interior's colour (within the texture's 0.015), not its own photo (0.05 too bright);
    INTERIOR_SOURCES off: the edge is its own source and keeps the window's light."""
    C, a, B, known, F_true, inner, near = _all_before_window()
    F = mk.foreground_colour(C, a, B, known, _fallback)
    np.testing.assert_allclose(F[inner], F_true[inner], atol=1e-12)
    assert np.abs(F[near] - F_true[near]).mean() < 0.02
    monkeypatch.setattr(mi, "INTERIOR_SOURCES", False)
    F_off = mk.foreground_colour(C, a, B, known, _fallback)
    assert np.abs(F_off[near] - F_true[near]).mean() > 0.04


def _ball_before_window():
    """A 60 x 80 crop: an object (rows 10-49, columns 10-69) the matte calls opaque, whose background no frame saw;
    the plate known around it, dark (0.1) left of column 40 and a blown-out window (1.0) from there on.  Its colour
    is BODY_MEAN +- 0.015, but its last 3 columns are truly alpha 0.8 before the window (radiance WINDOW): their
    photo holds 0.2 x WINDOW of the window's light.  (C, alpha, plate B, known, true colour, the lit band)."""
    rng = np.random.default_rng(1)
    h, w = 60, 80
    a = np.zeros((h, w))
    a[10:50, 10:70] = 1.0
    F = np.clip(BODY_MEAN + rng.uniform(-0.015, 0.015, (h, w, 3)), 0, 1)
    B = np.where((np.arange(w) >= 40)[None, :, None], 1.0, 0.1) * np.ones((h, w, 3))
    known = a == 0
    band = np.zeros((h, w), bool)
    band[10:50, 67:70] = True
    C = np.where(known[..., None], B, F)
    C[band] = 0.8 * F[band] + 0.2 * WINDOW
    return np.clip(C, 0, 1), a, B, known, F, band


def test_an_unseen_band_before_a_window_takes_the_fill_not_its_lit_photo(monkeypatch):
    """The band that holds the window's light takes the body's fill (within the texture); the body (its photo not
    brighter than the fill) keeps its photo; with UNSEEN_BLOWN off the band keeps its photo (0.8 too bright)."""
    C, a, B, known, F_true, band = _ball_before_window()
    rec = {}
    F = mk.foreground_colour(C, a, B, known, _fallback, rec)
    assert np.abs(F[band] - F_true[band]).max() < 0.03 and rec["unseen_blown"] == int(band.sum())
    body = (a >= 1.0) & ~band
    np.testing.assert_allclose(F[body], C[body], atol=1e-12)
    monkeypatch.setattr(mi, "UNSEEN_BLOWN", False)
    F_off = mk.foreground_colour(C, a, B, known, _fallback)
    assert np.abs(F_off[band] - F_true[band]).min() > 0.5


def test_the_working_resolution_colour_fills_the_unseen_band_too():
    C, a, B, known, F_true, band = _ball_before_window()
    f_up = np.full(C.shape, 0.5, np.float32)
    out = _full_colour(C.astype(np.float32), a, B.astype(np.float32), known, f_up)
    assert np.abs(out[band] - F_true[band]).max() < 0.03

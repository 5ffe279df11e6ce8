"""capture.matting_fringe: a partial pixel before a blown-out wall takes the colour the view measured on its fringe."""

import numpy as np
import pytest

import capture.matting_fringe as mf
import capture.matting_known as mk

BODY = np.array([0.10, 0.06, 0.04])
GLOW = np.array([0.35, 0.29, 0.17])


def _backlit(dark_behind_fringe: float = 0.05, fringe_cols: int = 60):
    """An 80 x 120 crop: an opaque body (rows 20-59, columns 20-99) of colour BODY, a fringe of alpha 0.5 and colour
    GLOW three pixels wide around it; the background dark (``dark_behind_fringe``, known) in columns < 60, a window
    the plate holds blown out (1.0) in columns >= 60, where the photo is not clipped (C = 0.5 GLOW + 0.5).  The
    fringe keeps its alpha only in its first ``fringe_cols`` columns of the dark side."""
    h, w = 80, 120
    a = np.zeros((h, w))
    a[17:63, 17:103] = 0.5
    a[20:60, 20:100] = 1.0
    a[:, 17 + fringe_cols:60] = np.where(a[:, 17 + fringe_cols:60] == 0.5, 0.0, a[:, 17 + fringe_cols:60])
    F = np.where((a >= 1.0)[..., None], BODY, GLOW)
    B = np.full((h, w, 3), dark_behind_fringe)
    B[:, 60:] = 1.0
    C = np.clip(a[..., None] * F + (1 - a[..., None]) * B, 0.0, 1.0)
    return C, a, B, np.ones((h, w), bool)


def _fallback(image, alpha, need):
    return image


def test_a_fringe_before_a_blown_window_takes_the_measured_fringe():
    """The fringe's pixels before the window get the colour unmixed on the dark side (exact there: GLOW), the body's
    pixels before the window the body's; the record counts the pixels."""
    C, a, B, known = _backlit()
    rec = {}
    F = mk.foreground_colour(C, a, B, known, _fallback, rec)
    lit = (a == 0.5) & (np.arange(120) >= 60)
    np.testing.assert_allclose(F[lit], np.broadcast_to(GLOW, F[lit].shape), atol=1e-9)
    body = (a == 1.0) & (np.arange(120) >= 60)
    np.testing.assert_allclose(F[body], np.broadcast_to(BODY, F[body].shape), atol=1e-9)
    assert rec["fringe"] == int(lit.sum())


def test_switch_off_gives_the_body_fill(monkeypatch):
    """FRINGE_FILL off: the fringe before the window takes the body's colour, as before (the test fails if the new
    step does nothing)."""
    C, a, B, known = _backlit()
    lit = (a == 0.5) & (np.arange(120) >= 60)
    monkeypatch.setattr(mf, "FRINGE_FILL", False)
    rec = {}
    F = mk.foreground_colour(C, a, B, known, _fallback, rec)
    np.testing.assert_allclose(F[lit], np.broadcast_to(BODY, F[lit].shape), atol=1e-9)
    assert "fringe" not in rec


@pytest.mark.parametrize("case", ["few", "like the background"])
def test_no_fringe_measured_keeps_the_body_fill(case):
    """Fewer than MIN_SOURCES measured fringe pixels (the fringe on the dark side cut to one column: 46 pixels), or a
    fringe the dark side cannot tell from its background (B = GLOW there: |F - B| < FRINGE_SEPARATION): the body's
    fill, the same as with the switch off."""
    C, a, B, known = _backlit(fringe_cols=1) if case == "few" else _backlit(dark_behind_fringe=0.0)
    if case != "few":
        B[:, :60] = GLOW
        C = np.clip(a[..., None] * np.where((a >= 1.0)[..., None], BODY, GLOW) + (1 - a[..., None]) * B, 0.0, 1.0)
    assert mf.fringe_sources(np.clip(B + (C - B) / np.maximum(a, 1e-6)[..., None], 0, 1), B, a,
                             known & ~mk.clipped(C, B) & (a > 0), mk.FILL_ALPHA).sum() < mk.MIN_SOURCES
    rec = {}
    F = mk.foreground_colour(C, a, B, known, _fallback, rec)
    lit = (a == 0.5) & (np.arange(120) >= 60)
    np.testing.assert_allclose(F[lit], np.broadcast_to(BODY, F[lit].shape), atol=1e-9)
    assert "fringe" not in rec


def test_a_bright_background_not_known_keeps_the_body_fill():
    """Before a bright background that no frame saw (the plate unknown there, not blown out), the fill stays the
    body's: the fringe's colour went only where the plate is blown (fur before a background of its own colour lost
    0.29 dB held out when it went there too: docs/matting.md "The fringe's colour before a blown window")."""
    C, a, B, known = _backlit(dark_behind_fringe=0.3)  # the nearest known plate bright (FILL_BRIGHT): a fill
    B[:, 60:] = 0.6
    C = np.clip(a[..., None] * np.where((a >= 1.0)[..., None], BODY, GLOW) + (1 - a[..., None]) * B, 0.0, 1.0)
    known[:, 60:] = False
    rec = {}
    F = mk.foreground_colour(C, a, B, known, _fallback, rec)
    lit = (a == 0.5) & (np.arange(120) >= 60)
    np.testing.assert_allclose(F[lit], np.broadcast_to(BODY, F[lit].shape), atol=1e-9)
    assert "fringe" not in rec


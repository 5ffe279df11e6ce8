"""capture.matting_cap.blown_partial and the matte record's views before a blown-out background
(docs/matting.md "Fur before a blown-out wall")."""

import numpy as np

from capture.matting import MatteConfig
from capture.matting_cap import BLOWN_VIEW_SHARE, blown_partial
from capture.matting_known import CLIP_LEVEL


def _view(rng, h=40, w=50, blown_cols=20):
    """A seeded matte (a third 0, a third partial, a third 1), a plate blown out (one channel at or above CLIP_LEVEL)
    in its first ``blown_cols`` columns, and a known mask with holes."""
    alpha = rng.choice([0.0, 0.5, 1.0], size=(h, w)) * rng.uniform(0.2, 1.0, (h, w)) ** (rng.random((h, w)) < 0.5)
    alpha[rng.random((h, w)) < 0.1] = 1.0
    B = rng.uniform(0.1, 0.9, (h, w, 3))
    B[:, :blown_cols, rng.integers(0, 3)] = rng.uniform(CLIP_LEVEL, 1.2, (h, blown_cols))
    known = rng.random((h, w)) < 0.8
    return alpha, B, known


def test_the_partial_pixels_before_a_known_blown_plate_are_counted_pixel_by_pixel():
    """blown_partial against a loop over the pixels: partial (0 < alpha < 1), the plate known there, and a channel at
    or above CLIP_LEVEL; a plate just below the level or not known counts nothing."""
    rng = np.random.default_rng(72)
    alpha, B, known = _view(rng)
    want_b = want_p = 0
    for y in range(alpha.shape[0]):
        for x in range(alpha.shape[1]):
            if 0.0 < alpha[y, x] < 1.0:
                want_p += 1
                want_b += bool(known[y, x] and max(B[y, x]) >= CLIP_LEVEL)
    assert blown_partial(alpha, B, known) == (want_b, want_p)
    assert 0 < want_b < want_p
    assert blown_partial(alpha, np.minimum(B, CLIP_LEVEL - 1e-6), known) == (0, want_p)
    assert blown_partial(alpha, B, np.zeros_like(known)) == (0, want_p)


class _Work:
    """The matte record's stand-in for volume.pipeline.work.Work: ``record`` gives back what it was given."""

    def record(self, name, rec):
        return {name: rec}


def test_the_record_names_the_views_whose_share_reaches_the_level():
    """volume.surroundings.matte_record: the views whose partial pixels before a blown-out plate reach
    BLOWN_VIEW_SHARE are named by index with their share, the pixels summed over every view; a view without a
    plate (no note) and a matte-less view (None) are skipped without shifting the indices."""
    from volume.surroundings import matte_record

    base = {"method": "plate", "seconds": 0.1, "unknown": 0.1, "partial": 0.1}
    low = int(BLOWN_VIEW_SHARE * 1000) - 1
    notes = {"matte": [{**base, "blown": (0, 1000)}, None, {**base, "blown": (400, 1000)}, dict(base),
                       {**base, "blown": (low, 1000)}, {**base, "blown": (BLOWN_VIEW_SHARE * 1000, 1000)}]}
    rec = matte_record(_Work(), notes, MatteConfig())["matte"]["blown_background"]
    assert rec == {"pixels": 400 + low + int(BLOWN_VIEW_SHARE * 1000), "views": [2, 5],
                   "shares": [0.4, round(BLOWN_VIEW_SHARE, 3)], "names": ["2", "5"]}  # the stand-in has no refs


def test_the_console_names_the_views_and_says_their_colour_is_a_fill():
    """furrow.cmd_model's matte lines: the named views with their shares, in one warning; nothing when no view is
    named."""
    from rich.console import Console

    from furrow.cmd_model import _print_matte_inputs

    console = Console(record=True, width=400)
    _print_matte_inputs(console, {"blown_background": {"pixels": 9, "views": [6, 13], "shares": [0.553, 0.14],
                                                       "names": ["images/r0_v012.png", "images/r0_v026.png"]}})
    text = console.export_text()
    assert "views images/r0_v012.png (55%), images/r0_v026.png (14%)" in text
    assert "blown-out background" in text and "not a measurement" in text
    console = Console(record=True, width=400)
    _print_matte_inputs(console, {"blown_background": {"pixels": 3, "views": [], "shares": []}})
    assert console.export_text() == ""

"""capture.matting_choice: a detected plain backdrop against the view's background plate.  A dark, textured room
(a night park's grass: linear 0.03 +- 25 %) passes capture.matting.detect_backdrop's absolute tolerance; matted
against its one colour, the needles' premultiplied colour comes out worse than against the plate, which the rule
then takes; a black backdrop stays the backdrop (no plate can beat it).  Not shown here: needles darker, at 0.3 of
these colours, got a worse alpha against the exact plate than against the backdrop (alpha MSE 0.083 against 0.021;
docs/matting.md "A dark room is not a backdrop")."""

from __future__ import annotations

import numpy as np
import pytest

from capture import matting_choice as mc
from capture.camera import Camera, make_K
from capture.matting import MatteConfig, depth_trimap, detect_backdrop, matte_scan
from capture.plate import Plate
from capture.scan import Scan, srgb_to_linear, to_uint8_srgb
from tests import plate_scenes as ps

#: The dark room's mean (linear) and its texture's relative amplitude.
DARK, TEXTURE = 0.03, 0.5


def _q(x):
    """8-bit sRGB round trip of a linear image (the photo as written)."""
    return srgb_to_linear(to_uint8_srgb(x) / np.float32(255.0))


def _scan(C, D):
    h, w = D.shape
    cam = Camera(make_K(100, 100, (w - 1) / 2, (h - 1) / 2), np.eye(4), w, h)
    return Scan(np.asarray(C, np.float32), D, cam, "v")


def _dark_room():
    room = ps.room_image(128, 96, seed=3).astype(np.float64)
    return (DARK * (1 + TEXTURE * (room - room.mean()) / (room.max() - room.min()) * 2)).astype(np.float32)


def test_a_dark_textured_room_is_matted_against_its_plate():
    B = _dark_room()
    C, B, A, F, D = ps.needle_composite(background=B, seed=0)
    C = _q(C)
    assert detect_backdrop(C, depth_trimap(D)) is not None  # the absolute tolerance takes it for a backdrop
    plate = Plate(B, np.ones(A.shape, bool), 0.002, "fixed", 1.0, 0.0005, 0.0007)
    m = matte_scan(_scan(C, D), cfg=MatteConfig(), plate=plate)
    rec = m.notes["backdrop_refused"]
    assert m.method == "plate" and rec["backdrop_rmse"] > rec["plate_rmse"] == 0.0007
    # against the plate, the band's alpha and premultiplied colour are nearer the truth than against the backdrop
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(mc, "AGAINST_PLATE", False)
        b = matte_scan(_scan(C, D), cfg=MatteConfig(), plate=plate)
    assert b.method == "backdrop" and "backdrop_refused" not in b.notes
    band = (A > 0.02) & (A < 0.98)
    err = {k: (float(np.mean((x.alpha - A)[band] ** 2)),
               float(np.mean((x.alpha[..., None] * x.foreground - A[..., None] * F)[band] ** 2)))
           for k, x in (("plate", m), ("backdrop", b))}
    # measured: premultiplied 3.1e-5 against 4.0e-5, alpha 0.0303 against 0.0304 (seed 0)
    assert err["plate"][1] < 0.85 * err["backdrop"][1], err
    assert err["plate"][0] < 1.05 * err["backdrop"][0], err


def test_a_black_backdrop_stays_and_needs_no_plate():
    C, _, A, _, D = ps.needle_composite(background=np.zeros(3), seed=0)
    C = _q(C)
    black = detect_backdrop(C, depth_trimap(D))
    assert black is not None and mc.exact_backdrop(C, D, black)
    # a plate of black measures the same ring error (the partial needles beyond the depth): a tie keeps the backdrop
    e = mc.backdrop_error(C, D, np.zeros(3))
    assert e > mc.EXACT_ERROR  # those needles are in the ring; the median does not see them
    plate = Plate(np.zeros(C.shape, np.float32), np.ones(A.shape, bool), 0.002, "fixed", 1.0, 0.0, e)
    assert mc.plate_beats_backdrop(C, D, black, plate) is None
    assert matte_scan(_scan(C, D), cfg=MatteConfig(), plate=plate).method == "backdrop"
    # the dark room is not exact: the plate stage runs for it
    room = _q(ps.needle_composite(background=_dark_room(), seed=0)[0])
    assert not mc.exact_backdrop(room, D, detect_backdrop(room, depth_trimap(D)))


class _Work:
    """The matte record's stand-in for volume.pipeline.work.Work: ``record`` gives back what it was given."""

    def record(self, name, rec):
        return {name: rec}


def test_the_record_and_the_report_say_which_views_took_the_plate():
    """volume.surroundings.matte_record gathers the views' ``backdrop_refused`` notes; furrow model's report names
    capture.matting_choice with the RMS ranges, and says nothing when no backdrop was refused."""
    from io import StringIO

    from rich.console import Console

    from furrow.cmd_model import _print_surroundings
    from volume.surroundings import matte_record

    base = {"method": "plate", "seconds": 0.1, "unknown": 0.1, "partial": 0.1}
    notes = {"matte": [{**base, "backdrop_refused": {"backdrop_rmse": 0.0072, "plate_rmse": 0.0003}}, None,
                       {**base, "method": "backdrop"},
                       {**base, "backdrop_refused": {"backdrop_rmse": 0.0061, "plate_rmse": 0.0002}}]}
    rec = matte_record(_Work(), notes, MatteConfig())["matte"]
    assert rec["backdrop_refused"] == {"views": 2, "backdrop_rmse": [0.0072, 0.0061], "plate_rmse": [0.0003, 0.0002]}
    assert rec["methods"] == {"backdrop": 1, "plate": 2}

    def report(matte: dict) -> str:
        out = StringIO()
        _print_surroundings(Console(file=out, width=300), {"matte": matte})
        return out.getvalue()

    said = report(rec)
    assert "detected in 2 view(s)" in said and "RMS 0.0002-0.0003" in said and "0.0061-0.0072" in said, said
    assert "matting_choice" in said
    none = matte_record(_Work(), {"matte": [dict(base)]}, MatteConfig())["matte"]
    assert "matting_choice" not in report(none)

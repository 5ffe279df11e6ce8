"""Per kept view, how far the known-background matte's alpha is off on average, and whether the plate or the
colour it was read against carries it (issue 30, stop 73).

The default plate + matte of a room capture's kept views (their true matte hidden from the matte) against the
truth: the true matte (the room capture's ``mask_path``), the true background B_t = (C - C_black) / (1 - a_t) and
the true colour F_t = C_black / a_t from the black twin's photo, on the pixels whose true alpha is in [0.3, 0.9),
whose background a frame saw clean and whose photo is not blown out.  Per view it prints

* the matte's mean alpha error (``matte``; capture.matting.matte_scan, before the colour across the views);
* the alpha the compositing equation gives with the true colour and the plate's B (``true F``): what is left of
  the error once the colour is right, i.e. the plate's share;
* the plate's mean luminance error there, and the true background's and the true colour's mean luminance.

    PYTHONPATH=. .venv/bin/python scripts/alpha_bias_views.py ROOM BLACK_TWIN [--frames 0::2]

The room capture must not have auto exposure (the black twin's photo is the truth at the room's exposure).
"""

from __future__ import annotations

import contextlib
import io
import sys
from pathlib import Path

import numpy as np

from capture.matting import MatteConfig, matte_scan, warm_up
from capture.matting_known import CLIP_LEVEL
from capture.plate import PlateConfig, background_plates
from capture.scan import Scan

sys.path.insert(0, str(Path(__file__).parent))
from plate_error_split import kept_with_twin, room_twin_args

#: The true alpha's range read (where both the true colour and the true background are readable).
TRUE_RANGE = (0.3, 0.9)
#: Rec. 709 luminance weights (linear).
LUMA = np.array([0.2126, 0.7152, 0.0722])


def along(C: np.ndarray, B: np.ndarray, F: np.ndarray) -> np.ndarray:
    """(n,) alpha of the photo ``C`` (n, 3) on the line from ``B`` to ``F`` (n, 3 each): the projection of C - B
    on F - B, clipped to [0, 1]."""
    d = F - B
    return np.clip(((C - B) * d).sum(-1) / np.maximum((d * d).sum(-1), 1e-9), 0.0, 1.0)


def view_row(scan, out_scan, black, plate) -> dict | None:
    """The printed figures of one kept view (module docstring); None when no pixel qualifies."""
    if plate is None:
        return None
    plate = plate.full() if getattr(plate, "frame", None) is not None else plate
    with contextlib.redirect_stdout(io.StringIO()):
        m = matte_scan(Scan(scan.rgb, scan.depth, scan.camera, scan.name), out_scan.depth, MatteConfig(), plate)
    C, Cb = scan.linear_rgb.astype(np.float64), black.linear_rgb.astype(np.float64)
    at = np.asarray(scan.alpha, np.float64)
    seen = plate.known if plate.estimated is None else plate.known & ~plate.estimated
    sel = seen & (at >= TRUE_RANGE[0]) & (at < TRUE_RANGE[1]) & (C.max(-1) < CLIP_LEVEL)
    if not sel.any():
        return None
    a = at[sel]
    Bt, Ft = (C[sel] - Cb[sel]) / (1.0 - a[:, None]), Cb[sel] / a[:, None]
    Be = plate.background[sel].astype(np.float64)
    return {"n": int(sel.sum()), "matte": float(np.mean(m.alpha[sel] - a)),
            "true F": float(np.mean(along(C[sel], Be, Ft) - a)), "B error": float(np.mean((Be - Bt) @ LUMA)),
            "B": float(np.mean(Bt @ LUMA)), "F": float(np.mean(Ft @ LUMA))}


def main(argv=None) -> None:
    a = room_twin_args(__doc__, argv)
    warm_up()
    ss, bs, out, rep, views = kept_with_twin(a.room, a.black, a.frames)
    plates, rec = background_plates(views, PlateConfig(), rep.plane, (rep.focus_center, rep.focus_radius))
    print(f"{a.room}: plate {rec.get('mode')}; true alpha in [{TRUE_RANGE[0]}, {TRUE_RANGE[1]}), B seen, not blown")
    print("view  pixels  alpha error: matte / with the true F   B luminance error   true B   true F")
    for k, (s, o, b, pl) in enumerate(zip(ss.scans, out.scans, bs.scans, plates, strict=True)):
        r = view_row(s, o, b, pl)
        if r is not None:
            print(f"{k:4d} {r['n']:7d}   {r['matte']:+.3f} / {r['true F']:+.3f}              {r['B error']:+.4f}"
                  f"          {r['B']:.3f}    {r['F']:.4f}")


if __name__ == "__main__":
    main()

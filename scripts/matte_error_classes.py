"""Where the kept views' estimated matte goes wrong before a room (issue 30 fifth round): the default
plate + matte of a room capture's kept views (their true matte hidden from the matte) against the
true matte and the black twin's premultiplied colour, split by what the plate knew behind each object
pixel (seen: a frame saw it clean; lines: the frames' lines gave it, capture.plate_lines; blown: the
photo or the plate clipped, capture.matting_known.clipped; unknown) and by the true alpha's range.

    PYTHONPATH=. .venv/bin/python scripts/matte_error_classes.py ROOM BLACK_TWIN OUT_DIR

Prints per class and range: pixels, share of the summed squared alpha error, alpha MSE, mean alpha
error (bias), share and mean of the premultiplied colour's squared error (linear, summed over
channels).  OUT_DIR gets per kept view NN.npz (alpha, class map, colour, the plate and where it is known) for
scripts/hybrid_mattes.py and scripts/blown_opaque.py.
"""

from __future__ import annotations

import contextlib
import io
import sys
from pathlib import Path

import numpy as np

from capture.extent import remove_surroundings
from capture.io import read_scanset
from capture.matting import MatteConfig, matte_scan, warm_up
from capture.matting_known import clipped
from capture.plate import PlateView
from capture.scan import Scan

sys.path.insert(0, str(Path(__file__).parent))
from plate_error_split import _plates

CLASSES = ("seen", "lines", "blown", "unknown")
RANGES = ("a=0", "(0,.3)", "[.3,.7)", "[.7,1)", "a=1")


def _class_map(scan, matte, plate, seen) -> np.ndarray:
    """(H, W) int8: index into CLASSES over the object pixels (true or estimated alpha > 0), -1 elsewhere."""
    obj = (scan.alpha > 0) | (matte.alpha > 0)
    known = plate.known if plate is not None else np.zeros(obj.shape, bool)
    bg = plate.background if plate is not None else np.zeros(scan.linear_rgb.shape)
    cl = clipped(scan.linear_rgb, bg)
    cls = np.full(obj.shape, -1, np.int8)
    cls[obj & known & seen & ~cl] = 0
    cls[obj & known & ~seen & ~cl] = 1
    cls[obj & known & cl] = 2
    cls[obj & ~known] = 3
    return cls


def _print(acc: np.ndarray) -> None:
    ta, tp = acc[..., 0].sum(), acc[..., 1].sum()
    print(f"alpha SSE {ta:.1f} (frame MSE {ta / acc[0, 0, 4]:.5f})  premult SSE {tp:.2f}  "
          f"pixels {acc[..., 2].sum():.0f}")
    for c, name in enumerate(CLASSES):
        for r, rng in enumerate(RANGES + ("ALL",)):
            sa, sp, n, bias = acc[c].sum(0)[:4] if rng == "ALL" else acc[c, r, :4]
            if n:
                print(f"{name:8s} {rng:8s} n {n:8.0f} alpha share {sa / ta:6.1%} MSE {sa / n:.4f} bias {bias / n:+.3f}"
                      f"  premult share {sp / tp:6.1%} MSE {sp / n:.5f}")


def main(room: str, black: str, out_dir: str) -> None:
    warm_up()
    ss, bs = read_scanset(room, "0::2"), read_scanset(black, "0::2")
    out, rep = remove_surroundings(ss)
    views = [PlateView(o.camera, o.linear_rgb, o.depth, s.depth) for s, o in zip(ss.scans, out.scans, strict=True)]
    plates, rec, seens = _plates(views, rep)
    Path(out_dir).mkdir(parents=True, exist_ok=True)
    acc = np.zeros((len(CLASSES), len(RANGES), 5))  # alpha SSE, premult SSE, pixels, alpha error sum, frame px
    for i, (s, o, b, pl, seen) in enumerate(zip(ss.scans, out.scans, bs.scans, plates, seens, strict=True)):
        with contextlib.redirect_stdout(io.StringIO()):
            m = matte_scan(Scan(s.rgb, s.depth, s.camera, s.name), o.depth, MatteConfig(), pl)
        ta = np.asarray(s.alpha, np.float64)
        cls = _class_map(s, m, pl, seen)
        rg = np.digitize(ta, [1e-6, 0.3, 0.7, 1 - 1e-6])
        ea = (m.alpha - ta) ** 2
        ep = ((m.alpha[..., None] * m.foreground - b.linear_rgb) ** 2).sum(-1)
        for c in range(len(CLASSES)):
            for r in range(len(RANGES)):
                k = (cls == c) & (rg == r)
                acc[c, r, :4] += (ea[k].sum(), ep[k].sum(), k.sum(), (m.alpha - ta)[k].sum())
        acc[0, 0, 4] += ta.size
        full = pl.full() if pl is not None else None
        np.savez_compressed(Path(out_dir) / f"{i:02d}.npz", alpha=m.alpha.astype(np.float32), cls=cls,
                            fg=m.foreground.astype(np.float16),
                            plate=(full.background if full is not None else np.zeros_like(m.foreground)).astype(
                                np.float16),
                            known=full.known if full is not None else np.zeros(cls.shape, bool))
    print(f"{room}: plate {rec['mode']}, band known {rec.get('band_known_mean')}")
    _print(acc)


if __name__ == "__main__":
    main(*sys.argv[1:4])

"""The fixed camera's background where no frame saw it clean (capture.plate_lines) against the seen plate filled in
(push-pull) and the truth (docs/matting.md "Other rooms behind the conifer, and a fur ball before a blown-out wall").

    PYTHONPATH=. .venv/bin/python scripts/plate_lines_fringe.py ROOM_CAPTURE BLACK_TWIN

The kept views (0::2) get the pipeline's plates (as scripts/matte_error_classes.py makes them); at the pixels whose
background the frames' lines gave (not clipped, true alpha 0.05-0.7) each estimate is compared with the true
background B = (C - C_black) / (1 - a_true).  Prints the lines' bias and MAE, the fill's MAE, and, by how much the two
disagree (largest channel), the median error of each and the share of pixels where the fill is nearer the truth.
A measurement, not a method.
"""
from __future__ import annotations

import sys

import numpy as np

from capture.extent import remove_surroundings
from capture.fill import push_pull
from capture.io import read_scanset
from capture.matting_known import clipped

#: The true alpha of the pixels compared (below, B barely enters the photo; above, too little of it).
ALPHA_RANGE = (0.05, 0.7)
#: Bins of the two estimates' disagreement (linear, largest channel).
BINS = (0.0, 0.01, 0.02, 0.05, 0.1, 0.2, np.inf)


def main(room: str, black: str) -> None:
    sys.path.insert(0, str(__import__("pathlib").Path(__file__).parent))
    import matte_error_classes as mec

    ss, bs = read_scanset(room, "0::2"), read_scanset(black, "0::2")
    out, rep = remove_surroundings(ss)
    views = [mec.PlateView(o.camera, o.linear_rgb, o.depth, s.depth) for s, o in zip(ss.scans, out.scans, strict=True)]
    plates, _, seens = mec._plates(views, rep)
    d, e_lines, e_fill, bias = [], [], [], []
    for s, b, pl, seen in zip(ss.scans, bs.scans, plates, seens, strict=True):
        C, cb, t = (np.asarray(x, np.float64) for x in (s.linear_rgb, b.linear_rgb, s.alpha))
        true_b = (C - cb) / np.maximum(1.0 - t, 1e-6)[..., None]
        lines = np.asarray(pl.background, np.float64)
        fill = push_pull(lines, (pl.known & seen).astype(np.float64))
        sel = pl.known & ~seen & ~clipped(C, pl.background) & (t > ALPHA_RANGE[0]) & (t < ALPHA_RANGE[1])
        d.append(np.abs(lines - fill)[sel].max(-1))
        e_lines.append(np.abs(lines - true_b)[sel])
        e_fill.append(np.abs(fill - true_b)[sel])
        bias.append((lines - true_b)[sel])
    d, e_lines, e_fill, bias = (np.concatenate(x) for x in (d, e_lines, e_fill, bias))
    print(f"{room}: {len(d)} pixels; lines' B bias {np.round(bias.mean(0), 4).tolist()} MAE "
          f"{np.round(e_lines.mean(0), 4).tolist()}; the seen plate filled in: MAE "
          f"{np.round(e_fill.mean(0), 4).tolist()}")
    el, ef = e_lines.max(-1), e_fill.max(-1)
    for lo, hi in zip(BINS[:-1], BINS[1:]):
        k = (d >= lo) & (d < hi)
        if k.any():
            print(f"  disagree {lo:.2f}-{hi:.2f}: share {k.mean():.3f}, median error lines {np.median(el[k]):.4f} "
                  f"fill {np.median(ef[k]):.4f}, the fill nearer in {np.mean(ef[k] < el[k]):.2f}")


if __name__ == "__main__":
    main(*sys.argv[1:3])

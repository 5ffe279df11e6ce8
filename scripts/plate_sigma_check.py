"""Is the plate's uncertainty of the frames' lines' background (capture.plate.Plate.sigma,
capture.plate_lines.vertex_sigma) what its error is?  On a room capture whose kept views carry their
true matte and whose black twin gives the true premultiplied colour, the true background is
(room - black) / (1 - true alpha) where the true alpha is below TRUTH_ALPHA and nothing is blown out
(as scripts/plate_error_split.py); per estimated pixel the Euclidean |estimated B - true B| against
its sigma, by sigma's quantiles.

    PYTHONPATH=. .venv/bin/python scripts/plate_sigma_check.py ROOM_CAPTURE BLACK_TWIN [--frames 0::2]
"""

from __future__ import annotations

import argparse

import numpy as np

from capture.extent import remove_surroundings
from capture.io import read_scanset
from capture.matting_known import CLIP_LEVEL
from capture.plate import PlateConfig, PlateView, background_plates

#: The true background is read where the true alpha is below this.
TRUTH_ALPHA = 0.9


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("room")
    p.add_argument("black")
    p.add_argument("--frames", default="0::2")
    a = p.parse_args(argv)
    ss, bs = read_scanset(a.room, a.frames), read_scanset(a.black, a.frames)
    out, rep = remove_surroundings(ss)
    views = [PlateView(o.camera, o.linear_rgb, o.depth, s.depth) for s, o in zip(ss.scans, out.scans, strict=True)]
    plates, _ = background_plates(views, PlateConfig(), rep.plane, (rep.focus_center, rep.focus_radius))
    errs, sigs = [], []
    for s, b, pl in zip(ss.scans, bs.scans, plates, strict=True):
        pl = pl.full()
        if pl.estimated is None or pl.sigma is None:
            continue
        al = np.asarray(s.alpha, np.float64)[..., None]
        truth = (s.linear_rgb.astype(np.float64) - b.linear_rgb) / np.maximum(1.0 - al, 1e-6)
        m = pl.estimated & (al[..., 0] < TRUTH_ALPHA) & (truth.max(-1) < CLIP_LEVEL) & \
            (s.linear_rgb.max(-1) < CLIP_LEVEL) & np.isfinite(pl.sigma)
        errs.append(np.linalg.norm(pl.background - truth, axis=-1)[m])
        sigs.append(np.asarray(pl.sigma, np.float64)[m])
    e, sg = np.concatenate(errs), np.concatenate(sigs)
    print(f"{a.room}: {len(e)} estimated pixel-views with a readable truth; |B error| median {np.median(e):.4f}, "
          f"RMS {np.sqrt(np.mean(e ** 2)):.4f}; sigma median {np.median(sg):.4f}")
    edges = np.quantile(sg, np.linspace(0, 1, 6))
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        k = (sg >= lo) & (sg <= hi)
        print(f"  sigma {lo:.4f}-{hi:.4f}: n {k.sum():6d}  error median {np.median(e[k]):.4f}  RMS "
              f"{np.sqrt(np.mean(e[k] ** 2)):.4f}  RMS / sigma {np.sqrt(np.mean(e[k] ** 2)) / np.median(sg[k]):.2f}")


if __name__ == "__main__":
    main()

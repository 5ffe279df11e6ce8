"""The picture of docs/novel_views.md "A second depth layer": one held-out view of a room capture composited
over white (sRGB 235), the truth | gather with one layer | with the second layer, and the alpha error of each
(x ERROR_GAIN); the masked PSNR / SSIM over black and the PSNR over white of each printed.

    PYTHONPATH=. python scripts/second_layer_picture.py CAPTURE MODEL --view 13 [--crop X0 Y0 W H] -o OUT.jpg

CAPTURE: the room capture with its true mattes; MODEL: ``furrow model CAPTURE_hidden --frames 0::2``; the view is
a frame index of CAPTURE (odd: held out).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from ssim_split import _arrays, score

from capture.io import read_scanset
from capture.scan import srgb_to_linear
from render.evaluate import COMPOSITE_BACKDROPS
from render.frame import composite_over
from render.gather import reference as g
from render.metrics import as_srgb8

#: The alpha error is drawn times this (white = an error of 1 / ERROR_GAIN or more).
ERROR_GAIN = 2.0


def over_white(col: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """8-bit sRGB of premultiplied linear ``col`` over the white backdrop (render.frame.composite_over)."""
    w = float(srgb_to_linear(np.float64(COMPOSITE_BACKDROPS["white"] / 255.0)))
    return as_srgb8(np.clip(composite_over(col, alpha, (w, w, w)), 0.0, 1.0))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("capture")
    ap.add_argument("model")
    ap.add_argument("--view", type=int, required=True)
    ap.add_argument("--crop", type=int, nargs=4, metavar=("X0", "Y0", "W", "H"))
    ap.add_argument("-o", "--out", type=Path, required=True)
    a = ap.parse_args()
    import imageio.v3 as iio

    scan = read_scanset(a.capture).scans[a.view]
    cams, rgb, dep, al, meas = _arrays(a.model)
    centre = np.concatenate([c.depth_to_points(d)[0] for c, d in zip(cams, dep)]).mean(0)
    t = np.asarray(scan.alpha, np.float64)
    tiles, errs = [over_white(scan.linear_rgb.astype(np.float64), t)], [np.zeros(t.shape)]
    for name, cfg in (("one layer", g.GatherConfig(back_gap_m=0.0)), ("two layers", g.GatherConfig())):
        col, alpha, _, _ = g.gather_frame(scan.camera, None, cams, rgb, dep, centre, cfg, al, meas)
        s = score(scan, col, alpha)
        print(f"{name}: masked PSNR {s['psnr_masked']:.2f}, SSIM {s['ssim_masked']:.3f}, over white "
              f"{s['psnr_white']:.2f}, alpha MSE {s['alpha_mse']:.4f}")
        tiles.append(over_white(col.astype(np.float64), alpha.astype(np.float64)))
        errs.append(np.abs(alpha - t))
    x0, y0, w, h = a.crop or (0, 0, t.shape[1], t.shape[0])
    top = np.concatenate([im[y0:y0 + h, x0:x0 + w] for im in tiles], 1)
    err8 = [(np.clip(ERROR_GAIN * e, 0, 1) * 255).astype(np.uint8)[y0:y0 + h, x0:x0 + w] for e in errs]
    bottom = np.concatenate([np.repeat(e[..., None], 3, -1) for e in err8], 1)
    a.out.parent.mkdir(parents=True, exist_ok=True)
    iio.imwrite(a.out, np.concatenate([top, bottom], 0), quality=88)


if __name__ == "__main__":
    main()

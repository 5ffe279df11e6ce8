"""How much of a room capture's held-out loss lies where the kept photos are blown out (issue 30; docs/matting.md
"Fur before a blown-out wall").

A kept pixel counts as blown where the room photo's largest channel reaches capture.matting_known.CLIP_LEVEL, grown by
BLOWN_GROW pixels (the strands beside a clipped pixel are lost in the same glare).  Per kept view: the premultiplied
colour's error of the model against the black twin (C_black) at the partial pixels (true alpha 0.1-0.995), and the
share of them that are blown.  Then the held-out views rendered with gather's numpy twin (scripts/ssim_split.py's
render_all and score, the digits of ``furrow eval``) with the truth (the true matte, the black twin's straight colour
C_black / a_true) put into the kept views where they are blown, or where they are not.  A measurement, not a method.

    furrow model CAP --frames 0::2 -o MODEL            (CAP: scripts/hide_mattes.py of ROOM; or ROOM itself)
    PYTHONPATH=. python scripts/blown_colour_split.py ROOM BLACK MODEL [MODEL ...]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from scipy.ndimage import binary_dilation

sys.path.insert(0, str(Path(__file__).resolve().parent))
from ssim_split import _arrays, render_all, score, true_colour_alpha

from capture.io import read_scanset
from capture.matting_known import CLIP_LEVEL

#: Pixels a blown-out pixel's mask is grown by.
BLOWN_GROW = 3
#: The partial pixels of the per-view table: true alpha in [PARTIAL_LOW, PARTIAL_HIGH).
PARTIAL_LOW, PARTIAL_HIGH = 0.1, 0.995
KEYS = ("psnr_masked", "ssim_masked", "sharpness", "psnr_white", "alpha_mse")


def per_view(room, black, kept, rgb, alpha, blown) -> None:
    """One line per kept view: the premultiplied error's mean and RMS at the partial pixels, the blown share."""
    for k, i in enumerate(kept):
        at = np.asarray(room[i].alpha, np.float64)
        m = (at >= PARTIAL_LOW) & (at < PARTIAL_HIGH)
        e = rgb[k][m] * alpha[k][m][:, None] - black[i].linear_rgb[m]
        print(f"  view {room[i].name}: partial {m.sum():6d}, blown {blown[k][m].mean():.3f}, premultiplied error "
              f"mean {np.round(e.mean(0), 4)}, RMS {np.sqrt((e ** 2).mean()):.4f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("room")
    ap.add_argument("black")
    ap.add_argument("models", nargs="+")
    a = ap.parse_args()
    room, black = read_scanset(a.room).scans, read_scanset(a.black).scans
    held = [i for i in range(len(room)) if i % 2]
    kept = [i for i in range(len(room)) if i % 2 == 0]
    blown = np.stack([binary_dilation(room[i].linear_rgb.max(-1) >= CLIP_LEVEL, iterations=BLOWN_GROW) for i in kept])
    for md in a.models:
        cams, rgb, dep, al, meas = _arrays(md)
        at, ft = true_colour_alpha(room, black, kept, rgb)
        part = (at > 0) & (at < 1)
        print(f"{md}: blown share of the kept views' partial pixels {(blown & part).sum() / part.sum():.3f}")
        per_view(room, black, kept, rgb, al, blown)
        b3 = blown[..., None]
        runs = (("as built", rgb, al), ("true colour where blown", np.where(b3, ft, rgb), al),
                ("true colour where not blown", np.where(b3, rgb, ft), al), ("true colour", ft, al),
                ("true alpha where blown", rgb, np.where(blown, at, al)),
                ("true alpha and colour where blown", np.where(b3, ft, rgb), np.where(blown, at, al)))
        for name, col, alpha in runs:
            recs = [score(room[h], c, x) for h, c, x in render_all(room, held, cams, col, dep, alpha, meas)]
            print(f"  {name:34s} " + " / ".join(f"{np.nanmean([r[k] for r in recs]):.4f}" for k in KEYS), flush=True)


if __name__ == "__main__":
    main()

"""The kept views' truly opaque pixels before a blown-out plate (stop 58): how far the matte's premultiplied colour
there is from the truth, and how far the photo as it is would be.

    PYTHONPATH=. .venv/bin/python scripts/matte_error_classes.py ROOM BLACK_TWIN OUT_DIR
    PYTHONPATH=. .venv/bin/python scripts/blown_opaque.py ROOM BLACK_TWIN OUT_DIR

Reads OUT_DIR/NN.npz of scripts/matte_error_classes.py (same kept views, 0::2).  Over the pixels of class "blown"
whose true alpha is 1, prints: their count, the share whose photo / plate is clipped (capture.matting_known.CLIP_LEVEL),
the mean |photo - black twin| (8-bit sRGB / 255: 0 when the room capture and its twin are the same render there), the
matte's premultiplied colour's MSE and mean error against the twin, and the photo's own MSE (sRGB, per channel).
"""

from __future__ import annotations

import sys

import numpy as np

from capture.io import read_scanset
from capture.matting_known import CLIP_LEVEL
from capture.scan import linear_to_srgb

BLOWN = 2  # index of "blown" in scripts/matte_error_classes.CLASSES


def _srgb(x: np.ndarray) -> np.ndarray:
    return linear_to_srgb(np.clip(x, 0.0, 1.0))


def main(room: str, black: str, out_dir: str) -> None:
    ss, bs = read_scanset(room, "0::2"), read_scanset(black, "0::2")
    acc = np.zeros(7)  # pixels, photo clipped, plate clipped, |C - P|, matte SSE, matte error sum, photo SSE
    for i, (s, b) in enumerate(zip(ss.scans, bs.scans, strict=True)):
        z = np.load(f"{out_dir}/{i:02d}.npz")
        k = (z["cls"] == BLOWN) & (np.asarray(s.alpha) >= 0.999)
        if not k.any():
            continue
        C, P = s.linear_rgb[k].astype(np.float64), b.linear_rgb[k].astype(np.float64)
        est = z["alpha"][k, None].astype(np.float64) * z["fg"][k].astype(np.float64)
        e = _srgb(est) - _srgb(P)
        acc += (k.sum(), (C.max(1) >= CLIP_LEVEL).sum(), (z["plate"][k].max(1) >= CLIP_LEVEL).sum(),
                np.abs(_srgb(C) - _srgb(P)).mean(1).sum(), (e ** 2).mean(1).sum(), e.mean(1).sum(),
                ((_srgb(C) - _srgb(P)) ** 2).mean(1).sum())
    n = max(acc[0], 1.0)
    print(f"{room}: blown opaque pixels {acc[0]:.0f}; photo clipped {acc[1] / n:.3f}, plate clipped {acc[2] / n:.3f}; "
          f"mean |photo - twin| {acc[3] / n:.4f}; matte's premultiplied colour MSE {acc[4] / n:.5f} "
          f"(mean error {acc[5] / n:+.4f}); the photo's MSE {acc[6] / n:.5f}")


if __name__ == "__main__":
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    main(*sys.argv[1:])

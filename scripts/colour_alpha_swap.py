"""Which part of a room capture's model costs the held-out score: its colour or its alpha?

Given a capture with the room behind the object (its held-out views over black, as the path-traced
hard cases are made), the model built from its kept views, and the model of its black twin (the
same object and cameras over black, ``scripts/hardcases.py``), renders the held-out views with the
numpy twin of gather (render/gather/reference.py, the GL path's digits) from the room model's
RGBz with the straight colour and / or the alpha swapped for the black twin's, whose colour is
the photo's own (over black C = a F).  Prints masked PSNR / SSIM / sharpness of each.

    furrow model ROOMCAP --frames 0::2 -o ROOM_MODEL
    furrow model BLACKCAP --frames 0::2 -o BLACK_MODEL
    PYTHONPATH=. python scripts/colour_alpha_swap.py ROOMCAP ROOM_MODEL BLACK_MODEL

(docs/matting.md, "Colour or alpha"; ROOMCAP / BLACKCAP as ``scripts/hide_mattes.py`` writes them.)
"""

from __future__ import annotations

import argparse

import numpy as np

from capture.io import read_scanset
from render import metrics
from render.gather import reference as g
from volume.model import load_model


def _arrays(model_dir):
    r = load_model(model_dir).rgbz
    return (list(r.cameras), np.asarray(r.rgb, np.float32), np.asarray(r.depth, np.float32),
            np.asarray(r.alpha, np.float32), r.measured)


def held_out_scores(scans, held, cams, rgb, depth, alpha, measured) -> np.ndarray:
    """Mean (masked PSNR, masked SSIM, sharpness) of the twin's frames of the ``held`` views."""
    centre = np.concatenate([c.depth_to_points(d)[0] for c, d in zip(cams, depth)]).mean(0)
    out = []
    for h in held:
        col, _, _, _ = g.gather_frame(scans[h].camera, None, cams, rgb, depth, centre, g.GatherConfig(), alpha,
                                      measured)
        ref = scans[h].srgb8
        s = metrics.compare(ref, metrics.as_srgb8(col), metrics.foreground(ref))
        out.append((s["psnr_masked"], s["ssim_masked"], s["sharpness"]))
    return np.mean(out, 0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("capture", help="the room capture (its held-out views over black)")
    ap.add_argument("room_model", help="its model from the kept views (furrow model CAP --frames 0::2)")
    ap.add_argument("black_model", help="the black twin's model from the same kept views")
    ap.add_argument("--holdout", type=int, default=2, help="every n-th view kept, as furrow eval --holdout")
    a = ap.parse_args()
    scans = read_scanset(a.capture).scans
    held = [i for i in range(len(scans)) if i % a.holdout]
    cams, rgb_r, dep, al_r, meas = _arrays(a.room_model)
    _, rgb_b, _, al_b, _ = _arrays(a.black_model)
    for name, rgb, al in (("room model", rgb_r, al_r), ("room colour, black alpha", rgb_r, al_b),
                          ("black colour, room alpha", rgb_b, al_r), ("black colour and alpha", rgb_b, al_b)):
        p, s, sh = held_out_scores(scans, held, cams, rgb, dep, al, meas)
        print(f"{name:26s} {p:6.2f} dB  SSIM {s:.3f}  sharpness {sh:.2f}", flush=True)


if __name__ == "__main__":
    main()

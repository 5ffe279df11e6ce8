"""Held-out scores of the colour across the views' variants on one room capture (issue 30, eighth round).

Builds the model of the kept views (``furrow model CAP --frames 0::2 -o MODEL``) with the colour
across the views' inputs kept (every view's line samples, alpha errors and gains: DUMP, a pickle),
then, for each variant of capture.matting_lines.cell_colours (the reference of the pipeline's two
passes: the same colours where no view is drawn from), puts its colours into the model's RGBz at the
partial pixels (the matte's own colour elsewhere) and renders the held-out views with gather's numpy
twin (scripts/colour_alpha_swap.py; the GL path's digits): masked PSNR / SSIM / sharpness.

    PYTHONPATH=. python scripts/cells_variants.py CAP MODEL DUMP

(CAP as ``scripts/hide_mattes.py`` writes it; MODEL and DUMP are made when DUMP does not exist.)
"""

from __future__ import annotations

import argparse
import pickle
import sys
from pathlib import Path

#: The variants: (name, {module constant: value}) of capture.matting_lines / capture.matting_global.
VARIANTS = (("seventh round (cubes alone, lines from photo's alpha 0.1)", {"CELL_LINE_ALPHA": 0.1, "GLOBAL": False}),
            ("the object's colour, lines 0.1", {"CELL_LINE_ALPHA": 0.1, "SHRINK": False,
                                                 "VIEW_BRIGHTNESS": False, "FILLED_CUBES": False}),
            ("the object's colour, lines 0.5", {"SHRINK": False, "VIEW_BRIGHTNESS": False, "FILLED_CUBES": False}),
            ("the object's colour and the shrinkage, lines 0.5", {"VIEW_BRIGHTNESS": False, "FILLED_CUBES": False}),
            ("and the views' brightness", {"FILLED_CUBES": False}),
            ("and the filled pixels in crossed cubes, no brightness", {"VIEW_BRIGHTNESS": False}),
            ("the views' brightness and the filled pixels (defaults)", {}))


def dump_model(cap: str, model: str, dump: str) -> None:
    """``furrow model CAP --frames 0::2 -o MODEL`` with volume.surroundings.cell_colour_passes' inputs
    written to ``dump`` (every view's line samples recomputed as the second pass does)."""
    import volume.surroundings as vs
    from capture.matting_lines import line_samples
    from furrow.cli import main

    passes = vs.cell_colour_passes

    def keep(scans, photos, fits, sigma_alpha, gains, map_views):
        plates, originals = photos
        samples = []
        for k, view in enumerate(scans):
            p = None if fits[k] is None or plates[k] is None else vs.grow_plate(plates[k], *view.depth.shape[:2])
            samples.append(None if p is None else line_samples(view.camera, originals[k].linear_rgb, p.background,
                                                               p.known, view.alpha, view.rgb, view.depth,
                                                               p.estimated, p.sigma))
        with open(dump, "wb") as f:
            pickle.dump({"samples": samples, "sigma_alpha": sigma_alpha, "gains": gains}, f)
        return passes(scans, photos, fits, sigma_alpha, gains, map_views)

    vs.cell_colour_passes = keep
    main(["model", cap, "--frames", "0::2", "-o", model])
    vs.cell_colour_passes = passes


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("capture")
    ap.add_argument("model")
    ap.add_argument("dump")
    a = ap.parse_args()
    if not Path(a.dump).exists():
        dump_model(a.capture, a.model, a.dump)
    sys.path.insert(0, str(Path(__file__).parent))
    from colour_alpha_swap import _arrays, held_out_scores

    from capture import matting_global as mg
    from capture import matting_lines as ml
    from capture.io import read_scanset

    with open(a.dump, "rb") as f:
        d = pickle.load(f)
    cams, rgb, dep, alpha, meas = _arrays(a.model)
    scans = read_scanset(a.capture).scans
    held = [i for i in range(len(scans)) if i % 2]
    for name, consts in VARIANTS:
        saved = {k: getattr(ml if hasattr(ml, k) else mg, k) for k in consts}
        for k, v in consts.items():
            setattr(ml if hasattr(ml, k) else mg, k, v)
        colours, rec = ml.cell_colours(d["samples"], d["sigma_alpha"], d["gains"])
        for k, v in saved.items():
            setattr(ml if hasattr(ml, k) else mg, k, v)
        new = rgb.copy()
        for v, (s, c) in enumerate(zip(d["samples"], colours, strict=True)):
            flat = new[v].reshape(-1, 3)
            if s is not None:
                flat[s["index"]] = s["F0"]
            if c is not None:
                flat[c[0]] = c[1]
        p, s_, sh = held_out_scores(scans, held, cams, new, dep, alpha, meas)
        print(f"{name:62s} {p:.4f} / {s_:.4f} / {sh:.3f}  coloured {rec['coloured']}, the object's "
              f"{rec.get('global_coloured', 0)}, filled {rec.get('filled_coloured', 0)}", flush=True)


if __name__ == "__main__":
    main()

"""The needles' colour from the lines B -> C of a 3D cell across the kept views (issue 30, seventh round).

On the kept views (0::2) of a room capture, each view's matte and plate as the pipeline makes them
(capture.matting.matte_scan with the line colour off), the partial pixels (0 < alpha < FILL_ALPHA)
are placed in 3D by the object's depth (filled by push-pull where a needle missed the pixel centre)
and grouped in cubes of ``--cells`` per the object's extent; each cube's colour is
capture.matting_lines.cell_colour (no black twin, no true matte in it).  Prints the colour's error
against the black twin (its photo over the true alpha) and, given the room model built from the same
kept views, the held-out masked PSNR / SSIM / sharpness of the room model, the same with the cube's
colour at its partial pixels, and the oracle (each cube's alpha-weighted true colour), rendered with
gather's numpy twin (scripts/colour_alpha_swap.py).

    furrow model ROOMCAP --frames 0::2 -o ROOM_MODEL
    PYTHONPATH=. python scripts/colour_lines_cells.py ROOMCAP BLACK_TWIN ROOM_MODEL --cells 16,32

(docs/matting.md, seventh round; ROOMCAP as ``scripts/hide_mattes.py`` writes it, BLACK_TWIN the
hard case with its true mattes.)
"""

from __future__ import annotations

import argparse
import contextlib
import io

import numpy as np

from capture import matting_lines as ml
from capture.extent import remove_surroundings
from capture.fill import push_pull
from capture.io import read_scanset
from capture.matting import MatteConfig, matte_scan, warm_up
from capture.matting_known import FILL_ALPHA, clipped
from capture.plate import PlateConfig, PlateView, background_plates
from capture.scan import Scan


def samples(room: str, black: str) -> list[dict]:
    """Per kept view: its partial pixels (mask, 3D points, C, B, alpha, colour, usable, true premultiplied)."""
    ss, bs = read_scanset(room, "0::2"), read_scanset(black, "0::2")
    out, rep = remove_surroundings(ss)
    views = [PlateView(o.camera, o.linear_rgb, o.depth, s.depth) for s, o in zip(ss.scans, out.scans, strict=True)]
    with contextlib.redirect_stdout(io.StringIO()):
        plates, _ = background_plates(views, PlateConfig(), rep.plane, (rep.focus_center, rep.focus_radius))
    res = []
    for s, o, b, pl in zip(ss.scans, out.scans, bs.scans, plates, strict=True):
        pl = pl.full()
        with contextlib.redirect_stdout(io.StringIO()):
            m = matte_scan(Scan(s.rgb, s.depth, s.camera, s.name), o.depth, MatteConfig(), pl)
        C = np.clip(s.linear_rgb.astype(np.float64), 0, 1)
        B = np.clip(pl.background.astype(np.float64), 0, 1)
        a = m.alpha.astype(np.float64)
        dep = np.asarray(o.depth, np.float64)
        filled = push_pull(dep[..., None], (dep > 0).astype(np.float64))[..., 0]
        pts, mask = s.camera.depth_to_points(np.where((a > 0) & (a < FILL_ALPHA), filled, 0.0))
        res.append({"mask": mask, "pts": pts, "C": C[mask], "B": B[mask], "a": a[mask],
                    "F0": m.foreground.astype(np.float64)[mask], "usable": (pl.known & ~clipped(C, B))[mask],
                    "at": np.asarray(b.alpha, np.float64)[mask], "Cb": b.linear_rgb.astype(np.float64)[mask]})
    return res


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("room")
    ap.add_argument("black")
    ap.add_argument("model", nargs="?", help="the room model of the kept views (held-out scores)")
    ap.add_argument("--cells", default="16,32", help="cubes per the object's extent, comma-separated")
    a = ap.parse_args()
    warm_up()
    P = samples(a.room, a.black)
    cat = {k: np.concatenate([p[k] for p in P]) for k in ("pts", "C", "B", "a", "F0", "usable", "at", "Cb")}
    al = ml.line_alpha(cat["C"][None], cat["B"][None], np.median(cat["F0"], 0))[0]
    w = ml.line_weights(al[None], cat["usable"][None], np.zeros((1, len(al))))[0]
    extent = float((cat["pts"].max(0) - cat["pts"].min(0)).max())
    Ft = cat["Cb"] / np.maximum(cat["at"], 1e-3)[:, None]
    for n in (int(x) for x in a.cells.split(",")):
        F, sig2 = ml.cell_colour(cat["pts"], extent / n, cat["C"], cat["B"], w, cat["a"])
        ok = np.isfinite(sig2)
        k = ok & (cat["at"] > 0.1)
        e, e0 = np.linalg.norm(F - Ft, axis=-1)[k], np.linalg.norm(cat["F0"] - Ft, axis=-1)[k]
        print(f"cells {n}^3: colour for {ok.mean():.1%} of the partial pixels; |F - F_true| median {np.median(e):.4f} "
              f"(the matte's {np.median(e0):.4f}); predicted {np.median(np.sqrt(sig2[k])):.4f}; mean F "
              f"{np.round(F[k].mean(0), 4)} (true {np.round(Ft[k & (cat['at'] > 0.3)].mean(0), 4)})", flush=True)
        if a.model:
            held_out(a, P, F, ok, n)


def held_out(a, P, F, ok, n) -> None:
    """Held-out scores of the room model with the cells' colour at its partial pixels (numpy twin)."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parent))
    from colour_alpha_swap import _arrays, held_out_scores

    cams, rgb, dep, alpha, meas = _arrays(a.model)
    new = rgb.copy()
    off = 0
    for v, p in enumerate(P):
        ys, xs = np.nonzero(p["mask"])
        sel = ok[off:off + len(ys)] & (alpha[v][ys, xs] > 0) & (alpha[v][ys, xs] < FILL_ALPHA)
        new[v][ys[sel], xs[sel]] = F[off:off + len(ys)][sel]
        off += len(ys)
    scans = read_scanset(a.room).scans
    held = [i for i in range(len(scans)) if i % 2]
    for name, x in (("room model", rgb), (f"cells {n}^3", new)):
        p, s, sh = held_out_scores(scans, held, cams, x, dep, alpha, meas)
        print(f"  held out {name:12s} {p:6.2f} dB  SSIM {s:.3f}  sharpness {sh:.2f}", flush=True)


if __name__ == "__main__":
    main()

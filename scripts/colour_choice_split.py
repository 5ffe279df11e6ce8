"""Where the colour of a room capture's estimated-background pixels goes wrong (issue 30 sixth round):
on the kept views (every third of 0::2) of a room capture with true mattes and its black twin (the true
premultiplied colour), the default plate's estimated-B pixels (not clipped, estimated alpha > 0), the
premultiplied colour alpha x F unmixed everywhere (capture.matting.COLOUR_FROM_SEEN off) against filled
everywhere (the plate's sigma withheld: capture.matting_colour's fallback) and the per-pixel oracle of
the two, split by estimated alpha and by |B|, with the alpha's RMS error there.

    PYTHONPATH=. .venv/bin/python scripts/colour_choice_split.py ROOM_CAPTURE BLACK_TWIN
"""

from __future__ import annotations

import argparse
import contextlib
import io
from dataclasses import replace

import numpy as np

from capture import matting as mt
from capture import matting_colour as mc
from capture.extent import remove_surroundings
from capture.io import read_scanset
from capture.matting import MatteConfig, matte_scan, warm_up
from capture.matting_known import clipped
from capture.plate import PlateConfig, PlateView, background_plates
from capture.scan import Scan


def _rows(ss, out, bs, plates) -> np.ndarray:
    """(N, 6): estimated alpha, true alpha, unmixed and filled squared errors, |B|, |F filled|."""
    rows = []
    for i, (s, o, b, pl) in enumerate(zip(ss.scans, out.scans, bs.scans, plates, strict=True)):
        if i % 3 or pl is None:
            continue
        pl, sc = pl.full(), Scan(s.rgb, s.depth, s.camera, s.name)
        if pl.estimated is None:
            continue
        with contextlib.redirect_stdout(io.StringIO()):
            mt.COLOUR_FROM_SEEN, mc.GATE_SEEN = False, False
            mu = matte_scan(sc, o.depth, MatteConfig(), pl)
            mt.COLOUR_FROM_SEEN = True
            mf = matte_scan(sc, o.depth, MatteConfig(), replace(pl, sigma=None))
        a, truth = mu.alpha, b.linear_rgb.astype(np.float64)
        m = pl.estimated & ~clipped(s.linear_rgb, pl.background) & (a > 0)
        e = [((a[..., None] * x.foreground - truth) ** 2).sum(-1)[m] for x in (mu, mf)]
        rows.append(np.stack([a[m], np.asarray(s.alpha, np.float64)[m], e[0], e[1],
                              np.linalg.norm(pl.background[m], axis=-1), np.linalg.norm(mf.foreground[m], axis=-1)], 1))
    return np.concatenate(rows)


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("room")
    p.add_argument("black")
    a = p.parse_args(argv)
    warm_up()
    ss, bs = read_scanset(a.room, "0::2"), read_scanset(a.black, "0::2")
    out, rep = remove_surroundings(ss)
    views = [PlateView(o.camera, o.linear_rgb, o.depth, s.depth) for s, o in zip(ss.scans, out.scans, strict=True)]
    plates, _ = background_plates(views, PlateConfig(), rep.plane, (rep.focus_center, rep.focus_radius))
    al, at, eu, ef, nb, nf = _rows(ss, out, bs, plates).T
    rms = np.sqrt(np.mean((al - at) ** 2))
    print(f"{a.room}: {len(al)} estimated-B pixel-views; premultiplied MSE unmixed {eu.mean():.6f}, filled "
          f"{ef.mean():.6f}, oracle {np.minimum(eu, ef).mean():.6f}; alpha RMS error {rms:.3f}")
    for name, x, edges in (("alpha", al, (0, 0.2, 0.4, 0.6, 0.8, 1.01)), ("|B|", nb, (0, 0.2, 0.3, 0.4, 0.6, 2))):
        for lo, hi in zip(edges[:-1], edges[1:], strict=True):
            k = (x >= lo) & (x < hi)
            if k.any():
                rms = np.sqrt(np.mean((al - at)[k] ** 2))
                print(f"  {name} {lo}-{hi}: n {k.sum():6d}  unmixed {eu[k].mean():.5f}  filled {ef[k].mean():.5f}  "
                      f"alpha RMS {rms:.3f}  |B| {nb[k].mean():.2f}  |F| {nf[k].mean():.2f}")


if __name__ == "__main__":
    main()

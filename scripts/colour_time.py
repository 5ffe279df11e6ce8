"""Matte CPU seconds a view of the plate branch, alternated in one process (issue 30 sixth round):
the fifth round's (the solve, then capture.matting.unmixed again where B was estimated) / the sixth's
with capture.matting_colour.GATE_SEEN off / on, on every k-th kept view (0::2) of CAPTURE.

    PYTHONPATH=. .venv/bin/python scripts/colour_time.py CAPTURE VIEWS ROUNDS
"""
import contextlib
import io
import os
import sys
import time

import numpy as np

import capture.matting_colour as mc
from capture.extent import remove_surroundings
from capture.io import read_scanset
from capture.matting import MatteConfig, depth_trimap, matte_scan, solve_known, unmixed, warm_up
from capture.matting_known import clipped
from capture.plate import PlateConfig, PlateView, background_plates
from capture.scan import Scan

cap, nv, rounds = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
warm_up()
ss = read_scanset(cap, "0::2")
out, rep = remove_surroundings(ss)
views = [PlateView(o.camera, o.linear_rgb, o.depth, s.depth) for s, o in zip(ss.scans, out.scans)]
plates, _ = background_plates(views, PlateConfig(), rep.plane, (rep.focus_center, rep.focus_radius))
idx = list(range(0, len(views), max(1, len(views) // nv)))[:nv]
items = [(Scan(ss.scans[i].rgb, ss.scans[i].depth, ss.scans[i].camera, ss.scans[i].name), out.scans[i].depth,
          plates[i].full()) for i in idx]
def main_rule(sc, d, pl):
    img = sc.linear_rgb
    m = solve_known(img, depth_trimap(d), pl.background, pl.known, pl.noise, "plate", np.asarray(d) > 0, MatteConfig())
    if pl.estimated is not None and pl.estimated.any():
        unmixed(img, m.alpha, pl.background, pl.seen() | (pl.known & clipped(img, pl.background)))
def branch(on):
    def f(sc, d, pl):
        mc.GATE_SEEN = on
        matte_scan(sc, d, MatteConfig(), pl)
    return f
fs = {"main": main_rule, "seen_off": branch(False), "branch": branch(True)}
res = {k: [] for k in fs}
for r in range(rounds):
    order = list(fs) if r % 2 == 0 else list(reversed(list(fs)))
    for k in order:
        t = time.process_time()
        with contextlib.redirect_stdout(io.StringIO()):
            for it in items:
                fs[k](*it)
        res[k].append((time.process_time() - t) / len(items))
per_round = {k: [round(x, 3) for x in v] for k, v in res.items()}
median = {k: round(float(np.median(v)), 3) for k, v in res.items()}
print(os.path.basename(cap), "views", len(items), "load", [round(x, 2) for x in os.getloadavg()], per_round, median)

"""Colour images and depth maps flipped against each other: part of the depth-agreement check (volume/agreement.py).

The colour images of a capture stored upside down (bottom row first, as an OpenGL read-back gives them), mirrored or
turned 180 degrees, the depth maps and poses right: the depth agrees with the poses, and the colour's edges against
the depth's (capture.depth_registration) read the path-traced conifer with its colour upside down as depth beside
its colour by (-1, -7) px (1.02 times), a shift ``--depth-agreement fix`` then made (on the kept views of an 18 / 18
split, (-7, -8) at 1.05: held out 20.58 -> 19.01 dB; right 26.41).

Within each scored colour image, the depth's edges mirrored are held against the colour as stored
(capture.depth_pairing's data and fit, :func:`edge_flips`).  Where a mirror fits :data:`EDGE_GAIN` times better
(summed over the views), the colour and the depth sit flipped against each other: the check says so, and the
colour's shift from the depth is not judged (nor fixed).  Which of the two is flipped is not decided here: where the
depth agrees with the poses only mirrored, capture.depth_readings names the depth; otherwise the colour is the
likelier, but a test of the colours across views (the same point's colour in two views, read as stored and
mirrored) was tried and was not reliable: on the conifer's turntable its room, the same in every frame, matched
itself as stored, and on the object alone auto exposure and the needles' sameness left it at z -6.8 to +4.6.
Measured: the conifer's flipped colour 1.16-1.38 (whole, every other view, every third, fourth); depth maps flipped
alone 1.01-1.49; right captures 0.41-1.006 (146 checks, every other, third and fourth view included), and 1.23 on a
synthetic capture with D435 noise, flying pixels and clutter (its flying pixels' edges, mirrored, land on the
clutter's), whose depth agrees with its poses at no scale: the check is made only where the depth agrees with the
poses (volume/agreement.py).
"""

from __future__ import annotations

import numpy as np

#: The flips tried: name -> (rows reversed, columns reversed); the names of capture.depth_readings.READINGS.
FLIPS = {"upside down": (True, False), "left to right": (False, True), "turned 180 degrees": (True, True)}
#: The colour's edges fit the mirrored depth's this many times better than the stored depth's (summed over the
#: scored views): right captures 0.41-1.006 (one whose depth agrees with nothing 1.23), the flipped colours 1.16-1.38.
EDGE_GAIN = 1.1


def edge_flips(data: dict) -> dict:
    """Per flip, the colour's gradient at the mirrored depth edges over at the stored ones (each at its best shift),
    summed over the views of ``data`` (view -> capture.depth_pairing.pairing_data); ``best`` the flip with the
    largest."""
    from capture.camera import mirror_pixels
    from capture.depth_pairing import PAIR_MIN_EDGES, edge_fit

    sums = np.zeros(1 + len(FLIPS))
    for G, ys, xs in data.values():
        if len(ys) < PAIR_MIN_EDGES:
            continue
        fits = [edge_fit(G, ys, xs)]
        for r, c in FLIPS.values():
            m = mirror_pixels(np.stack([xs, ys], axis=-1), G.shape, r, c).astype(np.int64)
            fits.append(edge_fit(G, m[:, 1], m[:, 0]))
        if all(f == f for f in fits):
            sums += fits
    gains = {name: round(float(sums[k + 1] / sums[0]), 4) if sums[0] > 0 else 0.0 for k, name in enumerate(FLIPS)}
    return {"gains": gains, "best": max(gains, key=gains.get)}

"""capture.colour_flip: colour images stored flipped against right depth and poses, on seeded scenes."""

from __future__ import annotations

import zlib
from dataclasses import replace

import numpy as np
import pytest

from capture.colour_flip import EDGE_GAIN, FLIPS, edge_flips
from capture.depth_pairing import edge_fit, pairing_data
from tests.scenes import make_scanset, scan_ring, spheres_scene

MIRROR = {"upside down": lambda a: a[::-1], "left to right": lambda a: a[:, ::-1],
          "turned 180 degrees": lambda a: a[::-1, ::-1]}


@pytest.fixture(scope="module")
def ring():
    return make_scanset(spheres_scene(), scan_ring(16, 128, 96), noise=0.0005)


def _edges(scans):
    return edge_flips({k: pairing_data(s.rgb, s.depth, zlib.crc32(s.name.encode())) for k, s in enumerate(scans)})


def test_right_colour_fits_its_depth_as_stored(ring):
    edges = _edges(ring.scans)
    assert max(edges["gains"].values()) < EDGE_GAIN, edges


@pytest.mark.parametrize("name", list(FLIPS))
def test_colour_stored_flipped_fits_the_mirrored_depth(ring, name):
    edges = _edges([replace(s, rgb=np.ascontiguousarray(MIRROR[name](s.rgb))) for s in ring.scans])
    assert edges["best"] == name and edges["gains"][name] >= EDGE_GAIN, edges


def test_edge_flips_are_the_fits_of_the_mirrored_edges():
    """The summed fits against the pixel-by-pixel mirror of each view's edges (the reference)."""
    rng = np.random.default_rng(5)
    data = {}
    for k in range(3):
        G = rng.random((30, 40)).astype(np.float16)
        ys, xs = rng.integers(3, 27, 80).astype(np.int32), rng.integers(3, 37, 80).astype(np.int32)
        data[k] = (G, ys, xs)
    got = edge_flips(data)["gains"]
    for name, (r, c) in FLIPS.items():
        own = sum(edge_fit(G, ys, xs) for G, ys, xs in data.values())
        mirrored = sum(edge_fit(G, np.array([29 - y if r else y for y in ys]),
                                np.array([39 - x if c else x for x in xs])) for G, ys, xs in data.values())
        assert got[name] == pytest.approx(mirrored / own, abs=1e-4)

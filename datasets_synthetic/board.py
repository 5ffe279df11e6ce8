"""A ChArUco board under the synthetic object (issue 4: camera poses from a marker board).

``add_board(scene, spec)`` returns the scene with a printed ChArUco board (geometry and
texture from ``capture.registration.board.BoardSpec``, the same definition the PnP detector
uses) lying flat under the object on white paper.  Every board pixel is its own quad with
its own four vertices, so the per-vertex colours of the rasteriser reproduce the print with
sharp edges.  Use it with ``synthesize(cfg, scene=add_board(build_scene(name)))``.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from capture.registration.board import BoardSpec
from capture.scan import srgb_to_linear
from datasets_synthetic.geometry import merge
from datasets_synthetic.scenes import Scene
from render.mesh.raster.gl import RasterMesh

#: White paper around the printed pattern (metres).
PAPER_MARGIN_M = 0.04
#: Board texture resolution (cells per chessboard square).
PX_PER_SQUARE = 16
#: Gap between the object's lowest point and the board (metres).
BOARD_GAP_M = 1e-4


def _quads(x0, y0, x1, y1, z, colors) -> RasterMesh:
    """Axis-aligned quads [x0, x1] x [y0, y1] at height z (arrays of the same length)."""
    n = len(x0)
    v = np.empty((n, 4, 3), np.float64)
    v[:, 0] = np.stack([x0, y0, np.full(n, z)], 1)
    v[:, 1] = np.stack([x1, y0, np.full(n, z)], 1)
    v[:, 2] = np.stack([x1, y1, np.full(n, z)], 1)
    v[:, 3] = np.stack([x0, y1, np.full(n, z)], 1)
    base = 4 * np.arange(n)[:, None]
    f = np.concatenate([base + [0, 1, 2], base + [0, 2, 3]])
    c = np.repeat(np.asarray(colors, np.float32)[:, None, :], 4, axis=1).reshape(-1, 3)
    nrm = np.tile([0.0, 0.0, 1.0], (4 * n, 1))
    return RasterMesh(v.reshape(-1, 3), f, c, nrm)


def board_mesh(spec: BoardSpec = BoardSpec(), px_per_square: int = PX_PER_SQUARE,
               margin_m: float = PAPER_MARGIN_M) -> RasterMesh:
    """The board (pattern + white paper margin) in world coordinates, facing +z at ``spec.z_m``."""
    img = spec.image(px_per_square)
    lin = srgb_to_linear(img.astype(np.float32) / 255.0)
    H, W = img.shape
    cell = spec.square_m / px_per_square
    wfb = spec.world_from_board()
    j, i = np.mgrid[0:H, 0:W]
    # board frame cell [i, i+1] x [j, j+1] -> world: x = -w/2 + i cell, y = h/2 - j cell
    bx0 = i.ravel() * cell
    by0 = j.ravel() * cell
    xw0 = wfb[0, 3] + bx0
    xw1 = xw0 + cell
    yw0 = wfb[1, 3] - by0 - cell
    yw1 = wfb[1, 3] - by0
    cols = np.repeat(lin.ravel()[:, None], 3, axis=1)
    pattern = _quads(xw0, yw0, xw1, yw1, spec.z_m, cols)
    w, h = spec.size_m
    m = margin_m
    white = np.ones((4, 3), np.float32)
    paper = _quads(np.array([-w / 2 - m, -w / 2 - m, -w / 2 - m, w / 2]),
                   np.array([-h / 2 - m, h / 2, -h / 2, -h / 2]),
                   np.array([w / 2 + m, w / 2 + m, -w / 2, w / 2 + m]),
                   np.array([-h / 2, h / 2 + m, h / 2, h / 2]), spec.z_m, white)
    return merge([pattern, paper])


def add_board(scene: Scene, spec: BoardSpec | None = None) -> tuple[Scene, BoardSpec]:
    """The scene standing on a ChArUco board; the board height is set just under the object.

    Returns (scene with the board merged into its mesh, the BoardSpec used, with its ``z_m``)."""
    spec = spec or BoardSpec()
    z = float(scene.mesh.vertices[:, 2].min()) - BOARD_GAP_M
    spec = replace(spec, z_m=z)
    mesh = merge([scene.mesh, board_mesh(spec)])
    params = {**scene.params, "board": {"squares": [spec.squares_x, spec.squares_y], "square_m": spec.square_m,
                                        "marker_m": spec.marker_m, "dictionary": spec.dictionary, "z_m": z}}
    return Scene(f"{scene.name}+board", scene.seed, mesh, params, {**scene.stats, "board_cells": len(mesh.faces)}), spec

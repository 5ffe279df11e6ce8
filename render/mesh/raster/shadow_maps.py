"""Directional-light shadow maps of the mesh rasteriser (``render.mesh.raster.gl``): the light's
orthographic view-projection and the per-point visibility looked up in its read-back depth map.
"""

from __future__ import annotations

import numpy as np

from capture.camera import Camera, look_at
from capture.sampling import from_texcoord, linear_taps


def _ortho(half: float, near: float, far: float) -> np.ndarray:
    P = np.zeros((4, 4))
    P[0, 0] = P[1, 1] = 1.0 / half
    P[2, 2] = -2.0 / (far - near)
    P[2, 3] = -(far + near) / (far - near)
    P[3, 3] = 1.0
    return P


def light_view_projection(direction, centre, radius: float) -> np.ndarray:
    """(4, 4) world -> clip matrix of an orthographic light looking along ``-direction``
    (``direction`` points towards the light) at a sphere (``centre``, ``radius``)."""
    d = np.asarray(direction, np.float64)
    up = (0.0, 0.0, 1.0) if abs(d[2]) < 0.95 else (1.0, 0.0, 0.0)
    cam = Camera(np.eye(3), look_at(np.asarray(centre) + 2 * radius * d, centre, up), 1, 1)
    return _ortho(radius, radius, 3 * radius) @ cam.gl_view()


def shadow_map_visibility(points: np.ndarray, depth: np.ndarray, light_vp: np.ndarray, direction,
                          bias_m: float) -> np.ndarray:
    """(N,) float32 fraction of a directional light reaching ``points`` (N, 3) world.

    ``depth``: (S, S) window depth [0, 1] of the light's depth map as read back from GL (row 0
    = bottom, indexed with GL texture coordinates, so no row flip); ``light_vp`` its world ->
    clip matrix.  Each point is moved ``bias_m`` towards the light, then compared with the map by
    four bilinear taps half a texel apart (a smooth 3 x 3-texel percentage-closer filter).
    Points outside the map are lit.
    """
    S = depth.shape[0]
    p = np.asarray(points, np.float64) + bias_m * np.asarray(direction, np.float64)
    q = p @ light_vp[:3, :3].T + light_vp[:3, 3]
    w = p @ light_vp[3, :3] + light_vp[3, 3]
    ndc = q / w[:, None]
    ref = ndc[:, 2] * 0.5 + 0.5
    yx = from_texcoord(ndc[:, 1::-1] * 0.5 + 0.5, S)  # (row, column) texel coordinates
    inside = (np.abs(ndc) <= 1).all(axis=1)
    vis = np.zeros(len(p))
    offsets = (-0.5, 0.5)
    for dy in offsets:
        for dx in offsets:  # each tap compared, then weighted (GL's sampler2DShadow with LINEAR)
            for idx, _, wgt in linear_taps(yx + (dy, dx), depth.shape, "clamp"):
                vis += wgt * (ref <= depth[idx])
    vis /= len(offsets) ** 2
    return np.where(inside, vis, 1.0).astype(np.float32)

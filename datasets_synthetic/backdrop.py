"""What a real camera sees around the object: a cluttered room behind it and a support under it.

Real captures show the room behind the object and a depth sensor sees the table or turntable it
stands on (issue 20).  This module renders both analytically, per pixel ray, so that a synthetic
capture can carry them in colour (and the support in depth too) while the object's own coverage
stays the exact true matte:

* :func:`clutter_background`: a room around the rig, a cylindrical wall of radius
  ``CLUTTER_WALL_RADIUS_M`` about the world +z axis covered in shelves of coloured boxes (two
  layers of seeded cells plus dark edges) over a tiled floor ``CLUTTER_FLOOR_BELOW_M`` under the
  object.  No depth: the room is beyond the sensor's range.
* :func:`support_layer`: a horizontal support whose top is the plane z = ``z0`` (the object's
  lowest point, so the object stands on it): a turntable ``disc`` (radius ``DISC_RADIUS_FACTOR``
  times the object's horizontal radius, grey with concentric grooves) or a ``table`` top
  (``TABLE_HALF_SIZE_M``, wood-like stripes).  Colour (premultiplied by coverage, Lambertian
  under the environment's upper hemisphere), coverage and z-depth at the pixel centres.

The object stands on the support and every camera looks from above its plane, so a ray that
meets the object meets it before the plane: the object composites *over* the support, which
composites over the room.  World +z is up (the synthetic scenes' convention).
"""

from __future__ import annotations

import numpy as np

from capture.camera import Camera, resample_pixel_coords

#: Supports ``furrow synth --support`` can put under the object.
SUPPORTS = ("none", "disc", "table")
#: Turntable disc radius as a multiple of the object's horizontal radius (about its vertical axis).
DISC_RADIUS_FACTOR = 1.6
#: Table top half sizes along world x and y (metres): a 1.2 m x 0.8 m table.
TABLE_HALF_SIZE_M = (0.6, 0.4)
#: Albedo of the turntable disc (linear) and depth of its grooves (relative albedo drop).
DISC_ALBEDO = (0.32, 0.32, 0.34)
DISC_GROOVE = 0.35
#: Groove spacing of the disc (metres).
DISC_GROOVE_M = 0.012
#: Albedo range of the table's wood stripes (linear, dark to light).
TABLE_ALBEDO = ((0.20, 0.11, 0.05), (0.45, 0.28, 0.14))
#: Radius of the room's wall about the rig's axis and the floor's depth under the object (metres).
CLUTTER_WALL_RADIUS_M = 2.0
CLUTTER_FLOOR_BELOW_M = 0.75
#: Cell sizes of the wall's two box layers (metres) and width of the dark box edges (fraction of a cell).
CLUTTER_CELLS_M = (0.23, 0.07)
CLUTTER_EDGE = 0.08
#: Albedo range of the room's boxes (linear) and of the floor tiles.
CLUTTER_ALBEDO = (0.03, 0.75)
FLOOR_TILE_M = 0.3
#: Directions sampled to integrate the environment's irradiance on an upward-facing surface.
IRRADIANCE_SAMPLES = 2048


def upward_radiance(env, exposure: float, seed: int = 0) -> np.ndarray:
    """(3,) radiance of a white Lambertian surface facing +z under ``env`` (cosine-weighted mean
    of the upper hemisphere, Monte Carlo with a fixed seed), times ``exposure``."""
    rng = np.random.default_rng(seed)
    u1, u2 = rng.random(IRRADIANCE_SAMPLES), rng.random(IRRADIANCE_SAMPLES)
    r, phi = np.sqrt(u1), 2 * np.pi * u2
    d = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1 - u1)], axis=-1)
    return (np.asarray(env.sample(d), np.float64).mean(axis=0) * exposure).astype(np.float32)


def _subpixel_rays(camera: Camera, ss: int) -> tuple[np.ndarray, np.ndarray]:
    """World ray origin (3,) and (H, W, ss*ss, 3) unit world directions through ``ss`` x ``ss``
    stratified sub-pixel positions of every pixel."""
    H, W = camera.height, camera.width
    fine = resample_pixel_coords(camera.scaled(ss).pixel_grid(), 1.0 / ss)  # (H ss, W ss, 2) sub-pixel centres
    uv = fine.reshape(H, ss, W, ss, 2).transpose(0, 2, 1, 3, 4).reshape(H, W, ss * ss, 2)
    d = camera.pixel_rays(uv) @ camera.world_from_cam[:3, :3].T
    return camera.center, d / np.linalg.norm(d, axis=-1, keepdims=True)


def _hash_colours(seed: int, n: int, lo: float, hi: float) -> np.ndarray:
    rng = np.random.default_rng(seed)
    base = rng.uniform(lo, hi, (n, 1))
    tint = rng.dirichlet((1.5, 1.5, 1.5), n) * 3
    return np.clip(base * (0.35 + 0.65 * tint), 0.0, 1.0)


def _cell_colour(u: np.ndarray, v: np.ndarray, size: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Colour of the seeded cell holding (u, v) (metres) and a 0..1 'edge' weight near its border."""
    iu, iv = np.floor(u / size).astype(np.int64), np.floor(v / size).astype(np.int64)
    table = _hash_colours(seed, 4096, *CLUTTER_ALBEDO)
    idx = (iu * 73856093 ^ iv * 19349663) % 4096
    fu, fv = u / size - iu, v / size - iv
    edge = np.minimum(np.minimum(fu, 1 - fu), np.minimum(fv, 1 - fv)) < CLUTTER_EDGE
    return table[idx], edge


def clutter_background(camera: Camera, radiance: np.ndarray, seed: int = 0, supersample: int = 2) -> np.ndarray:
    """(H, W, 3) float32 linear colour of the cluttered room seen through every pixel (module
    docstring); ``radiance`` (3,) scales the albedo (e.g. :func:`upward_radiance`)."""
    o, d = _subpixel_rays(camera, supersample)
    # wall: |o_xy + t d_xy| = R, the root in front of the camera (the camera is inside the room)
    a = d[..., 0] ** 2 + d[..., 1] ** 2
    b = 2 * (o[0] * d[..., 0] + o[1] * d[..., 1])
    c = o[0] ** 2 + o[1] ** 2 - CLUTTER_WALL_RADIUS_M ** 2
    t_wall = (-b + np.sqrt(np.maximum(b * b - 4 * a * c, 0))) / np.maximum(2 * a, 1e-12)
    z_floor = -CLUTTER_FLOOR_BELOW_M
    with np.errstate(divide="ignore", invalid="ignore"):
        t_floor = np.where(d[..., 2] < 0, (z_floor - o[2]) / d[..., 2], np.inf)
    floor = t_floor < t_wall
    t = np.where(floor, t_floor, t_wall)
    p = o + t[..., None] * d
    u = np.arctan2(p[..., 1], p[..., 0]) * CLUTTER_WALL_RADIUS_M
    big, e1 = _cell_colour(u, p[..., 2], CLUTTER_CELLS_M[0], seed)
    small, e2 = _cell_colour(u + 0.031, p[..., 2] + 0.017, CLUTTER_CELLS_M[1], seed + 1)
    wall = np.where(e1[..., None], 0.02, 0.55 * big + 0.45 * small * np.where(e2, 0.4, 1.0)[..., None])
    tile = (np.floor(p[..., 0] / FLOOR_TILE_M) + np.floor(p[..., 1] / FLOOR_TILE_M)) % 2
    floor_col = np.where(tile[..., None] > 0, 0.35, 0.12) * np.array([1.0, 0.95, 0.85])
    col = np.where(floor[..., None], floor_col, wall) * np.asarray(radiance, np.float64)
    return col.mean(axis=2).astype(np.float32)


def support_layer(camera: Camera, kind: str, z0: float, object_radius: float, radiance: np.ndarray,
                  supersample: int = 3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The support under the object seen by ``camera`` (module docstring).

    Returns (colour (H, W, 3) float32 linear premultiplied by coverage, coverage (H, W) float32
    in [0, 1], z-depth (H, W) float32 metres at the pixel centres, 0 where the support is not hit).
    """
    if kind not in SUPPORTS:
        raise ValueError(f"support must be one of {', '.join(SUPPORTS)}, got {kind!r}")
    H, W = camera.height, camera.width
    if kind == "none":
        return np.zeros((H, W, 3), np.float32), np.zeros((H, W), np.float32), np.zeros((H, W), np.float32)
    o, d = _subpixel_rays(camera, supersample)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(d[..., 2] < 0, (z0 - o[2]) / d[..., 2], np.inf)
    p = o + np.where(np.isfinite(t), t, 0.0)[..., None] * d
    if kind == "disc":
        r = np.hypot(p[..., 0], p[..., 1])
        hit = np.isfinite(t) & (r <= DISC_RADIUS_FACTOR * object_radius)
        groove = 1 - DISC_GROOVE * (np.cos(2 * np.pi * r / DISC_GROOVE_M) > 0.8)
        albedo = np.asarray(DISC_ALBEDO)[None, None, None] * groove[..., None]
    else:
        hit = np.isfinite(t) & (np.abs(p[..., 0]) <= TABLE_HALF_SIZE_M[0]) & (np.abs(p[..., 1]) <= TABLE_HALF_SIZE_M[1])
        grain = 0.5 + 0.5 * np.sin(p[..., 1] * 180 + 3 * np.sin(p[..., 0] * 11) + 1.7 * np.sin(p[..., 1] * 37))
        lo, hi = (np.asarray(c) for c in TABLE_ALBEDO)
        albedo = lo + (hi - lo) * grain[..., None]
    col = (albedo * hit[..., None] * np.asarray(radiance, np.float64)).mean(axis=2)
    cov = hit.mean(axis=2)
    # depth at the pixel centre: the plane's z-depth where the centre ray hits the support
    uv = camera.pixel_grid()
    dc = camera.pixel_rays(uv) @ camera.world_from_cam[:3, :3].T  # camera-frame z = 1: t is the z-depth
    with np.errstate(divide="ignore", invalid="ignore"):
        tz = np.where(dc[..., 2] < 0, (z0 - o[2]) / dc[..., 2], 0.0)
    pc = o + tz[..., None] * dc
    if kind == "disc":
        inside = np.hypot(pc[..., 0], pc[..., 1]) <= DISC_RADIUS_FACTOR * object_radius
    else:
        inside = (np.abs(pc[..., 0]) <= TABLE_HALF_SIZE_M[0]) & (np.abs(pc[..., 1]) <= TABLE_HALF_SIZE_M[1])
    depth = np.where(inside & (tz > 0), tz, 0.0)
    return col.astype(np.float32), cov.astype(np.float32), depth.astype(np.float32)

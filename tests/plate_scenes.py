"""Synthetic captures with an exactly known background, for the plate and known-background matting tests.

* :func:`orbit_capture`: cameras on a ring around a sphere, a textured table top (a plane with
  depth) under it and an environment at infinity (colour a function of direction only) behind it.
  The true background of every pixel is computed in closed form (:func:`true_background`).
* :func:`turntable_capture`: one fixed camera, a textured room image behind the object, the object
  (an opaque core with thin partial needles, coverage by supersampling) turning from frame to frame;
  the poses are written as a turntable capture writes them (the camera orbiting the object).
* :func:`needle_composite`: one image of thin needles, mostly partial pixels, over a background:
  true alpha (coverage) and straight colour.
"""

from __future__ import annotations

import functools

import numpy as np

from capture.matting import UNKNOWN, depth_trimap
from capture.plate import PlateView
from capture.sampling import cell_centres
from tests import scenes

#: Orbit scene: sphere radius, table height and half size (metres), camera ring.
SPHERE_R = 0.07
TABLE_Z = -0.12
TABLE_HALF = 0.35
RING_RADIUS = 0.5


def env_colour(d: np.ndarray) -> np.ndarray:
    """(N, 3) linear colour of the environment at infinity seen along directions (N, 3)."""
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    phi = np.arctan2(d[:, 1], d[:, 0])
    th = np.arccos(np.clip(d[:, 2], -1, 1))
    r = 0.45 + 0.3 * np.sin(9 * phi) * np.cos(4 * th)
    g = 0.5 + 0.25 * np.cos(13 * phi + 1.0)
    b = 0.35 + 0.2 * np.sin(7 * th + 3 * phi)
    return np.stack([r, g, b], -1)


def black_env(d: np.ndarray) -> np.ndarray:
    """(N, 3) black: a dark room all round."""
    return np.zeros((len(d), 3))


def table_colour(p: np.ndarray) -> np.ndarray:
    """(N, 3) linear colour of the table top at world points (N, 3)."""
    return np.stack([0.35 + 0.2 * np.sin(40 * p[:, 0]), 0.25 + 0.15 * np.cos(35 * p[:, 1]),
                     0.15 + 0.1 * np.sin(30 * (p[:, 0] + p[:, 1]))], -1)


def _rays(cam):
    rays_c = cam.pixel_rays(cam.pixel_grid().reshape(-1, 2))
    dirs = rays_c / np.linalg.norm(rays_c, axis=1, keepdims=True)
    return dirs @ cam.world_from_cam[:3, :3].T, dirs[:, 2]


def true_background(cam, env=env_colour) -> tuple[np.ndarray, np.ndarray]:
    """((H, W, 3) colour, (H, W) z-depth, 0 = at infinity) of what lies behind the sphere in ``cam``;
    ``env``: the environment's colour along directions (default :func:`env_colour`)."""
    d, cz = _rays(cam)
    o = cam.center
    t = (TABLE_Z - o[2]) / np.where(np.abs(d[:, 2]) > 1e-12, d[:, 2], 1e-12)
    p = o + t[:, None] * d
    on = (t > 0) & (np.abs(p[:, 0]) < TABLE_HALF) & (np.abs(p[:, 1]) < TABLE_HALF)
    col = np.where(on[:, None], table_colour(p), env(d))
    z = np.where(on, t * cz, 0.0)
    H, W = cam.height, cam.width
    return col.reshape(H, W, 3).astype(np.float32), z.reshape(H, W).astype(np.float32)


def orbit_capture(n: int = 12, width: int = 96, height: int = 72,
                  env=env_colour) -> tuple[list[PlateView], list[np.ndarray]]:
    """(plate views, true backgrounds) of the orbit scene (module docstring); ``env`` as :func:`true_background`
    (:func:`black_env`: a table in a dark room, as a phone capture over a black backdrop)."""
    cams = scenes.ring_cameras(n, width, height, radius=RING_RADIUS, elevations=(20.0,), fov_deg=50.0)
    views, truth = [], []
    for cam in cams:
        bg, bz = true_background(cam, env)
        d, cz = _rays(cam)
        t = scenes.ray_sphere(np.broadcast_to(cam.center, d.shape), d, np.zeros(3), SPHERE_R)
        hit = np.isfinite(t).reshape(height, width)
        oz = np.where(np.isfinite(t), t * cz, 0.0).reshape(height, width).astype(np.float32)
        col = np.where(hit[..., None], np.array([0.1, 0.5, 0.15], np.float32), bg)
        views.append(PlateView(cam, col.astype(np.float32), oz, np.where(hit, oz, bz).astype(np.float32)))
        truth.append(bg)
    return views, truth


def room_image(width: int, height: int, seed: int = 0) -> np.ndarray:
    """(H, W, 3) linear textured room: smooth gradients, blocks and stripes in [0.05, 0.9]."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:height, 0:width].astype(np.float64)
    img = np.zeros((height, width, 3))
    for _ in range(5):
        f = rng.uniform(0.05, 0.3, 2)
        img += rng.uniform(0.04, 0.12, 3) * np.sin(f[0] * x + f[1] * y + rng.uniform(0, 6.3))[..., None]
    blocks = rng.uniform(0, 1, (height // 6 + 1, width // 6 + 1, 3))
    img += 0.25 * np.kron(blocks, np.ones((6, 6, 1)))[:height, :width]
    return np.clip(img + 0.3, 0.05, 0.9).astype(np.float32)


def _needles(height: int, width: int, angle: float, rng, ss: int = 6, n: int = 40):
    """(coverage (H, W), depth mask (H, W) bool) of a turning object: an opaque core and ``n`` thin
    needles around the image centre turned by ``angle`` (radians about the vertical image axis,
    foreshortened), supersampled ``ss`` x ``ss``; the depth sees the core and needles at least
    a pixel wide at the pixel centre."""
    H, W = height * ss, width * ss
    yy, xx = np.meshgrid(cell_centres(H), cell_centres(W), indexing="ij")  # supersample centres
    cy, cx = H / 2, W / 2
    cov = ((yy - cy) / (0.3 * H)) ** 2 + ((xx - cx) / (0.05 * W)) ** 2 < 1
    seen = cov.copy()
    for _ in range(n):
        h = rng.uniform(-0.28, 0.28) * H
        az = rng.uniform(0, 2 * np.pi) + angle
        length = rng.uniform(0.1, 0.22) * W * np.cos(az)
        width_px = rng.uniform(0.3, 1.6) * ss
        p0 = np.array([cy + h, cx])
        d = np.array([rng.uniform(-0.05, 0.05) * H, length])
        t = np.clip(((yy - p0[0]) * d[0] + (xx - p0[1]) * d[1]) / max(d @ d, 1e-9), 0, 1)
        dist = np.hypot(yy - p0[0] - t * d[0], xx - p0[1] - t * d[1])
        line = dist < width_px / 2
        cov |= line
        if width_px >= ss:
            seen |= line
    alpha = cov.reshape(height, ss, width, ss).mean((1, 3))
    return alpha.astype(np.float32), seen[ss // 2::ss, ss // 2::ss]


@functools.lru_cache(maxsize=8)
def _turning_object(n: int, width: int, height: int, seed: int) -> tuple:
    """The :func:`_needles` of each of the turntable's ``n`` frames (made once per process: 6 s at 192x144, which
    a dozen tests asked for again), read-only; :func:`turntable_capture` copies them."""
    out = []
    for i in range(n):
        a, seen = _needles(height, width, 2 * np.pi * i / n, np.random.default_rng(seed + 1))
        a.setflags(write=False)
        seen.setflags(write=False)
        out.append((a, seen))
    return tuple(out)


def turntable_capture(n: int = 12, width: int = 96, height: int = 72, gains=None, seed: int = 0, room=None):
    """(plate views, true background (H, W, 3), true alphas, colours of the object (3,)) of the
    turntable scene (module docstring); ``gains`` (n, 3): each frame's exposure (colour / gain);
    ``room`` (H, W, 3): the background (default :func:`room_image`; above 1 the photos clip)."""
    room = room_image(width, height, seed) if room is None else np.asarray(room, np.float32)
    cams = scenes.ring_cameras(n, width, height, radius=RING_RADIUS, elevations=(15.0,), fov_deg=40.0)
    F = np.array([0.08, 0.3, 0.06], np.float32)
    views, alphas = [], []
    for i, (cam, (a, seen)) in enumerate(zip(cams, _turning_object(n, width, height, seed), strict=True)):
        a, seen = a.copy(), seen.copy()
        col = a[..., None] * F + (1 - a[..., None]) * room
        if gains is not None:
            col = col / np.asarray(gains[i], np.float32)
        depth = np.where(seen, RING_RADIUS, 0.0).astype(np.float32)
        views.append(PlateView(cam, np.clip(col, 0, 1).astype(np.float32), depth, depth))
        alphas.append(a)
    return views, room, alphas, F


def needle_composite(height: int = 96, width: int = 128, n: int = 90, background=None, seed: int = 0, ss: int = 8,
                     shade: float = 0.0):
    """(image C (H, W, 3), background B, true alpha (H, W), straight colour F (H, W, 3), object depth
    (H, W) float32): an opaque brown core and ``n`` green needles 0.25-1.4 px wide (mostly partial
    pixels) over ``background`` (default :func:`room_image`; an (H, W, 3) array is taken as it is);
    depth where the pixel centre hits.  ``shade``: each needle's colour is scaled by its own factor
    in [1 - shade, 1] (lit and shaded needles: colours along one direction from a bright room)."""
    alpha, F, depth = (x.copy() for x in _needle_object(height, width, n, seed, ss, float(shade)))
    B = room_image(width, height, seed) if background is None else np.broadcast_to(background, F.shape)
    C = alpha[..., None] * F + (1 - alpha[..., None]) * B
    return C.astype(np.float32), np.asarray(B, np.float32), alpha.astype(np.float32), F.astype(np.float32), depth


@functools.lru_cache(maxsize=16)
def _needle_object(height: int, width: int, n: int, seed: int, ss: int, shade: float) -> tuple:
    """(alpha (H, W) float64, straight colour F (H, W, 3) float64, depth (H, W) float32) of
    :func:`needle_composite`'s object, made once per process (8 s at 256x192 with 160 needles, asked for by a
    dozen tests), read-only."""
    rng = np.random.default_rng(seed)
    H, W = height * ss, width * ss
    yy, xx = np.meshgrid(cell_centres(H), cell_centres(W), indexing="ij")  # supersample centres
    cy, cx = H / 2, W / 2
    core = ((yy - cy) / (0.18 * H)) ** 2 + ((xx - cx) / (0.08 * W)) ** 2 < 1
    cov = core.copy()
    lit = np.ones(cov.shape)
    for _ in range(n):
        a0 = rng.uniform(0, 2 * np.pi)
        r0 = rng.uniform(0.0, 0.35) * H
        p0 = np.array([cy + r0 * np.sin(a0), cx + r0 * np.cos(a0)])
        ang = a0 + rng.normal(0, 0.6)
        d = rng.uniform(0.05, 0.15) * H * np.array([np.sin(ang), np.cos(ang)])
        radius = rng.uniform(0.25, 1.4) * ss / 2
        # only the supersamples near the needle can be within its radius: the box around its segment (the same
        # booleans as over the whole grid, 20x faster)
        ends = np.array([p0, p0 + d])
        lo = np.maximum(np.floor(ends.min(0) - radius).astype(int) - 2, 0)
        hi = np.minimum(np.ceil(ends.max(0) + radius).astype(int) + 2, (H, W))
        box = (slice(lo[0], hi[0]), slice(lo[1], hi[1]))
        y, x = yy[box], xx[box]
        t = np.clip(((y - p0[0]) * d[0] + (x - p0[1]) * d[1]) / (d @ d), 0, 1)
        line = np.zeros(cov.shape, bool)
        line[box] = np.hypot(y - p0[0] - t * d[0], x - p0[1] - t * d[1]) < radius
        cov |= line
        if shade:
            lit[line & ~core] = rng.uniform(1 - shade, 1)
    alpha = cov.reshape(height, ss, width, ss).mean((1, 3))
    y, x = np.mgrid[0:height, 0:width] / height
    F = np.stack([0.08 + 0.06 * np.sin(5 * x), 0.25 + 0.15 * np.cos(4 * y), 0.05 + 0.03 * x], -1)
    if shade:  # the mean factor of the covered subsamples
        F = F * ((lit * cov).reshape(height, ss, width, ss).sum((1, 3)) / np.maximum(alpha * ss * ss, 1))[..., None]
    c = core.reshape(height, ss, width, ss).mean((1, 3))[..., None]
    F = F * (1 - c) + np.array([0.3, 0.12, 0.05]) * c
    depth = np.where(cov[ss // 2::ss, ss // 2::ss], 0.5, 0.0).astype(np.float32)
    for a in (alpha, F, depth):
        a.setflags(write=False)
    return alpha, F, depth


def band_error(views, plates, truths) -> tuple[float, float]:
    """(median over views of the band's median largest-channel |plate - truth| where known, mean band known)."""
    errs, known = [], []
    for v, p, t in zip(views, plates, truths, strict=True):
        band = depth_trimap(v.object_depth) == UNKNOWN
        k = band & p.known
        errs.append(float(np.median(np.abs(p.background - t).max(axis=-1)[k])) if k.any() else np.inf)
        known.append(k.sum() / band.sum())
    return float(np.median(errs)), float(np.mean(known))


def switched_alpha_mse(monkeypatch, module, flag: str, C, tri, B, A, D, region) -> dict:
    """{False: alpha MSE in ``region``, True: ...} of the known-background matte (the plate ``B``
    known everywhere, noise 0.004, the depth ``D``'s mask) with ``module.flag`` off and on: a
    matting rule against the true alpha ``A`` without it."""
    from capture.matting import solve_known

    mse = {}
    for on in (False, True):
        monkeypatch.setattr(module, flag, on)
        m = solve_known(C, tri, B, np.ones(A.shape, bool), 0.004, "plate", D > 0)
        mse[on] = float(np.mean((m.alpha - A)[region] ** 2))
    return mse

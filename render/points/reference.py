"""Numpy reference of the plain RGB-D point splatter (issue 11's baseline, the ``points`` method;
docs/methods.md §1.9).

Every pixel of every kept view that has a depth is back-projected to a coloured world point
(:func:`back_project`).  For a new view the ``N_VIEWS`` kept cameras nearest in viewing angle
(:func:`nearest_views`: the angle at the object centre between the directions to the two
camera centres) are taken; their points are projected into the view with a z-buffer in
``SPLAT_PX`` x ``SPLAT_PX``-pixel splats, and every pixel averages the colours of all the points
that land on it within ``VIS_TOL_M`` of its front depth, each weighted by 1 / angle of its
camera (:func:`splat`).  Nothing else: no filtering, no fill, one sample per pixel.

With a matte (``volume.model.RgbzImages.alpha``) every point carries its premultiplied colour and
its alpha, averaged alike: the frame's colour is premultiplied and its alpha the points' mean
alpha (without one, 1 wherever a point lands).

A splat of side s centred on the projection (u, v) (OpenCV pixel centres) covers the pixels
whose centre lies in [u - s/2, u + s/2) x [v - s/2, v + s/2): for s = 2 the 2 x 2 pixels
nearest to the point (the rule of GL point sprites).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from capture.camera import Camera

#: Kept cameras splatted per frame (the nearest in viewing angle).
N_VIEWS = 4
#: Splat side in output pixels.
SPLAT_PX = 2
#: Points within this distance (metres of z-depth) behind a pixel's front depth are averaged.
VIS_TOL_M = 0.004
#: Smallest viewing angle used in the 1 / angle weight (radians): an eye on an input camera
#: gives that camera (almost) all the weight without dividing by zero.
ANGLE_EPS = 1e-3


class Cloud(NamedTuple):
    """The coloured points of one kept view: ``points`` (N, 3) float64 world metres,
    ``colours`` (N, 3) float32 linear rgb, or (N, 4) premultiplied rgb + alpha with a matte."""

    points: np.ndarray
    colours: np.ndarray


def back_project(cameras, rgb: np.ndarray, depth: np.ndarray, alpha: np.ndarray | None = None) -> list[Cloud]:
    """One Cloud per camera: every pixel with depth > 0 of ``depth`` (N, H, W, metres) with its
    colour in ``rgb`` (N, H, W, 3 linear), premultiplied by ``alpha`` (N, H, W) and with the alpha
    appended when a matte is given."""
    out = []
    for i, (cam, c, d) in enumerate(zip(cameras, rgb, depth)):
        pts, mask = cam.depth_to_points(d)
        col = np.asarray(c, np.float32)[mask]
        if alpha is not None:
            a = np.asarray(alpha[i], np.float32)[mask][:, None]
            col = np.concatenate([col * a, a], 1)
        out.append(Cloud(pts, col))
    return out


def back_project_crop(cam: Camera, rect, rgb: np.ndarray, depth: np.ndarray,
                      alpha: np.ndarray | None = None) -> Cloud:
    """The Cloud of one view from its crop (render.crops): ``rect`` (x0, y0, w, h) in the camera's
    image, ``rgb`` (h, w, 3) linear, ``depth`` (h, w) metres, ``alpha`` (h, w) or None; the same
    points, in the same order, as :func:`back_project` of the full frame the crop was cut from."""
    x0, y0 = int(rect[0]), int(rect[1])
    d = np.asarray(depth)
    mask = np.isfinite(d) & (d > 0)
    v, u = np.nonzero(mask)
    uv = np.stack([u + float(x0), v + float(y0)], -1).astype(np.float64)
    pts = cam.unproject(uv, d[mask])
    col = np.asarray(rgb, np.float32)[mask]
    if alpha is not None:
        a = np.asarray(alpha, np.float32)[mask][:, None]
        col = np.concatenate([col * a, a], 1)
    return Cloud(pts, col)


def view_direction(position: np.ndarray, centre: np.ndarray, forward: np.ndarray | None = None) -> np.ndarray:
    """(3,) unit direction from ``centre`` to ``position``; ``-forward`` when they coincide
    (an eye at the object centre)."""
    d = np.asarray(position, np.float64) - np.asarray(centre, np.float64)
    n = float(np.linalg.norm(d))
    if n < 1e-9:
        if forward is None:
            raise ValueError("view_direction: position at the centre and no forward axis")
        return -np.asarray(forward, np.float64) / np.linalg.norm(forward)
    return d / n


def view_angles(eye: Camera, cameras, centre: np.ndarray) -> np.ndarray:
    """(N,) angles (radians) at ``centre`` between the eye's direction and each camera's."""
    t = view_direction(eye.center, centre, eye.forward)
    dirs = np.stack([view_direction(c.center, centre, c.forward) for c in cameras])
    return np.arccos(np.clip(dirs @ t, -1.0, 1.0))


def nearest_views(eye: Camera, cameras, centre: np.ndarray, k: int = N_VIEWS) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the (at most) ``k`` cameras nearest to ``eye`` in viewing angle, nearest
    first (ties: lower index first), and their angles."""
    ang = view_angles(eye, cameras, centre)
    order = np.argsort(ang, kind="stable")[:k]
    return order, ang[order]


def splat_pixels(uv: np.ndarray, width: int, height: int, side: int = SPLAT_PX):
    """Pixels covered by splats of ``side`` x ``side`` pixels centred at ``uv`` (M, 2): yields
    (point index, flat pixel index) arrays, one pair per offset of the splat, inside the image."""
    x0 = np.ceil(uv[:, 0] - 0.5 * side).astype(np.int64)
    y0 = np.ceil(uv[:, 1] - 0.5 * side).astype(np.int64)
    for dy in range(side):
        for dx in range(side):
            x, y = x0 + dx, y0 + dy
            ok = np.nonzero((x >= 0) & (y >= 0) & (x < width) & (y < height))[0]
            yield ok, y[ok] * width + x[ok]


def splat(eye: Camera, clouds, weights, side: int = SPLAT_PX, tol: float = VIS_TOL_M):
    """The splatter's frame for ``eye`` from ``clouds`` (Cloud per camera) with one weight per
    cloud: (rgb (H, W, 3) float32 linear premultiplied (over black), alpha (H, W) float32 (0 / 1
    without a matte, the points' mean alpha with one), depth (H, W) float32 front z-depth, 0 where
    empty, splatted point count)."""
    W, H = eye.width, eye.height
    pix, zs, cols, wts = [], [], [], []
    n_pts = 0
    for cl, w in zip(clouds, weights):
        if len(cl.points) == 0:
            continue
        uv, z = eye.project(cl.points)
        front = np.nonzero(z > 0)[0]
        n_pts += len(front)
        for i, p in splat_pixels(uv[front], W, H, side):
            j = front[i]
            pix.append(p)
            zs.append(z[j])
            cols.append(cl.colours[j])
            wts.append(np.full(len(j), float(w)))
    C = next((cl.colours.shape[1] for cl in clouds if len(cl.colours)), 3)
    rgb = np.zeros((H * W, C))
    front_z = np.full(H * W, np.inf)
    if pix:
        pix, zs, cols, wts = (np.concatenate(a) for a in (pix, zs, cols, wts))
        np.minimum.at(front_z, pix, zs)
        near = zs < front_z[pix] + tol
        wsum = np.bincount(pix[near], wts[near], H * W)
        for k in range(C):
            rgb[:, k] = np.bincount(pix[near], wts[near] * cols[near, k], H * W)
        rgb /= np.where(wsum > 0, wsum, 1.0)[:, None]
    covered = np.isfinite(front_z)
    alpha = np.minimum(rgb[:, 3], 1.0) if C == 4 else covered
    depth = np.where(alpha > 0, front_z, 0.0)
    return (rgb[:, :3].reshape(H, W, 3).astype(np.float32), alpha.reshape(H, W).astype(np.float32),
            depth.reshape(H, W).astype(np.float32), n_pts)


def points_frame(eye: Camera, clouds, cameras, centre: np.ndarray, k: int = N_VIEWS):
    """splat() with the ``k`` cameras nearest to ``eye`` weighted by 1 / angle."""
    idx, ang = nearest_views(eye, cameras, centre, k)
    return splat(eye, [clouds[i] for i in idx], 1.0 / np.maximum(ang, ANGLE_EPS))

"""New viewpoints derived from a capture rig (its up direction and a turntable orbit), and the
turntable ring of cameras itself.

Nothing in the orbit assumes the world's +z is up or that the object sits at the origin: both
are estimated from the input cameras and the object's bounds.
"""

from __future__ import annotations

import numpy as np

from capture.camera import Camera, image_up, look_at, make_K


def estimate_up(cameras) -> np.ndarray:
    """(3,) unit world 'up' of a rig: the mean of the cameras' image-up directions
    (``capture.camera.image_up``), which for any upright capture rig is the world's up."""
    ups = np.array([image_up(c) for c in cameras])
    m = ups.sum(axis=0)
    n = np.linalg.norm(m)
    if n < 1e-6 * len(ups):
        raise ValueError("cannot estimate the rig's up direction: the cameras' up vectors cancel out")
    return m / n


def orbit_cameras(cameras, n: int, center=None, up=None) -> list[Camera]:
    """n cameras on a circle around ``up`` through ``center`` (default: the point closest to all
    optical axes), at the input cameras' mean distance and mean height along ``up``, looking at
    ``center``, with the first camera's intrinsics; the first starts at the first camera's azimuth."""
    if n < 1:
        raise ValueError(f"an orbit needs at least one frame, got {n}")
    cameras = list(cameras)
    up = estimate_up(cameras) if up is None else np.asarray(up, float) / np.linalg.norm(up)
    if center is None:
        center = closest_point_to_axes(cameras)
    center = np.asarray(center, float)
    rel = np.array([c.center for c in cameras]) - center
    h = float(np.mean(rel @ up))
    radial = rel - np.outer(rel @ up, up)
    r = float(np.mean(np.linalg.norm(radial, axis=1)))
    e1 = radial[0] / max(np.linalg.norm(radial[0]), 1e-12)
    if np.linalg.norm(radial[0]) < 1e-9:                  # first camera on the axis
        e1 = np.cross(up, [1.0, 0, 0] if abs(up[0]) < 0.9 else [0, 1.0, 0])
        e1 /= np.linalg.norm(e1)
    e2 = np.cross(up, e1)
    c0 = cameras[0]
    out = []
    for i in range(n):
        a = 2 * np.pi * i / n
        eye = center + h * up + r * (np.cos(a) * e1 + np.sin(a) * e2)
        out.append(Camera(c0.K, look_at(eye, center, up=up), c0.width, c0.height, name=f"orbit_{i:04d}.png"))
    return out


def closest_point_to_axes(cameras) -> np.ndarray:
    """(3,) least-squares point nearest to every camera's optical axis (the rig's look-at point)."""
    A = np.zeros((3, 3))
    b = np.zeros(3)
    for c in cameras:
        d = c.forward
        P = np.eye(3) - np.outer(d, d)
        A += P
        b += P @ c.center
    if np.linalg.matrix_rank(A, tol=1e-9) < 3:        # parallel axes: fall back to the mean centre + 1 m
        return np.mean([c.center + c.forward for c in cameras], axis=0)
    return np.linalg.solve(A, b)


def ring_cameras(n: int, width: int, height: int, focal: float, radius: float, elevations_deg=(0.0,),
                 azimuths_rad=None, target=(0.0, 0.0, 0.0), name: str = "cam_{:03d}") -> list[Camera]:
    """``n`` turntable cameras around the world +z axis through ``target``, looking at it (world +z
    up in the image): camera i at azimuth ``azimuths_rad[i]`` (default 2 pi i / n, counter-clockwise
    from +x), elevation ``elevations_deg[i % len]`` and distance ``radius`` (metres); square pixels
    of ``focal`` pixels, principal point at the image centre; named ``name.format(i)``."""
    K = make_K(focal, focal, (width - 1) / 2, (height - 1) / 2)
    az = 2 * np.pi * np.arange(n) / n if azimuths_rad is None else np.asarray(azimuths_rad, np.float64)
    target = np.asarray(target, np.float64)
    cams = []
    for i, a in enumerate(az):
        el = np.radians(elevations_deg[i % len(elevations_deg)])
        eye = target + radius * np.array([np.cos(a) * np.cos(el), np.sin(a) * np.cos(el), np.sin(el)])
        cams.append(Camera(K, look_at(eye, target), width, height, name.format(i)))
    return cams


def focal_for_fov(size_px: int, fov_deg: float) -> float:
    """Focal length (pixels) whose field of view across ``size_px`` pixels is ``fov_deg`` degrees."""
    return 0.5 * size_px / np.tan(np.radians(fov_deg) / 2)

"""Rotations of 3-D space (Rodrigues' formula): the one implementation every package uses."""

from __future__ import annotations

import numpy as np

#: Below this |sin| of the angle between two directions they count as parallel.
PARALLEL_EPS = 1e-12


def _cross_matrix(k: np.ndarray) -> np.ndarray:
    return np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])


def rotation(axis, angle_rad: float) -> np.ndarray:
    """(3, 3) rotation by ``angle_rad`` (right-handed) about ``axis`` (any non-zero length):
    I + sin(a) K + (1 - cos(a)) K^2 with K the cross-product matrix of the unit axis."""
    a = np.asarray(axis, dtype=np.float64)
    n = np.linalg.norm(a)
    if a.shape != (3,) or not np.isfinite(n) or n == 0:
        raise ValueError(f"rotation: axis must be a finite non-zero 3-vector, got {axis!r}")
    K = _cross_matrix(a / n)
    return np.eye(3) + np.sin(angle_rad) * K + (1 - np.cos(angle_rad)) * K @ K


def rotation_between(u, target) -> np.ndarray:
    """(3, 3) smallest rotation taking the direction ``u`` to the direction ``target`` (both any
    non-zero length); for opposite directions a half turn about the axis perpendicular to
    ``target`` nearest to its smallest coordinate axis (about x for target +z)."""
    u, t = (np.asarray(v, np.float64) for v in (u, target))
    for v, name in ((u, "u"), (t, "target")):
        if v.shape != (3,) or not np.all(np.isfinite(v)) or np.linalg.norm(v) == 0:
            raise ValueError(f"rotation_between: {name} must be a non-zero 3-vector, got {v!r}")
    u, t = u / np.linalg.norm(u), t / np.linalg.norm(t)
    c = float(u @ t)
    v = np.cross(u, t)
    s = float(np.linalg.norm(v))
    if s < PARALLEL_EPS:
        if c > 0:
            return np.eye(3)
        e = np.eye(3)[int(np.argmin(np.abs(t)))]
        return rotation(e - (e @ t) * t, np.pi)
    return rotation(v, float(np.arctan2(s, c)))

"""Noise models for synthetic range scans (all seeded through an explicit numpy Generator).

* :func:`depth_noise`: additive Gaussian z-noise with standard deviation ``k * z^2``
  (structured-light / stereo scanners: the disparity error is constant, so the depth error
  grows with the square of the depth).
* :func:`grazing_dropout`: no measurement where the surface is seen at a grazing angle
  (angle between the normal and the ray to the camera above a threshold).
* :func:`random_holes`: random blobs (discs of random radius) with no measurement, covering
  a requested fraction of the image.
* :func:`perturb_pose`: a random rigid error of the recorded pose: rotation by an angle of
  RMS ``rot_deg`` about a random axis through the camera centre, and a translation of the
  centre of RMS ``trans_m``.

Each returns new arrays; the clean inputs are untouched.  tests/datasets_synthetic measure
that each does what it claims.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from capture.camera import Camera
from capture.rotations import rotation


@dataclass(frozen=True)
class NoiseConfig:
    """Which noise to add to a synthetic capture (all zero = exact data)."""

    depth_sigma_at_1m: float = 0.0
    """k of the depth noise: sigma(z) = k z^2 (metres of sigma at z = 1 m)."""
    grazing_deg: float = 0.0
    """Drop depth where the angle between normal and view ray exceeds this (0 = off)."""
    holes_fraction: float = 0.0
    """Fraction of the image covered by random hole blobs (0 = off)."""
    hole_radius_px: tuple[float, float] = (2.0, 8.0)
    """Range of blob radii (pixels, scaled with image width / 640)."""
    pose_rot_deg: float = 0.0
    """RMS rotation error of the recorded poses (degrees)."""
    pose_trans_frac: float = 0.0
    """RMS translation error of the recorded poses, as a fraction of the object size."""

    def __post_init__(self) -> None:
        for name in ("depth_sigma_at_1m", "grazing_deg", "holes_fraction", "pose_rot_deg", "pose_trans_frac"):
            if getattr(self, name) < 0:
                raise ValueError(f"noise: {name} must be >= 0, got {getattr(self, name)}")
        if self.grazing_deg >= 90:
            raise ValueError(f"noise: grazing_deg must be below 90, got {self.grazing_deg}")
        if self.holes_fraction >= 1:
            raise ValueError(f"noise: holes_fraction must be below 1, got {self.holes_fraction}")

    @property
    def any_depth(self) -> bool:
        return self.depth_sigma_at_1m > 0 or self.grazing_deg > 0 or self.holes_fraction > 0

    @property
    def any_pose(self) -> bool:
        return self.pose_rot_deg > 0 or self.pose_trans_frac > 0


def depth_noise(depth: np.ndarray, rng: np.random.Generator, sigma_at_1m: float) -> np.ndarray:
    """(H, W) z-depth + N(0, (k z^2)^2) on valid pixels (0 stays 0; results kept > 0)."""
    d = np.asarray(depth, np.float32)
    valid = d > 0
    z = d.astype(np.float64)
    noisy = z + rng.standard_normal(z.shape) * sigma_at_1m * z**2
    out = np.where(valid, np.maximum(noisy, 1e-6), 0.0)
    return out.astype(np.float32)


def incidence_angle_deg(camera: Camera, depth: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """(H, W) angle (degrees) between the world normal and the ray from the surface to the
    camera; NaN where there is no depth."""
    pts, mask = camera.depth_to_points(depth)
    out = np.full(depth.shape, np.nan)
    v = camera.center - pts
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    n = np.asarray(normals, np.float64)[mask]
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    out[mask] = np.degrees(np.arccos(np.clip(np.abs(np.sum(v * n, axis=1)), 0, 1)))
    return out


def grazing_dropout(camera: Camera, depth: np.ndarray, normals: np.ndarray, max_deg: float) -> np.ndarray:
    """Depth with pixels seen at more than ``max_deg`` from the normal set to 0."""
    ang = incidence_angle_deg(camera, depth, normals)
    out = np.asarray(depth, np.float32).copy()
    out[np.nan_to_num(ang, nan=0.0) > max_deg] = 0.0
    return out


def hole_mask(shape: tuple[int, int], rng: np.random.Generator, fraction: float,
              radius_px: tuple[float, float]) -> np.ndarray:
    """(H, W) bool: random discs added until they cover ``fraction`` of the image."""
    H, W = shape
    m = np.zeros((H, W), bool)
    if fraction <= 0:
        return m
    yy, xx = np.mgrid[0:H, 0:W]
    target = fraction * H * W
    while m.sum() < target:
        r = rng.uniform(*radius_px)
        cx, cy = rng.uniform(0, W), rng.uniform(0, H)
        x0, x1 = int(max(cx - r - 1, 0)), int(min(cx + r + 2, W))
        y0, y1 = int(max(cy - r - 1, 0)), int(min(cy + r + 2, H))
        sub = (xx[y0:y1, x0:x1] - cx) ** 2 + (yy[y0:y1, x0:x1] - cy) ** 2 <= r * r
        m[y0:y1, x0:x1] |= sub
    return m


def random_holes(depth: np.ndarray, rng: np.random.Generator, fraction: float,
                 radius_px: tuple[float, float]) -> np.ndarray:
    """Depth with the pixels of :func:`hole_mask` set to 0."""
    out = np.asarray(depth, np.float32).copy()
    out[hole_mask(out.shape, rng, fraction, radius_px)] = 0.0
    return out


def random_rotation(rng: np.random.Generator, rms_deg: float) -> np.ndarray:
    """(3, 3) rotation about a uniformly random axis by an angle drawn so that its RMS is
    ``rms_deg`` (the angle is |N(0, rms)| per axis component: rotation vector ~ N(0, rms^2/3 I))."""
    w = rng.standard_normal(3) * np.radians(rms_deg) / np.sqrt(3.0)
    a = float(np.linalg.norm(w))
    if a == 0:
        return np.eye(3)
    return rotation(w, a)


def perturb_pose(camera: Camera, rng: np.random.Generator, rot_deg: float, trans_m: float) -> Camera:
    """The camera with a random rigid pose error: orientation turned by a random rotation of RMS
    angle ``rot_deg`` about its own centre, centre moved by a random vector of RMS length
    ``trans_m``.  Intrinsics and size unchanged."""
    R = camera.cam_from_world[:3, :3]
    c = camera.center
    dR = random_rotation(rng, rot_deg)
    dc = rng.standard_normal(3) * trans_m / np.sqrt(3.0)
    R2 = R @ dR.T  # world_from_cam rotation R^T is turned by dR
    c2 = c + dc
    m = np.eye(4)
    m[:3, :3] = R2
    m[:3, 3] = -R2 @ c2
    return Camera(camera.K, m, camera.width, camera.height, camera.name)


def pose_error(a: Camera, b: Camera) -> tuple[float, float]:
    """(rotation angle in degrees, centre distance in metres) between two camera poses."""
    dR = a.cam_from_world[:3, :3] @ b.cam_from_world[:3, :3].T
    ang = np.degrees(np.arccos(np.clip((np.trace(dR) - 1) / 2, -1, 1)))
    return float(ang), float(np.linalg.norm(a.center - b.center))

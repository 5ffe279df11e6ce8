"""Depth maps -> point clouds with normals: the ONE conversion every registration method uses.

Points are produced in the scan's own camera frame (OpenCV axes, metres) by
:meth:`Camera.depth_to_points` on a copy of the camera with an identity pose, so a
registration method only ever estimates the rigid ``cam_from_world`` that places them.

Range data at depth discontinuities is unreliable (mixed pixels at silhouettes, fur tips,
needle edges): pixels whose depth differs from a 4-neighbour by more than
``edge_frac * depth`` are dropped before the cloud is built.  On fur this removes most of
the strand tips, which is what makes point-to-plane ICP usable at all (see ``icp.py``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from capture.camera import Camera
from capture.scan import Scan

#: Default relative depth jump (fraction of depth) between 4-neighbours that marks an edge pixel.
EDGE_FRAC = 0.02
#: Normal estimation radius in voxels of the cloud it is computed on.
NORMAL_RADIUS_VOXELS = 2.5
#: Maximum neighbours used for a normal.
NORMAL_MAX_NN = 30


@dataclass(frozen=True)
class CloudConfig:
    """How a depth map becomes a registration point cloud."""

    stride: int = 1
    """Use every ``stride``-th pixel in x and y (1 = all)."""
    edge_frac: float = EDGE_FRAC
    """Drop pixels whose depth jumps by more than this fraction of depth to a 4-neighbour (<= 0: keep all)."""
    median_px: int = 0
    """Median-filter the depth map over this window (pixels, odd; 0 = off) before anything else:
    on fur the strand tips scatter the depth, the median keeps the coat's envelope."""
    keep_silhouettes: bool = True
    """Keep pixels next to "no data" (thin needles / strands); False drops them (smooth objects)."""
    min_points: int = 30
    """Fewer valid points than this is an error naming the scan."""
    normal_radius_px: int = -1
    """Range-image normals (projective stage): half-size of the plane-fit window in pixels
    (``rangeimage.plane_fit``); -1 = auto from the measured noise (``rangeimage.choose_radius``);
    0 = central differences of neighbouring pixels (the estimate before issue 16)."""

    def __post_init__(self) -> None:
        if int(self.stride) < 1:
            raise ValueError(f"CloudConfig.stride must be >= 1, got {self.stride}")


class CloudError(ValueError):
    """A scan cannot be turned into a usable point cloud; the message names it."""


def edge_mask(depth: np.ndarray, edge_frac: float, keep_silhouettes: bool = True,
              far_side_only: bool = False) -> np.ndarray:
    """(H, W) bool: valid pixels with no *valid* 4-neighbour more than ``edge_frac * depth`` away
    in depth (mixed pixels at depth discontinuities).  With ``keep_silhouettes`` pixels next to
    "no data" are kept, so one-pixel needles and strands in front of empty space survive;
    without, they are dropped too (grazing silhouette pixels of smooth objects)."""
    d = np.asarray(depth, dtype=np.float64)
    valid = np.isfinite(d) & (d > 0)
    if edge_frac <= 0:
        return valid
    ok = valid.copy()
    dz = np.where(valid, d, np.nan)
    for axis in (0, 1):
        for shift in (1, -1):
            nb = np.roll(dz, shift, axis=axis)
            # the rolled border wraps around: treat it as missing
            if axis == 0:
                nb[0 if shift == 1 else -1, :] = np.nan
            else:
                nb[:, 0 if shift == 1 else -1] = np.nan
            with np.errstate(invalid="ignore"):
                jump = (dz - nb if far_side_only else np.abs(nb - dz)) > edge_frac * dz
            ok &= ~jump
            if not keep_silhouettes:
                ok &= np.isfinite(nb)
    return ok


def smooth_depth(depth: np.ndarray, median_px: int) -> np.ndarray:
    """Median filter of a depth map (0 = no data) that does not pull depths towards 0: empty
    pixels count as far; pixels empty before, or whose median is empty, stay empty."""
    d = np.asarray(depth, dtype=np.float64)
    if median_px <= 1:
        return d
    from scipy.ndimage import median_filter

    valid = np.isfinite(d) & (d > 0)
    far = 2.0 * (d[valid].max() if valid.any() else 1.0)
    m = median_filter(np.where(valid, d, far), size=int(median_px), mode="nearest")
    return np.where(valid & (m < far), m, 0.0)


def camera_frame(camera: Camera) -> Camera:
    """The same intrinsics with an identity pose: back-projection then yields camera-frame points."""
    return Camera(camera.K, np.eye(4), camera.width, camera.height, camera.name)


def scan_points(scan: Scan, config: CloudConfig = CloudConfig()) -> tuple[np.ndarray, np.ndarray]:
    """Camera-frame points and linear colours of a scan's reliable depth pixels.

    Returns:
        points: (N, 3) float64 metres, OpenCV camera axes of ``scan.camera``.
        colors: (N, 3) float64 linear RGB in [0, 1] (clipped).
    """
    depth = smooth_depth(scan.depth, config.median_px).astype(np.float32)
    keep = edge_mask(depth, config.edge_frac, config.keep_silhouettes)
    if config.stride > 1:
        sub = np.zeros_like(keep)
        sub[:: config.stride, :: config.stride] = True
        keep &= sub
    depth[~keep] = 0.0
    pts, mask = camera_frame(scan.camera).depth_to_points(depth)
    if len(pts) < config.min_points:
        raise CloudError(f"scan {scan.name!r}: only {len(pts)} usable depth pixels (need {config.min_points})")
    cols = np.clip(scan.linear_rgb[mask].astype(np.float64), 0.0, 1.0)
    return pts, cols


def to_o3d(points: np.ndarray, colors: np.ndarray | None = None):
    """numpy (N, 3) points [+ colours] -> open3d.geometry.PointCloud."""
    import open3d as o3d

    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.asarray(points, dtype=np.float64)))
    if colors is not None:
        pc.colors = o3d.utility.Vector3dVector(np.asarray(colors, dtype=np.float64))
    return pc


def downsample(cloud, voxel: float):
    """Voxel-grid average of a cloud, with normals (radius ``NORMAL_RADIUS_VOXELS`` voxels)
    oriented towards the camera at the origin of the cloud's frame."""
    import open3d as o3d

    d = cloud.voxel_down_sample(voxel) if voxel > 0 else o3d.geometry.PointCloud(cloud)
    d.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=NORMAL_RADIUS_VOXELS * voxel, max_nn=NORMAL_MAX_NN))
    d.orient_normals_towards_camera_location(np.zeros(3))
    return d


def scan_cloud(scan: Scan, config: CloudConfig = CloudConfig()):
    """A scan as a full-resolution open3d cloud in its camera frame (colours attached)."""
    pts, cols = scan_points(scan, config)
    return to_o3d(pts, cols)


def cloud_pyramid(cloud, voxels: tuple[float, ...]) -> list:
    """Downsampled copies (with normals) at each voxel size, in the given order."""
    return [downsample(cloud, v) for v in voxels]

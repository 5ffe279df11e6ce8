"""Evidence beyond the range surface for placing a view (issue 16): silhouettes against the
capture's empty background, and colour features (SIFT) with depth.

Each kind yields, for an ordered pair (target i, source j) at a relative pose ``T``
(cam_i_from_cam_j), a Gauss-Newton system in the left twist (w, t) of ``T`` (as
``projective.normal_equations`` does for the surface), so that any pose model (the turntable
of ``turntable_solve``) can chain it to its own parameters.

* **Silhouette**: points of view j near its outline, mapped into view i, must fall inside view
  i's silhouette; the residual is the distance (pixels) to it, 0 inside (one-sided: the
  silhouette of a fur ball's envelope is stable across views even where single strands are not).
* **Features**: SIFT keypoints matched between the colour images (ratio test, both ways), the
  source keypoint lifted to 3-D by its (median-filtered) depth; the residual is the pixel
  distance of its projection from the target keypoint (Cauchy-weighted: fur has mismatches).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from capture.camera import Camera
from capture.registration.projective import point_twist_jacobian, projection_jacobian
from capture.sampling import nearest_pixel, sample_image
from capture.scan import Scan

#: A colour pixel differs from the background when a channel differs by more than this (linear).
BACKGROUND_TOL = 0.02
#: Silhouette opening radius at 640 pixels across (pixels; scaled with width): removes single
#: strands and needles so the outline is the object's envelope.
SILHOUETTE_OPEN_PX = 2
#: Outline band (pixels, at 640 across) from which silhouette sample points are drawn.
OUTLINE_BAND_PX = 6
#: Huber scale of the silhouette residual (pixels).
SILHOUETTE_HUBER_PX = 2.0
#: Silhouette residuals are clipped at this distance (pixels): a point far outside is an
#: outlier (a foreign object), not a pull.
SILHOUETTE_CLIP_PX = 30.0
#: Ratio test of the feature matching (nearest / second nearest descriptor distance).
FEATURE_RATIO = 0.8
#: Most features kept per image.
MAX_FEATURES = 3000
#: Cauchy scale of the feature residual (pixels).
FEATURE_CAUCHY_PX = 2.0
#: Median window (pixels) of the depth that lifts a keypoint to 3-D.
FEATURE_DEPTH_WINDOW = 5


def _scaled_px(value: float, width: int) -> int:
    return max(1, int(round(value * width / 640)))


def silhouette_mask(scan: Scan, background: np.ndarray | None = None) -> np.ndarray:
    """(H, W) bool: the object against the empty background (depth measured, or colour away
    from the background colour (default: the median colour of the image border)), opened by
    ``SILHOUETTE_OPEN_PX`` so that single strands do not count."""
    from scipy.ndimage import binary_closing, binary_opening

    rgb = scan.linear_rgb
    if background is None:
        border = np.concatenate([rgb[0], rgb[-1], rgb[:, 0], rgb[:, -1]])
        background = np.median(border, axis=0)
    m = (scan.depth > 0) | (np.abs(rgb - background).max(axis=-1) > BACKGROUND_TOL)
    r = _scaled_px(SILHOUETTE_OPEN_PX, scan.camera.width)
    disk = _disk(r)
    return binary_opening(binary_closing(m, disk), disk)


def _disk(r: int) -> np.ndarray:
    y, x = np.mgrid[-r:r + 1, -r:r + 1]
    return x * x + y * y <= r * r


@dataclass(frozen=True)
class Silhouette:
    """A view's silhouette: distance outside it (pixels, (H, W)), its gradient (H, W, 2 as
    d/du, d/dv), and sample points near the outline ((M, 3) camera frame, metres)."""

    distance: np.ndarray
    grad: np.ndarray
    outline_points: np.ndarray
    area_px: int


def silhouette(scan: Scan, mask: np.ndarray, points: np.ndarray, valid: np.ndarray, samples: int) -> Silhouette:
    """Silhouette evidence of a view from its mask and its camera-frame range points
    ``points`` (H, W, 3) where ``valid``: up to ``samples`` outline points."""
    from scipy.ndimage import binary_erosion, distance_transform_edt

    dist = distance_transform_edt(~mask)
    gv, gu = np.gradient(dist)
    band = _scaled_px(OUTLINE_BAND_PX, scan.camera.width)
    inner = binary_erosion(mask, _disk(band), border_value=0)
    sel = valid & mask & ~inner
    iy, ix = np.nonzero(sel)
    if len(iy) > samples:
        keep = np.linspace(0, len(iy) - 1, samples).astype(np.int64)
        iy, ix = iy[keep], ix[keep]
    return Silhouette(dist, np.stack([gu, gv], axis=-1), points[iy, ix], int(mask.sum()))


def silhouette_equations(src: Silhouette, tgt: Silhouette, camera: Camera, T: np.ndarray,
                         sigma_px: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A 6x6, b 6, residuals px) of the source outline points against the target silhouette
    at ``T`` (target_from_source), residuals divided by ``sigma_px``."""
    q = src.outline_points @ T[:3, :3].T + T[:3, 3]
    q = q[q[:, 2] > 1e-6]
    if len(q) == 0:
        return np.zeros((6, 6)), np.zeros(6), np.zeros(0)
    uv, _ = Camera(camera.K, np.eye(4), camera.width, camera.height).project(q)
    H, W = tgt.distance.shape
    inside = (uv[:, 0] >= 0) & (uv[:, 0] <= W - 1) & (uv[:, 1] >= 0) & (uv[:, 1] <= H - 1)
    r = np.where(inside, sample_image(tgt.distance, uv[:, 0], uv[:, 1], "linear", "clamp"), SILHOUETTE_CLIP_PX)
    g = sample_image(tgt.grad, uv[:, 0], uv[:, 1], "linear", "clamp")
    use = inside & (r > 0) & (r < SILHOUETTE_CLIP_PX)
    a = np.einsum("nk,nkj->nj", g[use], projection_jacobian(camera.K, q[use]))
    J = point_twist_jacobian(q[use], a) / sigma_px
    rr = r[use] / sigma_px
    h = SILHOUETTE_HUBER_PX / sigma_px
    w = np.where(rr <= h, 1.0, h / np.maximum(rr, 1e-300))
    return (J * w[:, None]).T @ J, -(J * w[:, None]).T @ rr, r


@dataclass(frozen=True)
class Features:
    """A view's colour keypoints: pixels (K, 2), descriptors (K, 128) float32, camera-frame
    points (K, 3) from the depth (NaN where the keypoint has no depth)."""

    pixels: np.ndarray
    descriptors: np.ndarray
    points: np.ndarray


def features(scan: Scan, mask: np.ndarray, depth: np.ndarray) -> Features:
    """SIFT keypoints of the colour image inside ``mask``, lifted by the median of the valid
    ``depth`` in a ``FEATURE_DEPTH_WINDOW`` window."""
    import cv2
    from scipy.ndimage import median_filter

    gray = cv2.cvtColor(np.ascontiguousarray(scan.srgb8), cv2.COLOR_RGB2GRAY)
    kp, des = cv2.SIFT_create(nfeatures=MAX_FEATURES).detectAndCompute(gray, mask.astype(np.uint8) * 255)
    if des is None or not kp:
        return Features(np.zeros((0, 2)), np.zeros((0, 128), np.float32), np.zeros((0, 3)))
    uv = np.array([k.pt for k in kp], dtype=np.float64)
    d = np.where(depth > 0, depth, np.nan).astype(np.float64)
    far = np.nanmax(d) * 4 if np.isfinite(d).any() else 1.0
    med = median_filter(np.where(np.isfinite(d), d, far), size=FEATURE_DEPTH_WINDOW)
    iu = np.clip(nearest_pixel(uv[:, 0]), 0, depth.shape[1] - 1)
    iv = np.clip(nearest_pixel(uv[:, 1]), 0, depth.shape[0] - 1)
    z = med[iv, iu]
    z = np.where(z < far, z, np.nan)
    cam = Camera(scan.camera.K, np.eye(4), scan.camera.width, scan.camera.height)
    pts = cam.pixel_rays(uv) * z[:, None]
    return Features(uv, des.astype(np.float32), pts)


def match(a: Features, b: Features) -> np.ndarray:
    """(M, 2) index pairs (into a, into b) of mutual nearest neighbours passing the ratio test."""
    import cv2

    if len(a.descriptors) < 2 or len(b.descriptors) < 2:
        return np.zeros((0, 2), np.int64)
    bf = cv2.BFMatcher(cv2.NORM_L2)
    ab = bf.knnMatch(a.descriptors, b.descriptors, k=2)
    ba = bf.knnMatch(b.descriptors, a.descriptors, k=1)
    back = {m[0].queryIdx: m[0].trainIdx for m in ba if m}
    out = [(m[0].queryIdx, m[0].trainIdx) for m in ab
           if len(m) == 2 and m[0].distance < FEATURE_RATIO * m[1].distance
           and back.get(m[0].trainIdx) == m[0].queryIdx]
    return np.array(out, dtype=np.int64).reshape(-1, 2)


def feature_equations(src_points: np.ndarray, tgt_pixels: np.ndarray, camera: Camera, T: np.ndarray,
                      sigma_px: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A 6x6, b 6, residual norms px) of matched source 3-D points against target pixels at
    ``T`` (target_from_source), Cauchy-weighted, divided by ``sigma_px``."""
    ok = np.isfinite(src_points).all(axis=1)
    q = src_points[ok] @ T[:3, :3].T + T[:3, 3]
    x = tgt_pixels[ok]
    front = q[:, 2] > 1e-6
    q, x = q[front], x[front]
    if len(q) == 0:
        return np.zeros((6, 6)), np.zeros(6), np.zeros(0)
    K = camera.K
    uv = np.stack([K[0, 0] * q[:, 0] / q[:, 2] + K[0, 1] * q[:, 1] / q[:, 2] + K[0, 2],
                   K[1, 1] * q[:, 1] / q[:, 2] + K[1, 2]], axis=1)
    r = (uv - x) / sigma_px
    P = projection_jacobian(K, q)
    J = np.concatenate([_rows(P, q, 0), _rows(P, q, 1)], axis=0) / sigma_px
    rr = np.concatenate([r[:, 0], r[:, 1]])
    norm = np.linalg.norm(r, axis=1)
    c = FEATURE_CAUCHY_PX / sigma_px
    w1 = 1.0 / (1.0 + (norm / c) ** 2)
    w = np.concatenate([w1, w1])
    return (J * w[:, None]).T @ J, -(J * w[:, None]).T @ rr, norm * sigma_px


def _rows(P: np.ndarray, q: np.ndarray, k: int) -> np.ndarray:
    """(N, 6) twist Jacobian of pixel coordinate ``k`` (0 = u, 1 = v)."""
    return point_twist_jacobian(q, P[:, k, :])

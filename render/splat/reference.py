"""Numpy twin of the ``splat`` method: the 3D Gaussian Splatting image formation (Kerbl et al.
2023, the reference rasteriser's formulas) in vectorised float64, front to back.

Per Gaussian (:func:`project`), in the eye's OpenCV camera frame t = W p + t0:

* culled when t.z <= ``NEAR_M``;
* the EWA screen covariance (Zwicker et al. 2002) ``J W Sigma W^T J^T + LOW_PASS_PX2 I`` with
  J = [[fx/z, s/z, -(fx x + s y)/z^2], [0, fy/z, -fy y/z^2]] (s the skew), x/z and y/z clamped
  to +-``JACOBIAN_CLAMP`` x the half field of view as the reference does;
* the centre projected with K (OpenCV pixels: the centre of pixel (i, j) at (i, j));
* the colour max(0, 0.5 + SH(dir)) with dir the unit vector from the eye's centre to the
  Gaussian (volume/splat_sh.py);
* the reach: pixels where ``opacity exp(-q / 2) >= ALPHA_MIN`` (q = d^T Sigma'^-1 d), i.e.
  q <= 2 ln(opacity / ALPHA_MIN): no pixel outside it can receive anything.

Per pixel (:func:`blend`): the Gaussians sorted by their centre's z (ascending, ties by index),
``alpha = min(ALPHA_MAX, opacity exp(-q / 2))``, skipped when < ALPHA_MIN, blended front to back:
C += colour alpha T, A += alpha T, D += z alpha T, T *= 1 - alpha (no early stop: the GL owner
cannot stop per pixel; the reference's stop below T = 1e-4 changes a pixel by at most that
last Gaussian's share).  The frame (:func:`to_frame`): premultiplied linear
``srgb_to_linear(clip(C / A, 0, 1)) A``
(the coefficients hold display colour, volume/splats.py), alpha A, depth D / A (the
alpha-weighted mean z-depth of the Gaussians blended at the pixel).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from capture.camera import Camera
from capture.scan import srgb_to_linear
from volume import splat_sh

#: Variance (pixels^2) added to the screen covariance: the reference's anti-aliasing low pass.
LOW_PASS_PX2 = 0.3
#: Largest alpha of one Gaussian at one pixel (the reference's 0.99).
ALPHA_MAX = 0.99
#: Smallest alpha drawn (the reference's 1 / 255).
ALPHA_MIN = 1.0 / 255.0
#: Jacobian clamp: x/z, y/z limited to this x tan(half field of view) (the reference's 1.3).
JACOBIAN_CLAMP = 1.3
#: Gaussians nearer than this z-depth (metres) are culled.
NEAR_M = 0.01
#: Bounding-box pixels evaluated per batch by :func:`fragments` (bounds its memory).
FRAGMENT_BATCH = 2_000_000


class Projected(NamedTuple):
    """The screen-space Gaussians of one eye (only those drawn, front to back).

    Attributes:
        index: (P,) indices into the splat set, sorted by ``z`` (ties by index).
        mean: (P, 2) centre in OpenCV pixels.
        cov: (P, 2, 2) screen covariance with the low pass (pixels^2).
        conic: (P, 3) its inverse (a, b, c) of [[a, b], [b, c]].
        z: (P,) z-depth of the centre (metres).
        colour: (P, 3) display colour.
        opacity: (P,) opacity.
        reach: (P,) q limit 2 ln(opacity / ALPHA_MIN).
    """

    index: np.ndarray
    mean: np.ndarray
    cov: np.ndarray
    conic: np.ndarray
    z: np.ndarray
    colour: np.ndarray
    opacity: np.ndarray
    reach: np.ndarray


def screen_covariance(t: np.ndarray, cov_cam: np.ndarray, eye: Camera) -> np.ndarray:
    """(P, 2, 2) EWA screen covariance of camera-frame centres ``t`` (P, 3) and camera-frame
    covariances ``cov_cam`` (P, 3, 3), with the low pass."""
    K = eye.K
    fx, fy, s = K[0, 0], K[1, 1], K[0, 1]
    z = t[:, 2]
    limx, limy = JACOBIAN_CLAMP * 0.5 * eye.width / fx, JACOBIAN_CLAMP * 0.5 * eye.height / fy
    x = np.clip(t[:, 0] / z, -limx, limx) * z
    y = np.clip(t[:, 1] / z, -limy, limy) * z
    J = np.zeros((len(t), 2, 3))
    J[:, 0, 0], J[:, 0, 1], J[:, 0, 2] = fx / z, s / z, -(fx * x + s * y) / (z * z)
    J[:, 1, 1], J[:, 1, 2] = fy / z, -fy * y / (z * z)
    cov = np.einsum("pij,pjk,plk->pil", J, cov_cam, J)
    cov[:, 0, 0] += LOW_PASS_PX2
    cov[:, 1, 1] += LOW_PASS_PX2
    return cov


def project(positions, covariances, opacities, sh, eye: Camera) -> Projected:
    """The Gaussians (positions (N, 3), world covariances (N, 3, 3), opacities (N,), SH (N, K, 3))
    as ``eye`` sees them (module docstring)."""
    p = np.asarray(positions, np.float64)
    R = eye.cam_from_world[:3, :3]
    t = p @ R.T + eye.cam_from_world[:3, 3]
    o = np.asarray(opacities, np.float64)
    keep = np.nonzero((t[:, 2] > NEAR_M) & (o >= ALPHA_MIN))[0]
    keep = keep[np.argsort(t[keep, 2], kind="stable")]
    t = t[keep]
    cov_cam = np.einsum("ij,pjk,lk->pil", R, np.asarray(covariances, np.float64)[keep], R)
    cov = screen_covariance(t, cov_cam, eye)
    det = cov[:, 0, 0] * cov[:, 1, 1] - cov[:, 0, 1] ** 2
    conic = np.stack([cov[:, 1, 1], -cov[:, 0, 1], cov[:, 0, 0]], 1) / det[:, None]
    uv, _ = eye.project(p[keep])
    dirs = p[keep] - eye.center
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    col = splat_sh.colour(np.asarray(sh)[keep], dirs)
    return Projected(keep, uv, cov, conic, t[:, 2], col, o[keep], 2.0 * np.log(o[keep] / ALPHA_MIN))


def fragments(pr: Projected, width: int, height: int):
    """Every (Gaussian rank, flat pixel, alpha) with alpha >= ALPHA_MIN inside the image: the
    pixels of each Gaussian's bounding box of q <= reach, evaluated (``FRAGMENT_BATCH`` box
    pixels at a time), sorted by pixel then rank."""
    rx = np.sqrt(pr.reach * pr.cov[:, 0, 0])
    ry = np.sqrt(pr.reach * pr.cov[:, 1, 1])
    x0 = np.maximum(np.ceil(pr.mean[:, 0] - rx), 0).astype(np.int64)
    x1 = np.minimum(np.floor(pr.mean[:, 0] + rx), width - 1).astype(np.int64)
    y0 = np.maximum(np.ceil(pr.mean[:, 1] - ry), 0).astype(np.int64)
    y1 = np.minimum(np.floor(pr.mean[:, 1] + ry), height - 1).astype(np.int64)
    nx, ny = np.maximum(x1 - x0 + 1, 0), np.maximum(y1 - y0 + 1, 0)
    counts = nx * ny
    ends = np.cumsum(counts)
    out = []
    lo = 0
    while lo < len(counts):
        hi = max(int(np.searchsorted(ends, (ends[lo] - counts[lo]) + FRAGMENT_BATCH, "right")), lo + 1)
        g = np.arange(lo, hi)
        rank = np.repeat(g, counts[g])
        local = np.arange(len(rank)) - np.repeat(np.cumsum(counts[g]) - counts[g], counts[g])
        x = x0[rank] + local % nx[rank]
        y = y0[rank] + local // nx[rank]
        dx, dy = x - pr.mean[rank, 0], y - pr.mean[rank, 1]
        power = -0.5 * (pr.conic[rank, 0] * dx * dx + pr.conic[rank, 2] * dy * dy) - pr.conic[rank, 1] * dx * dy
        alpha = np.minimum(ALPHA_MAX, pr.opacity[rank] * np.exp(np.minimum(power, 0.0)))
        ok = (alpha >= ALPHA_MIN) & (power <= 0)
        out.append((rank[ok].astype(np.int32), (y * width + x)[ok].astype(np.int32), alpha[ok]))
        lo = hi
    if not out:
        return np.zeros(0, np.int32), np.zeros(0, np.int32), np.zeros(0)
    rank, pix, alpha = (np.concatenate(a) for a in zip(*out))
    order = np.lexsort((rank, pix))
    return rank[order], pix[order], alpha[order]


def blend(pr: Projected, width: int, height: int):
    """Front-to-back blending: (C (H, W, 3) display colour premultiplied, A (H, W), D (H, W)
    alpha-weighted z sum) as float64."""
    rank, pix, alpha = fragments(pr, width, height)
    log_t = np.log1p(-alpha)
    csum = np.cumsum(log_t)
    start = np.r_[True, pix[1:] != pix[:-1]]
    first = np.nonzero(start)[0]
    seg = np.cumsum(start) - 1
    before = csum - log_t - (csum[first] - log_t[first])[seg]  # log T before this fragment
    w = alpha * np.exp(before)
    n = width * height
    C = np.stack([np.bincount(pix, w * pr.colour[rank, k], n) for k in range(3)], -1)
    A = np.bincount(pix, w, n)
    D = np.bincount(pix, w * pr.z[rank], n)
    return C.reshape(height, width, 3), A.reshape(height, width), D.reshape(height, width)


def to_frame(C: np.ndarray, A: np.ndarray, D: np.ndarray):
    """(rgb (H, W, 3) premultiplied linear float32, alpha (H, W) float32, depth (H, W) float32)
    of blended (C, A, D) (module docstring)."""
    A = np.asarray(A, np.float64)
    has = A > 0
    safe = np.where(has, A, 1.0)
    straight = np.clip(np.asarray(C, np.float64) / safe[..., None], 0.0, 1.0)
    rgb = np.where(has[..., None], srgb_to_linear(straight) * A[..., None], 0.0)
    depth = np.where(has, np.asarray(D, np.float64) / safe, 0.0)
    return rgb.astype(np.float32), np.minimum(A, 1.0).astype(np.float32), depth.astype(np.float32)


def splat_frame(splats, eye: Camera):
    """The frame of a volume.splats.Splats seen by ``eye``: (rgb, alpha, depth) as :func:`to_frame`
    and the number of Gaussians drawn."""
    pr = project(splats.positions, splats.covariances(), splats.opacities, splats.sh, eye)
    return (*to_frame(*blend(pr, eye.width, eye.height)), len(pr.index))

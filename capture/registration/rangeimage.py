"""Normals and denoised points of a noisy, quantised range image (issue 16).

Consumer RGB-D sensors deliver depth in whole millimetres with a noise that grows as z^2.
At 640x480 and 0.6 m a pixel spans about 0.8 mm, so the depth step between two neighbours
is of the order of the noise and the quantum itself: normals from central differences of
neighbouring pixels then scatter by tens of degrees.  Measured on the synthetic plant (36
views, 5 degree perturbation, ``furrow bench register``): that alone took the median pose
error from 0.06 to 0.12 degrees (mm quantisation + z^2 noise) and, with flying pixels on
the depth edges, to 0.48 degrees.

Here each pixel's normal is the smallest principal axis of the camera-frame points in a
``(2r+1)^2`` window that lie on the same surface (depth within ``gate`` of the centre): a
least-squares plane (Hoppe et al. 1992, "Surface reconstruction from unorganized points"),
which averages the noise over the window.  Where the window holds a line rather than a
patch (a needle or strand one or two pixels wide) the normal is the direction
perpendicular to the line that faces the camera.  The pixel's point is replaced by the
intersection of its ray with the fitted plane (the depth averaged over the window), which
keeps corners and silhouettes where they are and removes the quantisation steps.  A pixel
far from its own window's plane (relative to the window's RMS residual) is dropped: the
flying pixels a sensor leaves on depth edges.
"""

from __future__ import annotations

import numpy as np

#: The window grows (:func:`choose_radius`) until the predicted normal noise is below this
#: (degrees).  Chosen on the synthetic plant at 640x480 with millimetre depth and z^2 noise
#: (pairs 20 and 60 degrees apart, fine stage from 0.5 degrees off, ``out/exp/e4.py`` in the
#: issue-16 report): radius 1 (12 degrees predicted) 0.093 median / 0.39 max pair error,
#: radius 2 (5.4) 0.096 / 0.24, radius 3 (2.7) 0.12 / 0.41: wider windows blur the needles.
NORMAL_NOISE_MAX_DEG = 8.0
#: Points are moved onto their window's plane only where the measured depth noise exceeds this
#: many pixel footprints: on a curved surface the plane sits inside the curve, a bias that
#: noise-free depth pays without a gain.  Measured (fine stage from near-true poses): the
#: control object at 128x96, noise-free (0.01 footprints of noise): 0.078 degrees drift
#: denoised, 0.018 raw; the plant at 640x480 noise-free (0.014): 0.039 / 0.022 pair error;
#: with millimetre depth and z^2 noise (0.75 footprints): 0.093 denoised / 0.25 raw.
DENOISE_MIN_NOISE_PX = 0.25
#: The noise estimate fits planes at every this-many-th pixel in x and y.
NOISE_SAMPLE_STRIDE = 3
#: Largest window half-size (pixels) :func:`choose_radius` picks.
MAX_RADIUS = 4
#: Below this ratio of the middle to the largest eigenvalue of the window's covariance the
#: points form a line (a needle seen along its length), not a surface patch.
LINE_EIGEN_RATIO = 0.05
#: A window with fewer same-surface points than this gives no normal.
MIN_WINDOW_POINTS = 3
#: A pixel further from its window's plane than this many times the image's noise (see
#: :func:`plane_fit`; plus ``OUTLIER_FLOOR_FRAC`` of its depth) is an outlier, dropped: a
#: flying pixel next to a depth edge that the gate alone keeps when it lies close to one side.
OUTLIER_SIGMAS = 3.0
#: Floor of the outlier distance as a fraction of depth (exact depth has a zero plane RMS).
OUTLIER_FLOOR_FRAC = 5e-4


def _moments(pts: np.ndarray, ok: np.ndarray, gate: np.ndarray, radius: int, at: np.ndarray):
    """Count, sum and second moments (xx, yy, zz, xy, xz, yz) of the points within ``radius``
    pixels of each usable pixel whose depth is within ``gate`` of the pixel's own (relative to
    the pixel's point, for numerical accuracy).  Returns (rows, cols, n, s1, s2) over the
    pixels ``at`` only (a plant fills a tenth of its images)."""
    H, W = ok.shape
    iy, ix = np.nonzero(at)
    c = pts[iy, ix]
    g = gate[iy, ix]
    n = np.zeros(len(iy))
    s1 = np.zeros((len(iy), 3))
    s2 = np.zeros((len(iy), 6))
    for dy in range(-radius, radius + 1):
        for dx in range(-radius, radius + 1):
            y = np.clip(iy + dy, 0, H - 1)
            x = np.clip(ix + dx, 0, W - 1)
            q = pts[y, x] - c
            w = ok[y, x] & (np.abs(q[:, 2]) <= g) & (y == iy + dy) & (x == ix + dx)
            q = q * w[:, None]
            n += w
            s1 += q
            s2 += np.stack([q[:, 0] * q[:, 0], q[:, 1] * q[:, 1], q[:, 2] * q[:, 2],
                            q[:, 0] * q[:, 1], q[:, 0] * q[:, 2], q[:, 1] * q[:, 2]], axis=1)
    return iy, ix, n, s1, s2


def _fit(pts: np.ndarray, ok: np.ndarray, gate: np.ndarray, radius: int, at: np.ndarray | None = None) -> dict:
    """One gated plane fit over the usable pixels (or those ``at``; arrays over ``rows``/``cols``): normal,
    has (a normal), plane (a patch, not a line), z (depth where the pixel's ray meets the
    plane), dist (the pixel's own distance from its window's plane), rms (the window's RMS
    plane residual)."""
    iy, ix, n, s1, s2 = _moments(pts, ok, gate, int(radius), ok if at is None else at)
    p = pts[iy, ix]
    good = n >= MIN_WINDOW_POINTS
    nn = np.maximum(n, 1.0)
    m = s1 / nn[:, None]
    C = np.empty((len(n), 3, 3))
    for a, b, k in ((0, 0, 0), (1, 1, 1), (2, 2, 2), (0, 1, 3), (0, 2, 4), (1, 2, 5)):
        C[:, a, b] = C[:, b, a] = s2[:, k] / nn - m[:, a] * m[:, b]
    C[~good] = np.eye(3)
    lam, vec = np.linalg.eigh(C)  # ascending
    v_min, t = vec[:, :, 0], vec[:, :, 2]
    line = good & (lam[:, 1] < LINE_EIGEN_RATIO * np.maximum(lam[:, 2], 1e-30))
    # a line: the normal is the part of the viewing ray perpendicular to it
    ray = p / np.maximum(np.linalg.norm(p, axis=-1, keepdims=True), 1e-12)
    normal = np.where(line[:, None], ray - np.sum(ray * t, axis=-1, keepdims=True) * t, v_min)
    norm = np.linalg.norm(normal, axis=-1)
    good &= norm > 1e-9
    normal = normal / np.where(norm > 0, norm, 1.0)[:, None]
    normal = np.where((np.sum(normal * p, axis=-1) > 0)[:, None], -normal, normal)  # face the camera
    normal[~good] = 0.0
    # the pixel's ray (z = 1) meets the plane n . (x - (p + m)) = 0
    den = np.sum(normal * p, axis=-1) / p[:, 2]
    plane = good & ~line & (np.abs(den) > 1e-6)
    z = np.where(plane, np.sum(normal * (p + m), axis=-1) / np.where(plane, den, 1.0), p[:, 2])
    return {"rows": iy, "cols": ix, "normal": normal, "has": good, "plane": plane, "z": z,
            "dist": np.abs(np.sum(normal * m, axis=-1)), "rms": np.sqrt(np.maximum(lam[:, 0], 0.0))}


def noise_at_1m(pts: np.ndarray, ok: np.ndarray, gate: np.ndarray) -> float:
    """The range image's depth noise: sigma (metres) at 1 m of a z^2 model, from the RMS
    residual of 3x3 plane fits facing the camera within 60 degrees (median over the pixels;
    the residual along the normal is the depth noise times |n_z|; corrected for the 3 fitted
    parameters)."""
    sub = np.zeros_like(ok)
    sub[::NOISE_SAMPLE_STRIDE, ::NOISE_SAMPLE_STRIDE] = True
    f = _fit(pts, ok, gate, 1, at=ok & sub)
    z = pts[f["rows"], f["cols"], 2]
    nz = np.abs(f["normal"][:, 2])
    pl = f["plane"] & (nz > 0.5)
    return float(np.median(f["rms"][pl] / (nz[pl] * z[pl] ** 2))) / np.sqrt(6 / 9) if pl.any() else 0.0


def worth_denoising(sigma_1m: float, depth_m: float, focal_px: float) -> bool:
    """Whether the depth noise (``sigma_1m`` z^2) exceeds ``DENOISE_MIN_NOISE_PX`` pixel footprints."""
    return sigma_1m * depth_m**2 > DENOISE_MIN_NOISE_PX * depth_m / focal_px


def choose_radius(sigma_1m: float, depth_m: float, focal_px: float, max_deg: float = NORMAL_NOISE_MAX_DEG) -> int:
    """Smallest window half-size r whose plane-fit normal has a predicted noise below ``max_deg``:
    slope noise = sigma(z) / (pixel footprint * (2r + 1) * sqrt(r (r + 1) / 3)) (least squares
    over a (2r+1)^2 grid), sigma(z) = sigma_1m z^2, footprint = z / f."""
    for r in range(1, MAX_RADIUS + 1):
        slope = sigma_1m * depth_m * focal_px / ((2 * r + 1) * np.sqrt(r * (r + 1) / 3))
        if np.degrees(np.arctan(slope)) <= max_deg:
            return r
    return MAX_RADIUS


def plane_fit(pts: np.ndarray, ok: np.ndarray, gate: np.ndarray, radius: int,
              denoise: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Gated window plane fit of a camera-frame range image, outliers removed.

    A first fit measures the image's noise (median over the windows of their RMS plane
    residual, divided by z^2: the sensor's sigma at 1 m); pixels further from their window's
    plane than ``OUTLIER_SIGMAS`` of that (plus ``OUTLIER_FLOOR_FRAC`` of depth) are dropped
    and the fit is repeated without them.

    Args:
        pts: (H, W, 3) camera-frame points (metres), anything where not ``ok``.
        ok: (H, W) bool usable pixels.
        gate: (H, W) maximum |z difference| (metres) of a neighbour on the same surface.
        radius: window half-size in pixels (>= 1).
        denoise: move each point to where its ray meets its window's plane (else keep it).
    Returns:
        normals (H, W, 3) unit, facing the camera (0 where none), has_normal (H, W) bool,
        points (H, W, 3) (denoised: the pixel's ray meets the fitted plane; raw on lines).
    """
    f = _fit(pts, ok, gate, radius)
    z = pts[f["rows"], f["cols"], 2]
    pl = f["plane"]
    sigma_1m = float(np.median(f["rms"][pl] / z[pl] ** 2)) if pl.any() else 0.0
    outlier = pl & (f["dist"] > OUTLIER_SIGMAS * sigma_1m * z**2 + OUTLIER_FLOOR_FRAC * z)
    keep = ok.copy()
    keep[f["rows"][outlier], f["cols"][outlier]] = False
    f = _fit(pts, keep, gate, radius)
    iy, ix = f["rows"], f["cols"]
    normals = np.zeros(pts.shape)
    normals[iy, ix] = f["normal"]
    has = np.zeros(ok.shape, bool)
    has[iy, ix] = f["has"]
    out = np.array(pts, dtype=np.float64)
    if denoise:
        out[iy, ix] = pts[iy, ix] * (f["z"] / pts[iy, ix, 2])[:, None]
    return normals, has, out

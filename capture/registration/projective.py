"""Fine registration of two range images by projective point-to-plane ICP (numpy).

Open3D's ICP associates each source point with its nearest target point in 3-D.  On partial
range views that is biased: source points the target camera cannot see (self-occlusion,
beyond the target's silhouette) still find a "nearest" point on the target's boundary and
pull the estimate (measured: 0.4-0.8 degrees of drift from the exact pose on noise-free
ray-cast scans, ``tests/capture/test_registration.py``).  Range images allow the exact
association instead (Blais & Levine 1995; KinectFusion): project the source point into the
target image and compare with the target pixel it lands on; points that land on no target
measurement, on a depth edge, too far in depth, or with an incompatible normal are not
used.  Then Gauss-Newton on the point-to-plane residual n_t . (T p_s - q_t) with Huber weights.

Surfaces with a continuous symmetry (the control torus spins about its own axis, a sphere
about any) leave a direction that geometry cannot fix.  With ``color_scale > 0`` a photometric
term is added (as Open3D's hybrid RGB-D odometry, Steinbruecker et al. 2011): the target
intensity sampled bilinearly at the projection of the source point minus the source
intensity, scaled to metres by ``color_scale`` (metres per unit of chromaticity, :func:`chroma`).  The
normal equations are lightly damped so that a direction neither term constrains does not move.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from capture.camera import Camera
from capture.depth_normals import depth_normals
from capture.registration import points as P
from capture.registration import rangeimage as RI
from capture.sampling import nearest_pixel, sample_image
from capture.scan import Scan

#: Minimum cosine between source and target normals for a projective correspondence.
NORMAL_COS_MIN = 0.5
#: Huber threshold of the point-to-plane residual, as a fraction of the depth gate.
HUBER_FRAC = 0.3
#: A neighbour further than this many ``edge_frac * depth`` in depth is not used for a normal.
NORMAL_JUMP_FACTOR = 1.0
#: The colour term uses pixels this many pixels inside the measured region.
COLOR_ERODE_PX = 2
#: Huber threshold of the colour residual (chromaticity units).  Measured on the glossy torus
#: (3 perturbation seeds, 5 degrees): 0.02 with ``color_scale_frac`` 0.006 gave median 0.07-0.12
#: degrees, 0.05 with 0.003 gave 0.34-0.50 (reflections are outliers of the chromaticity too).
COLOR_HUBER = 0.02
#: Colour residuals are clipped at this value in the reported colour RMSE (chromaticity units).
COLOR_RMSE_CLIP = 0.15
#: Regulariser of the chromaticity denominator (linear colour units): dark pixels carry no hue.
CHROMA_EPS = 0.05
#: Damping of the normal equations, relative to their mean diagonal.
DAMPING = 1e-6
#: Stop when the update is below this rotation (rad) and translation (m).
CONVERGED_ROT = 1e-7
CONVERGED_TRANS = 1e-8


@dataclass(frozen=True)
class DepthFrame:
    """A range image prepared for projective association (camera frame, metres).

    Attributes:
        points: (H, W, 3) float64 camera-frame points (0 where invalid).
        normals: (H, W, 3) float64 unit normals facing the camera (0 where invalid).
        valid: (H, W) bool pixels with a point and a normal (edges removed).
        camera: intrinsics (pose unused).
        intensity: (H, W) float64 red-blue chromaticity of the colour image (:func:`chroma`).
        grad: (H, W, 2) float64 d intensity / d (u, v) (central differences).
        color_valid: (H, W) bool pixels whose 3x3 neighbourhood is all measured: colour there is
            not blended with the background (anti-aliased silhouettes) and its gradient is clean.
        depth_sigma_m: measured depth noise (metres) at the median depth (``rangeimage.noise_at_1m``;
            0 when the normals come from central differences).
    """

    points: np.ndarray
    normals: np.ndarray
    valid: np.ndarray
    camera: Camera
    intensity: np.ndarray
    grad: np.ndarray
    color_valid: np.ndarray
    depth_sigma_m: float = 0.0


def depth_frame(scan: Scan, cfg: P.CloudConfig = P.CloudConfig()) -> DepthFrame:
    """Points and normals of a scan's depth map (edges removed): gated plane-fit normals and
    denoised points (``rangeimage.plane_fit``), or central differences when the radius is 0."""
    cam = P.camera_frame(scan.camera)
    d = P.smooth_depth(scan.depth, cfg.median_px)
    fit = cfg.normal_radius_px != 0
    # flying pixels lie behind the edge they fly from: drop the far side of a depth jump only
    # (the plane fit removes the rest), so thin needles in front keep their pixels
    ok = P.edge_mask(d, cfg.edge_frac, cfg.keep_silhouettes, far_side_only=fit)
    rays = cam.pixel_rays(cam.pixel_grid())
    pts = rays * np.where(ok, d, 0.0)[..., None]
    sigma_m = 0.0
    if fit:
        gate = cfg.edge_frac * d if cfg.edge_frac > 0 else np.full(d.shape, np.inf)
        z_med = float(np.median(d[ok])) if ok.any() else 1.0
        sigma_1m = RI.noise_at_1m(pts, ok, gate)
        sigma_m = sigma_1m * z_med**2
        radius = cfg.normal_radius_px
        if radius < 0:
            radius = RI.choose_radius(sigma_1m, z_med, float(cam.K[0, 0]))
        n, okn, pts = RI.plane_fit(pts, ok, gate, radius, RI.worth_denoising(sigma_1m, z_med, float(cam.K[0, 0])))
        pts = np.where(okn[..., None], pts, 0.0)
    else:
        # central difference where both neighbours are usable, else the one-sided one to the usable
        # neighbour (1-2 pixel wide needles and strands keep a normal); a depth edge is no tangent
        lim = NORMAL_JUMP_FACTOR * cfg.edge_frac * d if cfg.edge_frac > 0 else None
        n, okn = depth_normals(pts, ok, "average", max_step=lim)
    lum = chroma(scan.linear_rgb)
    gv, gu = np.gradient(lum)
    from scipy.ndimage import binary_erosion

    meas = d > 0
    cval = binary_erosion(meas, structure=np.ones((3, 3), bool), iterations=COLOR_ERODE_PX, border_value=0)
    return DepthFrame(pts, n, okn, cam, lum, np.stack([gu, gv], axis=-1), cval, sigma_m)


def chroma(rgb: np.ndarray) -> np.ndarray:
    """(H, W) red-blue chromaticity (R - B) / (R + G + B + CHROMA_EPS) of linear colour.

    Measured on the glossy synthetic torus (``furrow synth torus``): luminance differs by
    0.057 on average between two views of the same surface point (environment reflections
    move with the view) and pulled ICP 8-16 degrees off; this ratio differs by 0.028 and
    keeps the pair within 0.1 degree.  Shading and white highlights scale R, G, B together.
    """
    c = np.asarray(rgb, dtype=np.float64)
    return (c[..., 0] - c[..., 2]) / (c.sum(axis=-1) + CHROMA_EPS)


@dataclass
class ProjectiveResult:
    """Outcome of :func:`projective_icp`."""

    T: np.ndarray  # (4, 4) target_from_source
    fitness: float  # inliers / sampled source points
    rmse: float  # point-to-plane RMSE of the inliers (m)
    inliers: int
    iterations: int
    information: np.ndarray  # (6, 6) J^T W J of the last iteration (rotation, translation; target frame)
    color_rmse: float = float("nan")  # RMS chromaticity difference over colour-valid correspondences


def associate(src_pts: np.ndarray, src_nrm: np.ndarray, tgt: DepthFrame, T: np.ndarray, gate: float):
    """Projective correspondences of source points under ``T``.

    Returns (mask over source points, transformed source points q, target points t, target
    normals n, continuous target pixel coordinates uv).
    """
    q = src_pts @ T[:3, :3].T + T[:3, 3]
    ns = src_nrm @ T[:3, :3].T
    K = tgt.camera.K
    z = q[:, 2]
    good = z > 1e-6
    zs = np.where(good, z, 1.0)
    uf = K[0, 0] * q[:, 0] / zs + K[0, 1] * q[:, 1] / zs + K[0, 2]
    vf = K[1, 1] * q[:, 1] / zs + K[1, 2]
    u = nearest_pixel(np.clip(uf, -1, 1e6))
    v = nearest_pixel(np.clip(vf, -1, 1e6))
    H, W = tgt.valid.shape
    good &= (u >= 0) & (u < W) & (v >= 0) & (v < H)
    u = np.where(good, u, 0)
    v = np.where(good, v, 0)
    good &= tgt.valid[v, u]
    t = tgt.points[v, u]
    n = tgt.normals[v, u]
    good &= np.abs(q[:, 2] - t[:, 2]) < gate
    good &= np.sum(ns * n, axis=1) > NORMAL_COS_MIN
    return good, q, t, n, np.stack([uf, vf], axis=1)


@dataclass(frozen=True)
class Samples:
    """Source samples of a range frame (every ``stride``-th usable pixel): points, normals,
    chromaticity, colour-valid flag, (N, ...) camera frame."""

    points: np.ndarray
    normals: np.ndarray
    intensity: np.ndarray
    color_valid: np.ndarray


def source_samples(src: DepthFrame, stride: int = 1) -> Samples:
    """The usable pixels of ``src`` on a ``stride`` grid."""
    m = src.valid[::stride, ::stride]
    return Samples(src.points[::stride, ::stride][m], src.normals[::stride, ::stride][m],
                   src.intensity[::stride, ::stride][m], src.color_valid[::stride, ::stride][m])


def projection_jacobian(K: np.ndarray, q: np.ndarray) -> np.ndarray:
    """(N, 2, 3) d(u, v) / d q of the pinhole projection of camera points q (skew ignored)."""
    z = q[:, 2]
    J = np.zeros((len(q), 2, 3))
    J[:, 0, 0] = K[0, 0] / z
    J[:, 0, 2] = -K[0, 0] * q[:, 0] / z**2
    J[:, 1, 1] = K[1, 1] / z
    J[:, 1, 2] = -K[1, 1] * q[:, 1] / z**2
    return J


def point_twist_jacobian(q: np.ndarray, a: np.ndarray) -> np.ndarray:
    """(N, 6) d(a . q) / d(w, t) for the left perturbation q' = q + w x q + t: [q x a, a]."""
    return np.concatenate([np.cross(q, a), a], axis=1)


def _color_rows(q, uv, si, tgt: DepthFrame, color_scale: float):
    """Photometric rows (residual, Jacobian, Huber weight), all scaled to metres."""
    rc = (sample_image(tgt.intensity, uv[:, 0], uv[:, 1], "linear", "clamp") - si) * color_scale
    g = sample_image(tgt.grad, uv[:, 0], uv[:, 1], "linear", "clamp")
    a = np.einsum("nk,nkj->nj", g, projection_jacobian(tgt.camera.K, q))  # dI/dq
    Jc = point_twist_jacobian(q, a) * color_scale
    hc = COLOR_HUBER * color_scale
    return rc, Jc, np.where(np.abs(rc) <= hc, 1.0, hc / np.maximum(np.abs(rc), 1e-300))


def _color_ok(samples: Samples, good: np.ndarray, uv: np.ndarray, tgt: DepthFrame) -> np.ndarray:
    H, W = tgt.color_valid.shape
    cu = np.clip(nearest_pixel(uv[:, 0]), 0, W - 1)
    cv = np.clip(nearest_pixel(uv[:, 1]), 0, H - 1)
    return samples.color_valid[good] & tgt.color_valid[cv, cu]


def normal_equations(samples: Samples, tgt: DepthFrame, T: np.ndarray, gate: float,
                     color_scale: float = 0.0) -> tuple[np.ndarray, np.ndarray, int] | None:
    """Gauss-Newton system (A 6x6, b 6, correspondences) of the point-to-plane (+ photometric)
    residuals of ``samples`` against ``tgt`` at ``T`` (target_from_source), in the left twist
    (w, t) of ``T``, Huber-weighted; None with fewer than 6 correspondences."""
    parts = normal_equation_parts(samples, tgt, T, gate, color_scale)
    if parts is None:
        return None
    (A, b), (Ac, bc), n, _ = parts
    return A + Ac, b + bc, n


def normal_equation_parts(samples: Samples, tgt: DepthFrame, T: np.ndarray, gate: float, color_scale: float = 0.0):
    """As :func:`normal_equations`, the surface and the photometric systems apart:
    ((A, b) surface, (A, b) colour (zero when off), correspondences, colour RMSE (clipped
    chromaticity difference, NaN when off)) or None."""
    good, q, t, n, uv = associate(samples.points, samples.normals, tgt, T, gate)
    if good.sum() < 6:
        return None
    q, t, n, uv = q[good], t[good], n[good], uv[good]
    cok = _color_ok(samples, good, uv, tgt)
    r = np.sum(n * (q - t), axis=1)
    huber = HUBER_FRAC * gate
    w = np.where(np.abs(r) <= huber, 1.0, huber / np.maximum(np.abs(r), 1e-300))
    J = point_twist_jacobian(q, n)
    Ac, bc, crmse = np.zeros((6, 6)), np.zeros(6), float("nan")
    if color_scale > 0 and cok.sum() >= 6:
        rc, Jc, wc = _color_rows(q[cok], uv[cok], samples.intensity[good][cok], tgt, color_scale)
        Ac, bc = (Jc * wc[:, None]).T @ Jc, -(Jc * wc[:, None]).T @ rc
        crmse = float(np.sqrt(np.mean(np.minimum(np.abs(rc / color_scale), COLOR_RMSE_CLIP) ** 2)))
    return ((J * w[:, None]).T @ J, -(J * w[:, None]).T @ r), (Ac, bc), int(good.sum()), crmse


def twist_to_transform(x: np.ndarray) -> np.ndarray:
    """(4, 4) rigid map of a twist (w, t) (rotation vector w, then translation t)."""
    from capture.registration.perturb import rotation

    ang = float(np.linalg.norm(x[:3]))
    D = np.eye(4)
    if ang > 0:
        D[:3, :3] = rotation(x[:3] / ang, ang)
    D[:3, 3] = x[3:]
    return D


def solve_damped(A: np.ndarray, b: np.ndarray) -> np.ndarray | None:
    """x of (A + DAMPING * mean diagonal * I) x = b, or None when singular."""
    try:
        return np.linalg.solve(A + DAMPING * np.trace(A) / len(A) * np.eye(len(A)), b)
    except np.linalg.LinAlgError:
        return None


def alignment_stats(samples: Samples, tgt: DepthFrame, T: np.ndarray, gate: float) -> tuple[float, float, int, float]:
    """(fitness, point-to-plane RMSE (m), correspondences, colour RMSE) of ``samples`` at ``T``."""
    good, q, t, n, uv = associate(samples.points, samples.normals, tgt, T, gate)
    r = np.sum(n[good] * (q[good] - t[good]), axis=1)
    rmse = float(np.sqrt(np.mean(r**2))) if len(r) else float("inf")
    uvg = uv[good]
    cok = _color_ok(samples, good, uvg, tgt)
    crmse = float("nan")
    if cok.sum() > 0:
        rc = sample_image(tgt.intensity, uvg[cok, 0], uvg[cok, 1], "linear", "clamp") - samples.intensity[good][cok]
        crmse = float(np.sqrt(np.mean(np.minimum(np.abs(rc), COLOR_RMSE_CLIP) ** 2)))
    return float(good.sum()) / max(len(samples.points), 1), rmse, int(good.sum()), crmse


def projective_icp(src: DepthFrame, tgt: DepthFrame, T0: np.ndarray, gate: float, iterations: int = 30,
                   stride: int = 1, color_scale: float = 0.0) -> ProjectiveResult:
    """Point-to-plane (+ optional photometric) Gauss-Newton with projective association.

    Args:
        gate: maximum |z| difference (m) for a correspondence; also sets the Huber scale.
        stride: use every ``stride``-th source pixel.
        color_scale: metres per unit of chromaticity difference (0 = geometry only).
    Returns:
        :class:`ProjectiveResult` (target_from_source); fitness / rmse are geometric.
    """
    samples = source_samples(src, stride)
    T = np.asarray(T0, dtype=np.float64).copy()
    it = 0
    info = np.zeros((6, 6))
    for it in range(0, iterations + 1):
        system = normal_equations(samples, tgt, T, gate, color_scale)
        if system is None:
            break
        A, b, _ = system
        info = A.copy()
        if it == iterations:
            break
        x = solve_damped(A, b)
        if x is None:
            break
        T = twist_to_transform(x) @ T
        if np.linalg.norm(x[:3]) < CONVERGED_ROT and np.linalg.norm(x[3:]) < CONVERGED_TRANS:
            break
    fitness, rmse, inliers, crmse = alignment_stats(samples, tgt, T, gate)
    return ProjectiveResult(T, fitness, rmse, inliers, it, info, crmse)

"""Strand tangents of a capture (issue 23): where the model is fur (or needles), the 3-D direction of the
strands, estimated at relight time from the model's RGBz images -- nothing new is stored in the model.

1. **Image orientation** per capture view: the structure tensor of the band-passed log luminance
   (fine detail only, so smooth shading and the silhouette do not count), integrated over
   :data:`TENSOR_SIGMA_PX`; along strands the colour varies least, so the strand direction t2 is the
   tensor's minor eigenvector and its coherence c = (l1 - l2) / (l1 + l2) says how line-like the
   texture is (Rao & Schunck 1991; the orientation field of image-based hair capture, Paris et al. 2004).
2. **Lifted to 3-D**: the strand through pixel p along t2 lies in the plane through the camera centre
   spanned by the rays of p and p + t2; its unit normal m = R^T normalize(K^-1 p x K^-1 t2).  Each pixel
   with depth adds c m m^T to the voxel of its world point on a cube over the model.
3. **Per voxel**: the tangent T is the eigenvector of the smallest eigenvalue of sum c m m^T (the
   direction closest to every view's plane); the strand score (0..1) is how line-like the texture is
   (mean coherence, ramped between :data:`COHERENCE_LO` and :data:`COHERENCE_HI`) times how well the
   views agree on one direction (1 - e0 / e1 of the eigenvalues e0 <= e1 <= e2), times how well the voxel
   was seen (:data:`MIN_SAMPLES`).  A surface with a normal (pot, leaf, the body under the fur) scores
   near 0 and keeps the normal transfer.

T's sign is arbitrary (strands have no arrow; every transfer that uses T is even in T), so lookups
interpolate the tensor s T T^T and take its principal direction (:func:`field_sample`), never T itself.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Band-pass of the log luminance before the structure tensor: Gaussian sigmas (pixels) of the
#: derivative scale and of the local mean removed (fine strand texture only).
GRADIENT_SIGMA_PX = 0.8
BACKGROUND_SIGMA_PX = 3.0
#: Integration scale of the structure tensor (pixels).
TENSOR_SIGMA_PX = 2.5
#: Pixels this close (in pixels) to the silhouette are left out (their orientation is the outline's).
SILHOUETTE_MARGIN_PX = 3
#: Fine-detail energy ramp (trace of the structure tensor, (log luminance / pixel)^2): below LO a pixel
#: has no strand texture (smooth shading, sensor noise: measured <= 1.5e-3 at its 90th percentile on the
#: test's noisy smooth slab), above HI its coherence counts fully.
ENERGY_LO = 2e-3
ENERGY_HI = 1e-2
#: Luminance floor of the log (linear units relative to the view's median foreground luminance).
LOG_FLOOR = 0.02
#: Mean coherence ramp of the strand score: below LO a voxel is a surface, above HI a strand.
COHERENCE_LO = 0.25
COHERENCE_HI = 0.55
#: Samples (pixels over all views) a voxel needs for a full score.
MIN_SAMPLES = 12.0
#: Gaussian smoothing (voxels) of the accumulated tensors before the eigen-decomposition.
VOLUME_SMOOTH_VOXELS = 0.7
#: Resolution of the strand volume (voxels per side of the model's orientation cube).
STRAND_RES = 48
#: Every this-many-th pixel (per axis) of each capture view is lifted (cost; the tensor is smooth): None =
#: one pixel in round(width / STRIDE_WIDTH_PX) per axis (1 at 320 wide, 2 at 640, 4 at 1280).
PIXEL_STRIDE = None
STRIDE_WIDTH_PX = 320


@dataclass(frozen=True)
class StrandField:
    """Strand tangents on a cube of voxels.

    tangent: (L, L, L, 3) float32 unit world directions (sign arbitrary but locally consistent), [i, j, k].
    score: (L, L, L) float32 in [0, 1], 1 = clearly strands, 0 = a surface or unseen.
    origin: (3,) world position (metres) of the cube's minimum corner; voxel: edge length (metres).
    """

    tangent: np.ndarray
    score: np.ndarray
    origin: np.ndarray
    voxel: float

    def __post_init__(self) -> None:
        t = np.asarray(self.tangent, np.float32)
        s = np.asarray(self.score, np.float32)
        if t.ndim != 4 or t.shape[-1] != 3 or len(set(t.shape[:3])) != 1 or s.shape != t.shape[:3]:
            raise ValueError(f"StrandField: tangent must be (L, L, L, 3) and score (L, L, L), got {t.shape}, {s.shape}")
        if not (np.all(np.isfinite(t)) and np.all((s >= 0) & (s <= 1))):
            raise ValueError("StrandField: tangents must be finite and scores in [0, 1]")
        object.__setattr__(self, "tangent", t)
        object.__setattr__(self, "score", s)
        object.__setattr__(self, "origin", np.asarray(self.origin, np.float64).reshape(3))
        object.__setattr__(self, "voxel", float(self.voxel))

    @property
    def resolution(self) -> int:
        return int(self.score.shape[0])



def image_orientation(rgb, mask) -> tuple[np.ndarray, np.ndarray]:
    """((H, W, 2) unit image direction (du, dv) along the strands, (H, W) coherence in [0, 1]) of one
    view's linear ``rgb`` (H, W, 3) inside ``mask`` (H, W) bool (0 outside, and near the silhouette); the
    coherence is scaled by the fine-detail energy ramp (:data:`ENERGY_LO`, :data:`ENERGY_HI`)."""
    from scipy import ndimage

    rgb = np.asarray(rgb, np.float64)
    m = np.asarray(mask, bool)
    lum = rgb @ np.array([0.2126, 0.7152, 0.0722])
    ref = float(np.median(lum[m])) if m.any() else 1.0
    y = np.log(np.maximum(lum, 0) + LOG_FLOOR * max(ref, 1e-12))
    y = np.where(m, y, float(np.mean(y[m])) if m.any() else 0.0)
    band = y - ndimage.gaussian_filter(y, BACKGROUND_SIGMA_PX)
    gx = ndimage.gaussian_filter(band, GRADIENT_SIGMA_PX, order=(0, 1))
    gy = ndimage.gaussian_filter(band, GRADIENT_SIGMA_PX, order=(1, 0))
    j11, j12, j22 = (ndimage.gaussian_filter(a, TENSOR_SIGMA_PX) for a in (gx * gx, gx * gy, gy * gy))
    tr = j11 + j22
    diff = np.sqrt((j11 - j22) ** 2 + 4 * j12 ** 2)
    coh = np.where(tr > 0, diff / np.where(tr > 0, tr, 1.0), 0.0)
    ang = 0.5 * np.arctan2(2 * j12, j11 - j22) + 0.5 * np.pi  # gradient direction turned by 90 degrees
    inner = ndimage.binary_erosion(m, iterations=SILHOUETTE_MARGIN_PX) if SILHOUETTE_MARGIN_PX else m
    coh = np.clip(coh, 0, 1) * _ramp(tr, ENERGY_LO, ENERGY_HI)
    return np.stack([np.cos(ang), np.sin(ang)], -1), np.where(inner, coh, 0.0)


def pixel_stride(cameras, stride: int | None) -> int:
    """``stride``, or for None one per :data:`STRIDE_WIDTH_PX` of the views' width (at least 1)."""
    if stride is not None:
        return max(1, int(stride))
    return max(1, round(cameras[0].width / STRIDE_WIDTH_PX)) if len(cameras) else 1


def plane_normals(camera, uv, t2) -> np.ndarray:
    """(P, 3) world unit normals of the planes through the camera centre that contain the image lines
    through pixels ``uv`` (P, 2) along image directions ``t2`` (P, 2)."""
    r = camera.pixel_rays(uv)
    Kinv = np.linalg.inv(camera.K)
    d = np.concatenate([t2, np.zeros((len(t2), 1))], 1) @ Kinv.T
    m = np.cross(r, d)
    m /= np.maximum(np.linalg.norm(m, axis=1, keepdims=True), 1e-300)
    return m @ camera.cam_from_world[:3, :3]  # R^T m as rows


def accumulate(rgb, depth, cameras, origin, voxel: float, res: int, alpha=None, stride: int | None = PIXEL_STRIDE):
    """(sums of c m m^T as (L^3, 6) xx xy xz yy yz zz, sums of c (L^3,), pixel counts (L^3,)) over every
    view (step 2 of the module doc); views: ``rgb`` (N, H, W, 3), ``depth`` (N, H, W), N cameras."""
    L = int(res)
    stride = pixel_stride(cameras, stride)
    tens = np.zeros((L ** 3, 6))
    csum = np.zeros(L ** 3)
    count = np.zeros(L ** 3)
    for i, cam in enumerate(cameras):
        dep = np.asarray(depth[i], np.float64)
        mask = dep > 0
        if alpha is not None:
            mask &= np.asarray(alpha[i]) > 0.5
        t2, coh = image_orientation(rgb[i], mask)
        sel = np.zeros_like(mask)
        sel[::stride, ::stride] = True
        sel &= mask
        if not sel.any():
            continue
        vv, uu = np.nonzero(sel)
        uv = np.stack([uu, vv], -1).astype(np.float64)
        x = cam.unproject(uv, dep[sel])
        ijk = np.floor((x - origin) / voxel).astype(np.int64)
        ok = np.all((ijk >= 0) & (ijk < L), axis=1)
        flat = (ijk[ok, 0] * L + ijk[ok, 1]) * L + ijk[ok, 2]
        m = plane_normals(cam, uv[ok], t2[sel][ok])
        c = coh[sel][ok]
        for col, (a, b) in enumerate(((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))):
            tens[:, col] += np.bincount(flat, c * m[:, a] * m[:, b], L ** 3)
        csum += np.bincount(flat, c, L ** 3)
        count += np.bincount(flat, None, L ** 3)
    return tens, csum, count


def _ramp(x, lo: float, hi: float):
    return np.clip((np.asarray(x) - lo) / (hi - lo), 0.0, 1.0)


def strand_field(rgb, depth, cameras, origin, voxel: float, res: int = STRAND_RES, alpha=None,
                 stride: int | None = PIXEL_STRIDE) -> StrandField:
    """The strand tangents and scores (module doc) on the cube ``origin`` + [0, res voxel)^3 from the
    capture views (``rgb`` (N, H, W, 3) linear, ``depth`` (N, H, W), N cameras, optional ``alpha``)."""
    from scipy import ndimage

    L = int(res)
    tens, csum, count = accumulate(rgb, depth, cameras, np.asarray(origin, np.float64), voxel, L, alpha, stride)
    if VOLUME_SMOOTH_VOXELS > 0:
        sm = lambda a: ndimage.gaussian_filter(a.reshape(L, L, L), VOLUME_SMOOTH_VOXELS, mode="constant").reshape(-1)
        tens = np.stack([sm(tens[:, c]) for c in range(6)], -1)
        csum, count = sm(csum), sm(count)
    M = np.empty((L ** 3, 3, 3))
    for col, (a, b) in enumerate(((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))):
        M[:, a, b] = M[:, b, a] = tens[:, col]
    ev, vec = np.linalg.eigh(M)  # ascending
    t = vec[:, :, 0]
    e0, e1 = np.maximum(ev[:, 0], 0), np.maximum(ev[:, 1], 0)
    agree = np.where(e1 > 0, 1.0 - e0 / np.where(e1 > 0, e1, 1.0), 0.0)
    mean_c = np.where(count > 0, csum / np.where(count > 0, count, 1.0), 0.0)
    score = _ramp(mean_c, COHERENCE_LO, COHERENCE_HI) * agree * np.clip(count / MIN_SAMPLES, 0, 1)
    return StrandField(t.reshape(L, L, L, 3), np.clip(score, 0, 1).reshape(L, L, L), origin, voxel)


#: Power-iteration steps that take the principal direction of an interpolated strand tensor (its
#: neighbours' s T T^T: exact in one step for a consistent field; the GLSL pass does the same).
POWER_STEPS = 3
#: Channel order of the tensor volume (xx, xy, xz, yy, yz, zz).
TENSOR_PAIRS = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))


def tensor_volume(field: StrandField) -> np.ndarray:
    """(L, L, L, 6) float32 s T T^T (:data:`TENSOR_PAIRS`): what is interpolated (sign-free, unlike T)."""
    t, s = field.tangent.astype(np.float64), field.score.astype(np.float64)
    return np.stack([s * t[..., a] * t[..., b] for a, b in TENSOR_PAIRS], -1).astype(np.float32)


def principal_direction(tensors) -> tuple[np.ndarray, np.ndarray]:
    """((P, 3) unit principal direction, (P,) its eigenvalue) of (P, 6) symmetric tensors by
    :data:`POWER_STEPS` power iterations from the column of the largest diagonal (twin of the GLSL)."""
    c = np.asarray(tensors, np.float64)
    M = np.empty((len(c), 3, 3))
    for col, (a, b) in enumerate(TENSOR_PAIRS):
        M[:, a, b] = M[:, b, a] = c[:, col]
    diag = np.stack([M[:, 0, 0], M[:, 1, 1], M[:, 2, 2]], -1)
    v = M[np.arange(len(c)), :, np.argmax(diag, 1)]
    for _ in range(POWER_STEPS):
        v = v / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-30)
        v = np.einsum("pab,pb->pa", M, v)
    lam = np.linalg.norm(v, axis=1)
    return v / np.maximum(lam, 1e-30)[:, None], lam


def field_sample(field: StrandField, points) -> tuple[np.ndarray, np.ndarray]:
    """((P, 3) tangent, (P,) score) at world points: trilinear lookup of :func:`tensor_volume` as GL's
    LINEAR 3-D texture (clamped to the edge texels), its principal direction and eigenvalue (the score,
    lowered where neighbours disagree)."""
    from render.relight.reference import volume_sample

    t, lam = principal_direction(volume_sample(tensor_volume(field), field.origin, field.voxel, points))
    return t, np.clip(lam, 0.0, 1.0)


#: Strand scores below this are not fitted (those pixels keep the surface transfer anyway).
FIT_MIN_SCORE = 0.05


@dataclass(frozen=True)
class StrandColour:
    """What the relighting knows of the strands: their field and, per voxel of the same cube, the fibre
    colour under the capture light from inverting the strand transfer (``render.shading.hair_transfer``).

    field: the StrandField, its score 0 where the colour fit had too few samples.
    fit: (L, L, L, 4) float32 (rho rgb, sigma): colour = rho D + sigma R (image units).
    """

    field: StrandField
    fit: np.ndarray

    def __post_init__(self) -> None:
        f = np.asarray(self.fit, np.float32)
        if f.shape != self.field.score.shape + (4,) or not np.all(np.isfinite(f)) or np.any(f < 0):
            raise ValueError(f"StrandColour: fit must be finite, >= 0, {self.field.score.shape + (4,)}; got {f.shape}")
        object.__setattr__(self, "fit", f)


def strand_colour(field: StrandField, rgb, depth, cameras, light_a, normals_at=None, alpha=None,
                  stride: int | None = PIXEL_STRIDE) -> StrandColour:
    """Fit rho, sigma per voxel (``render.shading.hair_transfer.fit_strand_colour``) from the capture views'
    pixels whose strand score is at least :data:`FIT_MIN_SCORE`, with D_A, R_A of the capture lighting
    ``light_a`` (``render.shading.transfer.RelightLighting``) at the pixel's tangent, shell normal
    (``normals_at``: (P, 3) points -> (P, 3) unit normals or 0; None: 0) and view; voxels with fewer than
    MIN_FIT_SAMPLES samples lose their strand score."""
    from render.shading.hair_transfer import MIN_FIT_SAMPLES, fit_strand_colour, hair_diffuse, hair_specular

    L = field.resolution
    stride = pixel_stride(cameras, stride)
    flats, cols, ds, rs = [], [], [], []
    for i, cam in enumerate(cameras):
        dep = np.asarray(depth[i], np.float64)
        sel = np.zeros(dep.shape, bool)
        sel[::stride, ::stride] = True
        sel &= dep > 0
        if alpha is not None:
            sel &= np.asarray(alpha[i]) > 0.5
        vv, uu = np.nonzero(sel)
        x = cam.unproject(np.stack([uu, vv], -1).astype(np.float64), dep[sel])
        ijk = np.floor((x - field.origin) / field.voxel).astype(np.int64)
        t, s = field_sample(field, x)
        ok = np.all((ijk >= 0) & (ijk < L), axis=1) & (s >= FIT_MIN_SCORE)
        if not ok.any():
            continue
        v = cam.center - x[ok]
        v /= np.linalg.norm(v, axis=1, keepdims=True)
        flats.append((ijk[ok, 0] * L + ijk[ok, 1]) * L + ijk[ok, 2])
        cols.append(np.asarray(rgb[i], np.float64)[sel][ok])
        n = np.zeros_like(v) if normals_at is None else normals_at(x[ok])
        ds.append(hair_diffuse(light_a, t[ok], n, v))
        rs.append(hair_specular(light_a, t[ok], n, v))
    if not flats:
        return StrandColour(StrandField(field.tangent, np.zeros_like(field.score), field.origin, field.voxel),
                            np.zeros(field.score.shape + (4,), np.float32))
    rho, sigma, cnt = fit_strand_colour(np.concatenate(flats), np.concatenate(cols), np.concatenate(ds),
                                        np.concatenate(rs), L ** 3)
    good = (cnt >= MIN_FIT_SAMPLES) & (rho.sum(1) > 0)
    score = np.where(good.reshape(L, L, L), field.score, 0.0)
    fit = np.concatenate([rho, sigma[:, None]], -1) * good[:, None]
    return StrandColour(StrandField(field.tangent, score, field.origin, field.voxel),
                        fit.reshape(L, L, L, 4).astype(np.float32))

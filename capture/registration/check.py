"""An independent check of every placed view (issues 22, 31): does its pose explain the data
better than its input pose, by evidence that did not place it?

For an ordered pair (view i, neighbour j) at candidate poses, j's range samples are carried into
view i through the relative pose and compared with what view i measured at the pixel they land on:

* **depth**: the sample agrees when it lands within ``AGREE_SIGMAS`` depth-noise sigmas of view
  i's depth (the noise measured on the range images, ``projective.depth_frame``, floored at
  ``SIGMA_FLOOR_FRAC`` of the object size); it disagrees when it lands in front of view i's
  surface (free space view i saw through), behind it by less than ``OCCLUDED_FRAC`` of the object
  size, or on view i's background (outside its silhouette); further behind it is occluded and
  does not count;
* **colour distribution**: the blurred luminance of the co-visible samples against view i's
  blurred luminance where they land (blurred by ``COLOUR_BLUR_PX``: single strands do not repeat
  between views, the coat's pattern does), as a normalised cross-correlation.

A view's score (``view_score``) is the mean over its neighbours of ``agreement + COLOUR_WEIGHT *
ncc``.  To compare two poses of one view against the same neighbours (``verify``), the same
evidence is summed per image tile of the source view (``tile_scores``: +1 per agreeing sample,
-1 per disagreeing one, plus ``COLOUR_WEIGHT`` times the product of the two luminances
standardised per view), so that the difference of the two poses is a sample per tile and its
paired t (``angles.paired_t``) says whether one is better beyond the capture's own noise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from capture.camera import invert_rigid
from capture.registration import evidence as EV
from capture.registration import points as P
from capture.registration import projective as PR
from capture.sampling import nearest_pixel
from capture.scan import Scan

#: A reprojected sample agrees with view i when within this many depth-noise sigmas of its depth.
AGREE_SIGMAS = 3.0
#: The depth-noise sigma is at least this fraction of the object size (exact synthetic depth).
SIGMA_FLOOR_FRAC = 1e-3
#: A sample this far (fraction of object size) behind view i's surface is occluded there.
OCCLUDED_FRAC = 0.05
#: Luminance blur (pixels at 640 across) before the colour correlation.
COLOUR_BLUR_PX = 2.0
#: Weight of the colour correlation in the score.
COLOUR_WEIGHT = 0.5
#: Range samples per view (fur: 4000 left 5 of 24 views at their true poses off the peak by noise).
SAMPLES = 12000
#: Neighbours (nearest by viewing direction) a view is checked against.
NEIGHBOURS = 4
#: Neighbours further apart than this (degrees between the viewing directions) are not used.
MAX_NEIGHBOUR_DEG = 60.0
#: Fewer co-visible samples than this over all neighbours: nothing to judge by.
MIN_COVISIBLE = 200
#: Image tile (pixels at 640 across) of the paired comparison: one score-difference sample per tile.
TILE_PX = 40


@dataclass(frozen=True)
class CheckView:
    """One view's inputs to the check (camera frame, metres).

    Attributes:
        points: (N, 3) range samples.
        lum: (N,) blurred luminance at the samples.
        depth: (H, W) depth, 0 where not measured.
        lum_img: (H, W) blurred luminance.
        mask: (H, W) bool silhouette (object against the background).
        sigma_m: depth-noise sigma (metres) at the median depth.
        K: (3, 3) intrinsics.
        tiles: (N,) the image tile of every sample (``TILE_PX``); ``n_tiles`` of them.
        lum_mean, lum_std: the blurred luminance's mean and standard deviation over the silhouette.
    """

    points: np.ndarray
    lum: np.ndarray
    depth: np.ndarray
    lum_img: np.ndarray
    mask: np.ndarray
    sigma_m: float
    K: np.ndarray
    tiles: np.ndarray | None = None
    n_tiles: int = 1
    lum_mean: float = 0.0
    lum_std: float = 1.0

    def __post_init__(self) -> None:
        if self.points.ndim != 2 or self.points.shape[1] != 3 or len(self.lum) != len(self.points):
            raise ValueError(f"CheckView: points must be (N, 3) with N luminances, got {self.points.shape}")


def prepare(scan: Scan, samples: int = SAMPLES) -> CheckView:
    """The check's inputs of ``scan`` (its pose is not used)."""
    from scipy.ndimage import gaussian_filter

    frame = PR.depth_frame(scan, P.CloudConfig())
    rgb = scan.linear_rgb
    lum = gaussian_filter(rgb.mean(axis=-1).astype(np.float64), COLOUR_BLUR_PX * scan.camera.width / 640)
    iy, ix = np.nonzero(frame.valid)
    if len(iy) > samples:
        keep = np.linspace(0, len(iy) - 1, samples).astype(np.int64)
        iy, ix = iy[keep], ix[keep]
    depth = np.where(np.asarray(scan.depth) > 0, np.asarray(scan.depth, np.float64), 0.0)
    mask = EV.silhouette_mask(scan)
    t = max(4, int(round(TILE_PX * scan.camera.width / 640)))
    nx = -(-scan.camera.width // t)
    tiles = (iy // t) * nx + ix // t
    inside = lum[mask] if mask.any() else lum.ravel()
    return CheckView(frame.points[iy, ix], lum[iy, ix], depth, lum, mask, frame.depth_sigma_m, scan.camera.K,
                     tiles.astype(np.int64), nx * -(-scan.camera.height // t), float(inside.mean()),
                     max(float(inside.std()), 1e-6))


@dataclass(frozen=True)
class PairScore:
    """Agreement of a source view's samples in a target view."""

    agree: int
    disagree: int
    ncc: float

    @property
    def counted(self) -> int:
        return self.agree + self.disagree

    @property
    def agreement(self) -> float:
        return self.agree / self.counted if self.counted else 0.0


def _land(src: CheckView, tgt: CheckView, T: np.ndarray, size: float):
    """Where ``src``'s samples land in ``tgt`` under ``T``: (indices of the samples inside the
    image, their pixels (iv, iu), agreeing flags, counted flags)."""
    q = src.points @ T[:3, :3].T + T[:3, 3]
    z = q[:, 2]
    front = z > 1e-6
    K = tgt.K
    u = np.full(len(q), -1.0)
    v = np.full(len(q), -1.0)
    u[front] = K[0, 0] * q[front, 0] / z[front] + K[0, 1] * q[front, 1] / z[front] + K[0, 2]
    v[front] = K[1, 1] * q[front, 1] / z[front] + K[1, 2]
    H, W = tgt.depth.shape
    iu, iv = nearest_pixel(u), nearest_pixel(v)
    inside = front & (iu >= 0) & (iu < W) & (iv >= 0) & (iv < H)
    idx = np.nonzero(inside)[0]
    iu, iv, zq = iu[inside], iv[inside], z[inside]
    zt = tgt.depth[iv, iu]
    bg = ~tgt.mask[iv, iu]
    d = zq - zt
    sigma = max(tgt.sigma_m, src.sigma_m, SIGMA_FLOOR_FRAC * size)
    meas = zt > 0
    ok = meas & (np.abs(d) <= AGREE_SIGMAS * sigma)
    counted = (meas & (d <= OCCLUDED_FRAC * size)) | (bg & ~meas)
    return idx, (iv, iu), ok, counted


def pair_score(src: CheckView, tgt: CheckView, T: np.ndarray, size: float) -> PairScore:
    """``src``'s samples carried into ``tgt`` by ``T`` (tgt_cam_from_src_cam)."""
    idx, (iv, iu), ok, counted = _land(src, tgt, T, size)
    lum = src.lum[idx]
    agree = int(ok.sum())
    ncc = _ncc(lum[ok], tgt.lum_img[iv[ok], iu[ok]])
    return PairScore(agree, int(counted.sum()) - agree, ncc)


def _ncc(a: np.ndarray, b: np.ndarray) -> float:
    if len(a) < 3:
        return 0.0
    a = a - a.mean()
    b = b - b.mean()
    den = math.sqrt(float(a @ a) * float(b @ b))
    return float(a @ b) / den if den > 0 else 0.0


def neighbours(poses: list[np.ndarray], centre: np.ndarray, k: int = NEIGHBOURS,
               max_deg: float = MAX_NEIGHBOUR_DEG) -> list[list[int]]:
    """Per view: the ``k`` views whose viewing directions (camera centre to ``centre``) are nearest."""
    d = []
    for p in poses:
        c = -p[:3, :3].T @ p[:3, 3]
        d.append((c - centre) / max(np.linalg.norm(c - centre), 1e-12))
    D = np.degrees(np.arccos(np.clip(np.array(d) @ np.array(d).T, -1, 1)))
    out = []
    for i in range(len(poses)):
        order = [j for j in np.argsort(D[i]) if j != i and D[i, j] <= max_deg]
        out.append([int(j) for j in order[:k]])
    return out


def view_score(views: list[CheckView], i: int, pose_i: np.ndarray, poses: list, nbrs: list[int],
               size: float) -> tuple[float, int]:
    """(score, co-visible samples) of view i at ``pose_i`` against ``nbrs`` at ``poses``
    (cam_from_world), both directions of each pair."""
    s, n, m = 0.0, 0, 0
    for j in nbrs:
        Tij = pose_i @ invert_rigid(poses[j])
        for a, b, T in ((views[j], views[i], Tij), (views[i], views[j], invert_rigid(Tij))):
            ps = pair_score(a, b, T, size)
            s += ps.agreement + COLOUR_WEIGHT * ps.ncc
            n += 1
            m += ps.agree
    return (s / n if n else 0.0), m


def tile_scores(src: CheckView, tgt: CheckView, T: np.ndarray, size: float) -> np.ndarray:
    """(src.n_tiles,) per image tile of ``src``: agreeing minus disagreeing samples in ``tgt``
    under ``T``, plus ``COLOUR_WEIGHT`` times the product of the standardised luminances of the
    agreeing ones (the module docstring)."""
    idx, (iv, iu), ok, counted = _land(src, tgt, T, size)
    val = np.where(ok, 1.0, np.where(counted, -1.0, 0.0))
    za = (src.lum[idx] - src.lum_mean) / src.lum_std
    zb = (tgt.lum_img[iv, iu] - tgt.lum_mean) / tgt.lum_std
    val = val + np.where(ok, COLOUR_WEIGHT * np.clip(za * zb, -4.0, 4.0), 0.0)
    return np.bincount(src.tiles[idx], weights=val, minlength=src.n_tiles)


def view_tiles(views: list[CheckView], i: int, pose_i: np.ndarray, poses: list, nbrs: list[int],
               size: float) -> np.ndarray:
    """View i at ``pose_i`` against ``nbrs`` at ``poses``: the tile scores of both directions of
    every pair, concatenated (the same tiles for any ``pose_i``: a paired sample)."""
    out = []
    for j in nbrs:
        Tij = pose_i @ invert_rigid(poses[j])
        out.append(tile_scores(views[j], views[i], Tij, size))
        out.append(tile_scores(views[i], views[j], invert_rigid(Tij), size))
    return np.concatenate(out) if out else np.zeros(0)

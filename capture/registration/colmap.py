"""Photometric registration: pycolmap SfM on the colour images, then a similarity (Umeyama) into
the depth frame (issue 4 item 2).

1. the colour images are written as 8-bit PNG to a temporary folder; intrinsics are known
   (PINHOLE, COLMAP pixel centres at i + 0.5, i.e. ``cx_colmap = cx_opencv + 0.5``) and fixed
   during bundle adjustment;
2. CPU SIFT, exhaustive matching for small sets (a turntable ring closes on itself) or
   sequential matching with loop detection off, incremental mapping; the largest model wins;
3. every SfM point observed in image k at a pixel with a depth measurement gives a
   correspondence: the SfM point X (SfM frame) and the range point of image k mapped to the
   world by the reference pose of scan k (the input poses) ``Y``; Umeyama (with trimming of
   the worst residuals) gives Y ~ s R X + t;
4. the poses are re-anchored so that the first registered scan keeps its reference pose
   (the gauge), exactly as the geometric method does.

The scale ``s`` is also estimated independently of any pose, as the median ratio of measured
depth to SfM depth over all observations (``depth_ratio_scale``); the two are reported.
"""

from __future__ import annotations

import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from capture.camera import invert_rigid
from capture.scan import ScanSet

#: Up to this many images: exhaustive matching; above: sequential with this overlap.
EXHAUSTIVE_MAX_IMAGES = 60
SEQUENTIAL_OVERLAP = 8
#: Umeyama trimming: correspondences with residual above this multiple of the median are dropped.
TRIM_MEDIANS = 3.0
#: Maximum |depth - SfM depth * s| / depth for a correspondence used in the scale estimate.
SCALE_OUTLIER_FRAC = 0.05
#: SIFT features are extracted inside the range mask dilated by this many pixels.
MASK_DILATE_PX = 3


@dataclass
class SfmResult:
    """SfM poses mapped into the depth frame."""

    poses: list  # cam_from_world (4, 4) per scan, None where SfM did not register the image
    scale: float  # Umeyama scale (metres per SfM unit)
    depth_ratio_scale: float  # pose-free scale from depth ratios
    reprojection_px: float  # mean reprojection error of the model
    n_points: int
    n_correspondences: int
    seconds: float


def umeyama(X: np.ndarray, Y: np.ndarray, with_scale: bool = True) -> tuple[float, np.ndarray, np.ndarray]:
    """Least-squares similarity Y ~ s R X + t (Umeyama 1991).  X, Y: (N, 3).  Returns (s, R, t)."""
    X = np.asarray(X, dtype=np.float64)
    Y = np.asarray(Y, dtype=np.float64)
    mx, my = X.mean(0), Y.mean(0)
    Xc, Yc = X - mx, Y - my
    C = Yc.T @ Xc / len(X)
    U, D, Vt = np.linalg.svd(C)
    S = np.eye(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:
        S[2, 2] = -1
    R = U @ S @ Vt
    var_x = (Xc**2).sum() / len(X)
    s = float(np.trace(np.diag(D) @ S) / var_x) if with_scale else 1.0
    t = my - s * R @ mx
    return s, R, t


def robust_umeyama(X: np.ndarray, Y: np.ndarray, rounds: int = 3) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
    """Umeyama with trimming (``TRIM_MEDIANS``); returns (s, R, t, inlier mask)."""
    keep = np.ones(len(X), dtype=bool)
    s, R, t = umeyama(X, Y)
    for _ in range(rounds):
        r = np.linalg.norm(Y - (s * X @ R.T + t), axis=1)
        keep = r <= TRIM_MEDIANS * max(np.median(r), 1e-12)
        if keep.sum() < 3:
            break
        s, R, t = umeyama(X[keep], Y[keep])
    return s, R, t, keep


def _dilate(mask: np.ndarray, r: int) -> np.ndarray:
    from scipy.ndimage import binary_dilation

    return binary_dilation(mask, iterations=r) if r > 0 else mask


def _run_sfm(scanset: ScanSet, work: Path, seed: int):
    import pycolmap

    from capture.imageio import write_png

    img_dir = work / "images"
    mask_dir = work / "masks"
    img_dir.mkdir(parents=True, exist_ok=True)
    mask_dir.mkdir(parents=True, exist_ok=True)
    names = []
    for k, s in enumerate(scanset.scans):
        nm = f"{k:04d}.png"
        write_png(img_dir / nm, s.srgb8)
        # features only where the range scanner saw the object (the background of a turntable
        # capture does not move with the object), dilated to keep silhouette features
        m = _dilate(s.depth > 0, MASK_DILATE_PX)
        write_png(mask_dir / f"{nm}.png", (m * 255).astype(np.uint8))
        names.append(nm)
    cams = scanset.cameras
    K0 = cams[0].K
    shared = all(np.allclose(c.K, K0) and (c.width, c.height) == (cams[0].width, cams[0].height) for c in cams)
    if not shared:
        raise ValueError("SfM registration needs one shared intrinsic matrix for all images")
    reader = pycolmap.ImageReaderOptions()
    reader.camera_model = "PINHOLE"
    reader.mask_path = str(mask_dir)
    reader.camera_params = ",".join(str(v) for v in (K0[0, 0], K0[1, 1], K0[0, 2] + 0.5, K0[1, 2] + 0.5))
    ext = pycolmap.FeatureExtractionOptions()
    ext.use_gpu = False
    ext.num_threads = 2
    db = work / "database.db"
    pycolmap.extract_features(db, img_dir, image_names=names, camera_mode=pycolmap.CameraMode.SINGLE,
                              reader_options=reader, extraction_options=ext, device=pycolmap.Device.cpu)
    mo = pycolmap.FeatureMatchingOptions()
    mo.use_gpu = False
    mo.num_threads = 2
    if len(names) <= EXHAUSTIVE_MAX_IMAGES:
        pycolmap.match_exhaustive(db, matching_options=mo, device=pycolmap.Device.cpu)
    else:
        po = pycolmap.SequentialPairingOptions()
        po.overlap = SEQUENTIAL_OVERLAP
        pycolmap.match_sequential(db, matching_options=mo, pairing_options=po, device=pycolmap.Device.cpu)
    opts = pycolmap.IncrementalPipelineOptions()
    opts.ba_refine_focal_length = False
    opts.ba_refine_principal_point = False
    opts.ba_refine_extra_params = False
    opts.num_threads = 2
    opts.random_seed = seed
    models = pycolmap.incremental_mapping(db, img_dir, work / "sparse", opts)
    if not models:
        raise RuntimeError("pycolmap SfM registered no model (too few matched features)")
    rec = max(models.values(), key=lambda r: r.num_reg_images())
    return rec, names


def sfm_poses(scanset: ScanSet, reference_poses: list[np.ndarray] | None = None, use_init_for_gauge: bool = True,
              seed: int = 0, workdir: Path | None = None) -> SfmResult:
    """SfM poses of every scan in the depth (world) frame; see the module docstring.

    Args:
        reference_poses: cam_from_world used to place the range points (default: the input cameras).
        use_init_for_gauge: re-anchor so the first registered scan keeps its reference pose.
    """
    t0 = time.perf_counter()
    ref = reference_poses or [s.camera.cam_from_world for s in scanset.scans]
    with tempfile.TemporaryDirectory(prefix="furrow-sfm-", dir=workdir) as tmp:
        rec, names = _run_sfm(scanset, Path(tmp), seed)
        sfm = {}
        for img in rec.images.values():
            if not img.has_pose:
                continue
            k = names.index(img.name)
            sfm[k] = (img, np.vstack([img.cam_from_world().matrix(), [0, 0, 0, 1]]))
        X, Y, ratios = [], [], []
        for k, (img, P) in sfm.items():
            scan = scanset.scans[k]
            cam = scan.camera
            wfc = invert_rigid(np.asarray(ref[k], dtype=np.float64))
            for p2 in img.points2D:
                if not p2.has_point3D():
                    continue
                u, v = p2.xy[0] - 0.5, p2.xy[1] - 0.5  # COLMAP centres at i + 0.5 -> OpenCV
                iu, iv = int(round(u)), int(round(v))
                if not (0 <= iu < cam.width and 0 <= iv < cam.height):
                    continue
                d = float(scan.depth[iv, iu])
                if d <= 0:
                    continue
                Xw = rec.points3D[p2.point3D_id].xyz
                xc = P[:3, :3] @ Xw + P[:3, 3]
                if xc[2] <= 0:
                    continue
                pc = cam.pixel_rays(np.array([u, v])) * d
                ratios.append(d / xc[2])
                X.append(Xw)
                Y.append(wfc[:3, :3] @ pc + wfc[:3, 3])
        if len(X) < 10:
            raise RuntimeError(f"SfM: only {len(X)} SfM points have a depth measurement; cannot place the model")
        X, Y, ratios = np.array(X), np.array(Y), np.array(ratios)
        s, Rm, t, keep = robust_umeyama(X, Y)
        poses: list = [None] * len(scanset.scans)
        for k, (_, P) in sfm.items():
            out = np.eye(4)
            out[:3, :3] = P[:3, :3] @ Rm.T
            out[:3, 3] = s * P[:3, 3] - out[:3, :3] @ t
            poses[k] = out
        if use_init_for_gauge:
            g = min(sfm)
            fix = invert_rigid(poses[g]) @ np.asarray(ref[g], dtype=np.float64)
            poses = [p @ fix if p is not None else None for p in poses]
        med = float(np.median(ratios))
        return SfmResult(poses, s, med, float(rec.compute_mean_reprojection_error()), rec.num_points3D(),
                         int(keep.sum()), time.perf_counter() - t0)

"""Geometric registration of range scans with Open3D (docs/design.md "capture/", issue 4).

Pipeline (multiway registration):

1. every scan -> camera-frame cloud (``points.py``) -> voxel pyramid (coarse -> fine, sizes
   relative to the object size) with normals;
2. pairs: scans whose nominal optical axes are within ``pair_max_angle_deg`` (or, without
   poses, ring neighbours k+1, k+2 including the wrap-around loop closure);
3. pairwise coarse-to-fine point-to-plane ICP (Open3D, Tukey robust kernel; coloured ICP at
   the finest level when ``colored``) from the nominal relative pose, then projective
   point-to-plane ICP on the range images (``projective.py``: exact association, no boundary
   bias); a pair that fails the thresholds of ``report.py`` is retried from FPFH + RANSAC;
4. a pose graph (``posegraph.py``; odometry edges certain, the others uncertain loop closures) optimised by
   Levenberg-Marquardt with line-process pruning; edges that still disagree with the optimum
   are removed and the graph re-optimised; then a refinement round re-runs fine ICP from the
   optimised poses;
5. scans not connected to the gauge scan by accepted, consistent edges are flagged.

Poses: ``cam_from_world`` (OpenCV).  A pair transform ``T_ij`` maps camera-j points into camera
i (``cam_i_from_cam_j``); graph node k holds ``world_from_cam_k``.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace

import numpy as np

from capture.camera import invert_rigid
from capture.registration import points as P
from capture.registration import posegraph as PG
from capture.registration import projective as PR
from capture.registration import report as R
from capture.scan import ScanSet

#: The colour term's scale (metres per chromaticity unit) is at least the measured depth noise
#: divided by this: with noisier depth the geometry pulls harder on the pose and the colour
#: must keep up, else symmetric shapes slide.  Measured on the glossy synthetic torus at 640x480
#: (pairs 20 degrees apart, fine stage from 0.5 degrees off): with millimetre depth and z^2
#: noise the fixed scale 0.006 x size (chosen on noise-free depth) gave 0.21 median / 0.62 max
#: pair error, 0.012 x size (= 0.28 mm measured noise / 0.064) 0.068 / 0.17, 0.024 x size
#: 0.087 / 0.29; on noise-free depth 0.006 and 0.012 give 0.070 and 0.063.
COLOR_CHROMA_SIGMA = 0.064
#: Auto projective stride of the first stages: source images are sampled about this many pixels across.
AUTO_STRIDE_WIDTH = 200
#: Auto projective stride of the last stage: about this many source samples (at most every
#: pixel).  Measured on the synthetic plant at 640x480 with millimetre depth (pairs 20 and 60
#: degrees apart, fine stage from 0.5 degrees off): every third pixel (about 2,500 samples)
#: 0.127 median / 0.78 max pair error, every second 0.137 / 0.45, every pixel (22,000)
#: 0.096 / 0.24; on exact depth 0.063 -> 0.033.  The noise averages over the samples.
FINE_SAMPLES = 30000


@dataclass(frozen=True)
class IcpConfig:
    """Knobs of the geometric registration."""

    voxel_fracs: tuple[float, ...] = (1 / 25, 1 / 50, 1 / 100)
    """Voxel sizes of the Open3D coarse-to-fine pyramid as fractions of the object size (bounds diagonal)."""
    corr_voxels: float = 2.0
    """Maximum correspondence distance, in voxels of the current level."""
    first_corr_voxels: float = 5.0
    """Correspondence distance at the coarsest level, in its voxels (captures the initial error)."""
    iterations: tuple[int, ...] = (40, 30, 30)
    """ICP iterations per level (the last entry repeats for extra levels)."""
    colored: bool = False
    """Use coloured ICP (Park et al. 2017) at the finest Open3D level (helps on textured fur/leaves)."""
    projective_gates: tuple[float, ...] = (1 / 50, 1 / 150)
    """Depth gates (fractions of object size) of the successive projective ICP stages; () = off."""
    projective_iterations: int = 30
    """Gauss-Newton iterations per projective stage."""
    projective_stride: int = 0
    """Source pixel stride of the projective stages (0 = auto: about 200 samples across the width)."""
    fine_candidates: int = 2
    """How many of the ranked coarse results are fine-aligned per pair."""
    color_scale_frac: float = 0.006
    """Photometric term of the projective stage: metres per unit chromaticity difference, as a
    fraction of object size (0 = geometry only), on noise-free depth; on noisy depth the scale
    grows with the measured depth noise (``color_chroma_sigma``).  Needed on symmetric shapes
    (the torus)."""
    color_chroma_sigma: float = COLOR_CHROMA_SIGMA
    """Chromaticity difference that weighs as much as one sigma of measured depth noise
    (:func:`color_scale`)."""
    robust: bool = True
    point_to_point_first: bool = True
    """Point-to-point ICP at the coarsest level (wider basin of convergence than point-to-plane)."""
    """Tukey robust kernel (scale = correspondence distance) in point-to-plane ICP."""
    pair_max_angle_deg: float = 65.0
    """With nominal poses: register pairs whose optical axes differ by less than this."""
    ring_neighbours: int = 2
    """Without nominal poses: pair scan k with k+1 .. k+ring_neighbours (cyclically)."""
    global_fallback: bool = True
    """Retry failed pairs with FPFH + RANSAC global registration."""
    global_voxel_frac: float = 1 / 40
    """Voxel size for FPFH features (fraction of object size)."""
    refine_rounds: int = 1
    """Extra rounds of fine ICP from the optimised poses followed by re-optimisation."""
    cloud: P.CloudConfig = field(default_factory=P.CloudConfig)
    """Depth -> cloud conversion."""
    seed: int = 0
    """Seed of Open3D's RANSAC."""
    correction_bound: tuple[float, float] | None = None
    """Largest correction of a pair's relative pose from its initial guess: (degrees, fraction of
    the object size); None = ``report.MAX_CORRECTION_DEG`` / ``MAX_CORRECTION_FRAC``.  The
    pipeline sets it from the input's stated uncertainty (``prior.PosePrior``: both views of a
    pair may be wrong by the bound)."""


@dataclass(frozen=True)
class PairResult:
    """Result of one pair registration (target i, source j); updated with ``dataclasses.replace``."""

    i: int
    j: int
    T: np.ndarray  # cam_i_from_cam_j
    fitness: float
    rmse: float
    information: np.ndarray
    method: str
    status: str
    correction_deg: float = float("nan")
    color_rmse: float = float("nan")


def _levels(cfg: IcpConfig, size: float) -> tuple[float, ...]:
    return tuple(f * size for f in cfg.voxel_fracs)


def _iters(cfg: IcpConfig, k: int) -> int:
    return cfg.iterations[min(k, len(cfg.iterations) - 1)]


def icp_refine(src_levels, tgt_levels, init: np.ndarray, voxels, cfg: IcpConfig, start: int = 0) -> np.ndarray:
    """Coarse-to-fine ICP from ``init`` over pyramid levels ``start``.. (target <- source)."""
    import open3d as o3d

    reg = o3d.pipelines.registration
    T = np.asarray(init, dtype=np.float64).copy()
    n = len(voxels)
    for k in range(start, n):
        v = voxels[k]
        dist = (cfg.first_corr_voxels if k == start else cfg.corr_voxels) * v
        crit = reg.ICPConvergenceCriteria(relative_fitness=1e-7, relative_rmse=1e-7, max_iteration=_iters(cfg, k))
        s, t = src_levels[k], tgt_levels[k]
        if cfg.colored and k == n - 1 and s.has_colors() and t.has_colors():
            try:
                res = reg.registration_colored_icp(s, t, dist, T, reg.TransformationEstimationForColoredICP(), crit)
                T = res.transformation
                continue
            except RuntimeError:  # too few correspondences for the colour term: fall back to geometry
                pass
        if cfg.point_to_point_first and k == start:
            est = reg.TransformationEstimationPointToPoint()
        elif cfg.robust:
            est = reg.TransformationEstimationPointToPlane(reg.TukeyLoss(k=dist))
        else:
            est = reg.TransformationEstimationPointToPlane()
        res = reg.registration_icp(s, t, dist, T, est, crit)
        T = res.transformation
    return np.asarray(T)


def global_init(src, tgt, voxel: float, seed: int = 0) -> np.ndarray:
    """FPFH + RANSAC global registration of two clouds (already downsampled to ``voxel``)."""
    import open3d as o3d

    reg = o3d.pipelines.registration
    o3d.utility.random.seed(seed)
    feats = []
    for c in (src, tgt):
        feats.append(reg.compute_fpfh_feature(c, o3d.geometry.KDTreeSearchParamHybrid(radius=5 * voxel, max_nn=100)))
    dist = 1.5 * voxel
    # Open3D warns on every pair whose mutual filter leaves few matches and then falls back to all
    # matches (as wanted here); the pair's fitness is judged by classify(), not by that warning
    with o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error):
        res = reg.registration_ransac_based_on_feature_matching(
            src, tgt, feats[0], feats[1], True, dist, reg.TransformationEstimationPointToPoint(False), 3,
            [reg.CorrespondenceCheckerBasedOnEdgeLength(0.9), reg.CorrespondenceCheckerBasedOnDistance(dist)],
            reg.RANSACConvergenceCriteria(100000, 0.999))
    return np.asarray(res.transformation)


def classify(fitness: float, rmse: float, correction: tuple[float, float] | None, size: float,
             color_rmse: float = float("nan"), bound: tuple[float, float] | None = None) -> str:
    """Status of a pair result against the thresholds of ``report.py`` (``color_rmse`` is
    checked when finite, i.e. when the colour term is on); ``bound`` replaces the correction limits
    (``IcpConfig.correction_bound``)."""
    max_deg, max_frac = bound or (R.MAX_CORRECTION_DEG, R.MAX_CORRECTION_FRAC)
    if correction is not None and (correction[0] > max_deg or correction[1] > max_frac * size):
        return "diverged"
    if fitness < R.MIN_FITNESS:
        return "low_fitness"
    if not math.isfinite(rmse) or rmse > R.MAX_RMSE_FRAC * size:
        return "high_rmse"
    if math.isfinite(color_rmse) and color_rmse > R.MAX_COLOR_RMSE:
        return "color_mismatch"
    return "ok"


def color_scale(cfg: IcpConfig, size: float, *frames: PR.DepthFrame) -> float:
    """Metres per chromaticity unit of the photometric term (0 = off): ``color_scale_frac`` x
    size, or more where the frames' measured depth noise is larger (``COLOR_CHROMA_SIGMA``)."""
    if cfg.color_scale_frac <= 0:
        return 0.0
    noise = max(f.depth_sigma_m for f in frames)
    return max(cfg.color_scale_frac * size, noise / cfg.color_chroma_sigma)


def projective_strides(cfg: IcpConfig, frame: PR.DepthFrame) -> tuple[int, int]:
    """(stride of the first projective stages, stride of the last) for a source frame."""
    if cfg.projective_stride:
        return cfg.projective_stride, cfg.projective_stride
    coarse = max(1, frame.valid.shape[1] // AUTO_STRIDE_WIDTH)
    fine = max(1, round(math.sqrt(frame.valid.sum() / FINE_SAMPLES)))
    return coarse, min(coarse, fine)


def fine_align(frame_i: PR.DepthFrame, frame_j: PR.DepthFrame, T: np.ndarray, cfg: IcpConfig,
               size: float) -> tuple[np.ndarray, float, float, np.ndarray, float]:
    """Projective ICP stages (gates from ``cfg.projective_gates``):
    (T, fitness, rmse, 6x6 information, colour RMSE) at the last gate."""
    gates = cfg.projective_gates or (1 / 150,)
    coarse, fine = projective_strides(cfg, frame_j)
    cs = color_scale(cfg, size, frame_i, frame_j)
    res = None
    for k, g in enumerate(cfg.projective_gates):
        res = PR.projective_icp(frame_j, frame_i, T, g * size, cfg.projective_iterations,
                                stride=fine if k == len(gates) - 1 else coarse, color_scale=cs)
        T = res.T
    if res is None:  # evaluation only
        res = PR.projective_icp(frame_j, frame_i, T, gates[-1] * size, 0, stride=fine, color_scale=cs)
    crmse = res.color_rmse if cfg.color_scale_frac > 0 else float("nan")
    return T, res.fitness, res.rmse, res.information, crmse


@dataclass
class ScanData:
    """Per-scan registration inputs: Open3D pyramid (coarse -> fine) and projective range frame."""

    pyramid: list
    frame: PR.DepthFrame


def prepare(scan, voxels, cfg: IcpConfig) -> ScanData:
    """The one shared conversion of a scan for registration."""
    return ScanData(P.cloud_pyramid(P.scan_cloud(scan, cfg.cloud), voxels), PR.depth_frame(scan, cfg.cloud))


def register_pair(di: ScanData, dj: ScanData, init: np.ndarray | None, voxels, cfg: IcpConfig, size: float,
                  center_j: np.ndarray, i: int = 0, j: int = 0) -> PairResult:
    """Register scan j (source) onto scan i (target): ICP from ``init`` then, if it fails and
    ``cfg.global_fallback`` (or there is no ``init``), ICP from FPFH + RANSAC.
    ``center_j``: object centre in camera j (for the translation part of the correction)."""
    tried = []
    if init is not None:
        # multi-start: the coarse levels widen the basin but can slide a good start away on
        # partial overlap; each start level is tried and the best accepted result is kept.
        # Starts (each coarse level, and the initial pose itself) are ranked by projective
        # fitness at the widest gate (no iterations: cheap); the best ``fine_candidates`` are
        # fine-aligned.  Among accepted results the lowest colour residual wins when the colour
        # term is on (on a symmetric shape slid solutions fit the geometry equally well), else
        # the highest fitness.
        gate0 = (cfg.projective_gates or (1 / 150,))[0] * size
        cands = []
        for start in range(len(voxels) + 1):
            T = init if start == len(voxels) else icp_refine(dj.pyramid, di.pyramid, init, voxels, cfg, start=start)
            cands.append((PR.projective_icp(dj.frame, di.frame, T, gate0, 0).fitness, start, T))
        cands.sort(key=lambda c: -c[0])
        results = []
        for _, _start, T in cands[: cfg.fine_candidates]:
            T, fit, rmse, info, crmse = fine_align(di.frame, dj.frame, T, cfg, size)
            corr = R.transform_delta(T, init, center_j)
            status = classify(fit, rmse, corr, size, crmse, cfg.correction_bound)
            results.append(PairResult(i, j, T, fit, rmse, info, "icp", status, corr[0], crmse))
        ok = [r for r in results if r.status == "ok"]
        if ok and cfg.color_scale_frac > 0 and all(math.isfinite(r.color_rmse) for r in ok):
            best = min(ok, key=lambda r: r.color_rmse)
        else:
            best = max(ok or results, key=lambda r: r.fitness)
        tried.append(best)
        if best.status == "ok":
            return best
    if cfg.global_fallback or init is None:
        gv = cfg.global_voxel_frac * size
        T0 = global_init(P.downsample(dj.pyramid[0], gv), P.downsample(di.pyramid[0], gv), gv, cfg.seed)
        T = icp_refine(dj.pyramid, di.pyramid, T0, voxels, cfg)
        T, fit, rmse, info, crmse = fine_align(di.frame, dj.frame, T, cfg, size)
        # with an initial guess, the global result must still agree with it within the
        # correction limits (a symmetric object offers many perfect-fitting global solutions)
        corr = R.transform_delta(T, init, center_j) if init is not None else None
        st = classify(fit, rmse, corr, size, crmse, cfg.correction_bound)
        tried.append(PairResult(i, j, T, fit, rmse, info, "fpfh+icp", st, corr[0] if corr else float("nan"), crmse))
        if st == "ok":
            return tried[-1]
    # none accepted: report the best attempt with its failure status
    return max(tried, key=lambda r: r.fitness)


def choose_pairs(poses: list[np.ndarray] | None, n: int, cfg: IcpConfig) -> list[tuple[int, int]]:
    """(i, j) pairs with i < j.  With poses: optical axes within ``pair_max_angle_deg``; always
    includes ring neighbours k, k+1 so that the sequence stays connected."""
    pairs = set()
    for k in range(n - 1):
        pairs.add((k, k + 1))
    if poses is None:
        for k in range(n):
            for d in range(1, cfg.ring_neighbours + 1):
                a, b = k, (k + d) % n
                if a != b:
                    pairs.add((min(a, b), max(a, b)))
    else:
        fwd = [p[2, :3] for p in poses]
        cos_max = math.cos(math.radians(cfg.pair_max_angle_deg))
        for a in range(n):
            for b in range(a + 1, n):
                if float(np.dot(fwd[a], fwd[b])) >= cos_max:
                    pairs.add((a, b))
    return sorted(pairs)


@dataclass
class IcpOutcome:
    """Result of :func:`register_icp`."""

    cam_from_world: list[np.ndarray]  # refined poses (flagged scans keep their input pose)
    registered: list[bool]
    gauge: int
    pairs: list[PairResult]
    residuals: dict  # (i, j) -> (deg, m)
    seconds: dict


def register_icp(scanset: ScanSet, cfg: IcpConfig = IcpConfig(), use_init: bool = True,
                 init_poses: list[np.ndarray] | None = None) -> IcpOutcome:
    """Multiway geometric registration of a scan set (see module docstring).

    Args:
        scanset: scans with their (nominal) cameras; ``bounds`` give the object size and centre.
        use_init: start from the input poses (``--init nominal``); False = global registration
            between ring neighbours only (``--init none``).
        init_poses: optional cam_from_world per scan overriding the input cameras (e.g. SfM).
    Returns:
        :class:`IcpOutcome`; the gauge scan keeps its input pose exactly.
    """
    t0 = time.perf_counter()
    n = len(scanset.scans)
    size = scanset.size
    center_w = scanset.bounds.mean(axis=0)
    voxels = _levels(cfg, size)
    poses_in = [np.asarray(p, dtype=np.float64)
                for p in (init_poses or [s.camera.cam_from_world for s in scanset.scans])]
    secs: dict[str, float] = {}
    data = [prepare(s, voxels, cfg) for s in scanset.scans]
    secs["clouds"] = time.perf_counter() - t0
    # object centre in each camera (nominal): used for translation figures
    centers = [p[:3, :3] @ center_w + p[:3, 3] for p in poses_in]
    t1 = time.perf_counter()
    results = []
    for i, j in choose_pairs(poses_in if use_init else None, n, cfg):
        init = poses_in[i] @ invert_rigid(poses_in[j]) if use_init else None
        results.append(register_pair(data[i], data[j], init, voxels, cfg, size, centers[j], i=i, j=j))
    secs["pairs"] = time.perf_counter() - t1
    t2 = time.perf_counter()
    bad = {id(e) for e in PG.triangle_check([r for r in results if r.status == "ok"], centers, size)}
    results = [replace(r, status="inconsistent") if id(r) in bad else r for r in results]
    nodes = PG.initial_nodes(poses_in, results, use_init)
    graph = PG.PoseGraph(results, nodes, centers, size, cfg.corr_voxels * voxels[-1])
    for rnd in range(1 + cfg.refine_rounds):
        graph.optimise_pruned()
        if rnd < cfg.refine_rounds:
            _refine_edges(graph, data, cfg)
    secs["pose_graph"] = time.perf_counter() - t2
    main, nodes, gauge = graph.main, graph.nodes, graph.gauge
    registered = [k in main for k in range(n)]
    # gauge: the gauge scan keeps its input pose
    fix = invert_rigid(poses_in[gauge]) @ invert_rigid(nodes[gauge])
    out = [_orthonormalise(invert_rigid(fix @ nodes[k])) if registered[k] else _orthonormalise(poses_in[k])
           for k in range(n)]
    return IcpOutcome(out, registered, gauge, graph.results, graph.residuals, secs)


def _refine_edges(graph: PG.PoseGraph, data: list[ScanData], cfg: IcpConfig) -> None:
    """Fine ICP of every edge from the optimised relative pose; kept when accepted and close."""
    for e in graph.edges:
        init = invert_rigid(graph.nodes[e.i]) @ graph.nodes[e.j]
        T, fit, rmse, info, crmse = fine_align(data[e.i].frame, data[e.j].frame, init, cfg, graph.size)
        corr = R.transform_delta(T, init, graph.centers[e.j])
        ok = classify(fit, rmse, corr, graph.size, crmse, cfg.correction_bound) == "ok"
        if ok and corr[0] < R.MAX_EDGE_RESIDUAL_DEG * 2:
            graph.replace_edge(e, replace(e, T=T, fitness=fit, rmse=rmse, information=info))


def _orthonormalise(m: np.ndarray) -> np.ndarray:
    u, _, vt = np.linalg.svd(m[:3, :3])
    r = u @ vt
    if np.linalg.det(r) < 0:
        u[:, -1] *= -1
        r = u @ vt
    out = np.eye(4)
    out[:3, :3] = r
    out[:3, 3] = m[:3, 3]
    return out

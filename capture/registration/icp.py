"""Geometric registration of range scans with Open3D (DESIGN "capture/", issue 4).

Pipeline (multiway registration):

1. every scan -> camera-frame cloud (``points.py``) -> voxel pyramid (coarse -> fine, sizes
   relative to the object size) with normals;
2. pairs: scans whose nominal optical axes are within ``pair_max_angle_deg`` (or, without
   poses, ring neighbours k+1, k+2 including the wrap-around loop closure);
3. pairwise coarse-to-fine point-to-plane ICP (Open3D, Tukey robust kernel; coloured ICP at
   the finest level when ``colored``) from the nominal relative pose, then projective
   point-to-plane ICP on the range images (``projective.py``: exact association, no boundary
   bias); a pair that fails the thresholds of ``report.py`` is retried from FPFH + RANSAC;
4. a pose graph (odometry edges certain, the others uncertain loop closures) optimised by
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
from dataclasses import dataclass, field

import numpy as np

from capture.camera import invert_rigid
from capture.registration import points as P
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


@dataclass
class PairResult:
    """Result of one pair registration (target i, source j)."""

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
    res = reg.registration_ransac_based_on_feature_matching(
        src, tgt, feats[0], feats[1], True, dist, reg.TransformationEstimationPointToPoint(False), 3,
        [reg.CorrespondenceCheckerBasedOnEdgeLength(0.9), reg.CorrespondenceCheckerBasedOnDistance(dist)],
        reg.RANSACConvergenceCriteria(100000, 0.999))
    return np.asarray(res.transformation)


def classify(fitness: float, rmse: float, correction: tuple[float, float] | None, size: float,
             color_rmse: float = float("nan")) -> str:
    """Status of a pair result against the thresholds of ``report.py`` (``color_rmse`` is
    checked when finite, i.e. when the colour term is on)."""
    if correction is not None and (correction[0] > R.MAX_CORRECTION_DEG or correction[1] > R.MAX_CORRECTION_FRAC * size):
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
    dist = cfg.corr_voxels * voxels[-1]
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
        for _, start, T in cands[: cfg.fine_candidates]:
            T, fit, rmse, info, crmse = fine_align(di.frame, dj.frame, T, cfg, size)
            corr = R.transform_delta(T, init, center_j)
            r = PairResult(i, j, T, fit, rmse, info, "icp", classify(fit, rmse, corr, size, crmse), corr[0])
            r.color_rmse = crmse
            results.append(r)
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
        st = classify(fit, rmse, corr, size, crmse)
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


def optimise_graph(nodes: list[np.ndarray], edges: list[PairResult], members: set[int], gauge: int,
                   dist: float) -> list[np.ndarray]:
    """Levenberg-Marquardt pose-graph optimisation over the scans in ``members`` (a connected
    component containing ``gauge``); returns world_from_cam for every scan (others unchanged)."""
    import open3d as o3d

    reg = o3d.pipelines.registration
    order = sorted(members)
    idx = {k: n for n, k in enumerate(order)}
    pg = reg.PoseGraph()
    for k in order:
        pg.nodes.append(reg.PoseGraphNode(nodes[k]))
    for e in edges:
        if e.i in idx and e.j in idx:
            uncertain = abs(e.j - e.i) != 1
            pg.edges.append(reg.PoseGraphEdge(idx[e.j], idx[e.i], e.T, e.information, uncertain))
    opt = reg.GlobalOptimizationOption(max_correspondence_distance=dist, edge_prune_threshold=0.25,
                                       preference_loop_closure=1.0, reference_node=idx[gauge])
    with o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error):
        reg.global_optimization(pg, reg.GlobalOptimizationLevenbergMarquardt(),
                                reg.GlobalOptimizationConvergenceCriteria(), opt)
    out = [np.array(n_) for n_ in nodes]
    for k in order:
        out[k] = np.asarray(pg.nodes[idx[k]].pose)
    return out


def edge_residual(e: PairResult, nodes: list[np.ndarray], center_j: np.ndarray) -> tuple[float, float]:
    """Disagreement of a measured pair transform with the optimised poses (degrees, metres)."""
    pred = invert_rigid(nodes[e.i]) @ nodes[e.j]
    return R.transform_delta(e.T, pred, center_j)


def triangle_check(edges: list[PairResult], centers: list[np.ndarray], size: float) -> list[PairResult]:
    """Loop-consistency over triangles before the pose graph: an accepted edge (i, j) whose
    transform disagrees with a two-edge path i -> m -> j made of *better* edges (higher
    fitness), and agrees with none, is returned as inconsistent.  On a symmetric object the
    wide-baseline pairs slide along the symmetry with a perfect geometric fit; the short
    pairs around them expose it."""
    by = {}
    for e in edges:
        by[(e.i, e.j)] = e
    def get(a, b):
        if (a, b) in by:
            return by[(a, b)].T, by[(a, b)].fitness
        if (b, a) in by:
            return invert_rigid(by[(b, a)].T), by[(b, a)].fitness
        return None, 0.0
    nodes = sorted({e.i for e in edges} | {e.j for e in edges})
    bad = []
    for e in edges:
        agree = disagree = 0
        for m in nodes:
            if m in (e.i, e.j):
                continue
            T1, f1 = get(e.i, m)
            T2, f2 = get(m, e.j)
            if T1 is None or T2 is None:
                continue
            rot, disp = R.transform_delta(e.T, T1 @ T2, centers[e.j])
            if rot <= R.MAX_TRIANGLE_DEG and disp <= R.MAX_TRIANGLE_FRAC * size:
                agree += 1
            elif min(f1, f2) > e.fitness:
                disagree += 1
        if disagree and not agree:
            bad.append(e)
    return bad


def _components(n: int, edges: list[PairResult]) -> list[set[int]]:
    parent = list(range(n))

    def find(a):
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    for e in edges:
        parent[find(e.i)] = find(e.j)
    comps: dict[int, set[int]] = {}
    for k in range(n):
        comps.setdefault(find(k), set()).add(k)
    return sorted(comps.values(), key=lambda c: (-len(c), min(c)))


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
    poses_in = [np.asarray(p, dtype=np.float64) for p in (init_poses or [s.camera.cam_from_world for s in scanset.scans])]
    secs: dict[str, float] = {}

    data = [prepare(s, voxels, cfg) for s in scanset.scans]
    secs["clouds"] = time.perf_counter() - t0
    # object centre in each camera (nominal): used for translation figures
    centers = [p[:3, :3] @ center_w + p[:3, 3] for p in poses_in]

    t1 = time.perf_counter()
    pairs = choose_pairs(poses_in if use_init else None, n, cfg)
    results: list[PairResult] = []
    for i, j in pairs:
        init = poses_in[i] @ invert_rigid(poses_in[j]) if use_init else None
        results.append(register_pair(data[i], data[j], init, voxels, cfg, size, centers[j], i=i, j=j))
    secs["pairs"] = time.perf_counter() - t1

    t2 = time.perf_counter()
    accepted = [r for r in results if r.status == "ok"]
    for e in triangle_check(accepted, centers, size):
        e.status = "inconsistent"
    accepted = [r for r in results if r.status == "ok"]
    # initial node poses: nominal, or chained along accepted odometry edges
    if use_init:
        nodes = [invert_rigid(p) for p in poses_in]
    else:
        nodes = [invert_rigid(p) for p in poses_in]
        by = {(r.i, r.j): r for r in accepted}
        for k in range(1, n):
            r = by.get((k - 1, k))
            if r is not None:
                nodes[k] = nodes[k - 1] @ r.T
    comps = _components(n, accepted)
    main = comps[0]
    gauge = min(main)
    dist = cfg.corr_voxels * voxels[-1]
    residuals: dict = {}
    for _round in range(1 + cfg.refine_rounds):
        edges = [r for r in accepted if r.i in main and r.j in main]
        nodes = optimise_graph(nodes, edges, main, gauge, dist)
        # remove inconsistent edges, re-optimise
        for _pass in range(3):
            bad = []
            for e in edges:
                res = edge_residual(e, nodes, centers[e.j])
                residuals[(e.i, e.j)] = res
                if res[0] > R.MAX_EDGE_RESIDUAL_DEG or res[1] > R.MAX_EDGE_RESIDUAL_FRAC * size:
                    bad.append(e)
            if not bad:
                break
            worst = max(bad, key=lambda e: residuals[(e.i, e.j)][0] / R.MAX_EDGE_RESIDUAL_DEG
                        + residuals[(e.i, e.j)][1] / (R.MAX_EDGE_RESIDUAL_FRAC * size))
            worst.status = "inconsistent"
            accepted = [r for r in accepted if r.status == "ok"]
            comps = _components(n, accepted)
            main = comps[0]
            gauge = min(main)
            edges = [r for r in accepted if r.i in main and r.j in main]
            nodes = optimise_graph(nodes, edges, main, gauge, dist)
        if _round < cfg.refine_rounds:
            # refine: fine ICP from optimised relative poses
            for e in edges:
                init = invert_rigid(nodes[e.i]) @ nodes[e.j]
                T, fit, rmse, info, crmse = fine_align(data[e.i].frame, data[e.j].frame, init, cfg, size)
                corr = R.transform_delta(T, init, centers[e.j])
                if classify(fit, rmse, corr, size, crmse) == "ok" and corr[0] < R.MAX_EDGE_RESIDUAL_DEG * 2:
                    e.T, e.fitness, e.rmse, e.information = T, fit, rmse, info
    secs["pose_graph"] = time.perf_counter() - t2

    registered = [k in main for k in range(n)]
    # gauge: the gauge scan keeps its input pose
    anchor = invert_rigid(poses_in[gauge])  # world_from_cam_g (input)
    fix = anchor @ invert_rigid(nodes[gauge])
    out = [invert_rigid(fix @ nodes[k]) if registered[k] else poses_in[k] for k in range(n)]
    out = [_orthonormalise(p) for p in out]
    return IcpOutcome(out, registered, gauge, results, residuals, secs)


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

"""The pose graph of the per-scan registration (``icp.py`` step 4-5): Levenberg-Marquardt over
the accepted pair transforms (Open3D), removal of inconsistent edges, loop checks.

Poses: graph node k holds ``world_from_cam_k``; a pair transform ``T_ij`` maps camera-j points
into camera i.  Pair results are replaced (``dataclasses.replace``), never changed in place.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from capture.camera import invert_rigid
from capture.registration import report as R

if TYPE_CHECKING:
    from capture.registration.icp import PairResult


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


def components(n: int, edges: list[PairResult]) -> list[set[int]]:
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


def initial_nodes(poses_in: list[np.ndarray], results: list[PairResult], use_init: bool) -> list[np.ndarray]:
    """world_from_cam per scan: the input poses, or (without them) chained along accepted
    odometry edges k-1 -> k."""
    nodes = [invert_rigid(p) for p in poses_in]
    if not use_init:
        by = {(r.i, r.j): r for r in results if r.status == "ok"}
        for k in range(1, len(nodes)):
            r = by.get((k - 1, k))
            if r is not None:
                nodes[k] = nodes[k - 1] @ r.T
    return nodes


class PoseGraph:
    """The accepted pair results, the node poses and the main component, through the pose-graph
    rounds: optimise, remove the worst inconsistent edge, repeat.
    Pair results are replaced (``dataclasses.replace``), never changed in place."""

    def __init__(self, results, nodes, centers, size, dist):
        self.results, self.nodes, self.centers, self.size, self.dist = list(results), nodes, centers, size, dist
        self.residuals: dict = {}
        self._components()

    def _components(self) -> None:
        self.main = components(len(self.nodes), self.accepted)[0]
        self.gauge = min(self.main)

    @property
    def accepted(self) -> list[PairResult]:
        return [r for r in self.results if r.status == "ok"]

    @property
    def edges(self) -> list[PairResult]:
        return [r for r in self.accepted if r.i in self.main and r.j in self.main]

    def replace_edge(self, old: PairResult, new: PairResult) -> None:
        """Put ``new`` where ``old`` was."""
        self.results = [new if r is old else r for r in self.results]

    def optimise_pruned(self, passes: int = 3) -> None:
        """Optimise; then up to ``passes`` times drop the worst edge whose residual exceeds the
        thresholds, and re-optimise."""
        self.nodes = optimise_graph(self.nodes, self.edges, self.main, self.gauge, self.dist)
        for _ in range(passes):
            bad = []
            for e in self.edges:
                res = edge_residual(e, self.nodes, self.centers[e.j])
                self.residuals[(e.i, e.j)] = res
                if res[0] > R.MAX_EDGE_RESIDUAL_DEG or res[1] > R.MAX_EDGE_RESIDUAL_FRAC * self.size:
                    bad.append(e)
            if not bad:
                return
            worst = max(bad, key=lambda e: self.residuals[(e.i, e.j)][0] / R.MAX_EDGE_RESIDUAL_DEG
                        + self.residuals[(e.i, e.j)][1] / (R.MAX_EDGE_RESIDUAL_FRAC * self.size))
            self.replace_edge(worst, replace(worst, status="inconsistent"))
            self._components()
            self.nodes = optimise_graph(self.nodes, self.edges, self.main, self.gauge, self.dist)

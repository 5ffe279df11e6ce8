"""The object's extent from the capture itself: support plane, far depth and clutter out of the depth.

A real capture's depth sees more than the object: the table or turntable it stands on, the wall
behind it, clutter beside it.  Fused as they are, they become part of the model (issue 20: a table
top in the depth raised L_opt from 8 to 256).  :func:`remove_surroundings` sets the depth of every
pixel that is not the object to 0 before fusion, RGBz and every method, and says what it removed:

* **focus region**: the rig looks at one region.  Its centre is the point nearest to every optical
  axis (``capture.orbit.closest_point_to_axes``); its radius is ``FOCUS_MARGIN`` times what the
  widest camera sees across its half diagonal at its distance to that centre (the median over the
  cameras).  Depth outside that sphere is ``far`` (behind the centre along the ray) or ``outside``
  (walls and clutter beside it).
* **support**: a plane fitted by RANSAC (:func:`ransac_plane`, seeded) to the world points in
  the focus region, accepted only when it is roughly perpendicular to the rig's up axis
  (``capture.orbit.estimate_up``; within ``PLANE_MAX_TILT_DEG``), holds at least
  ``SUPPORT_MIN_FRACTION`` of those points, lies under the focus centre and every camera, and has
  almost nothing (``SUPPORT_MAX_BELOW``) of the rest below it: an object stands on its support.  A
  flat top of the object itself (the soil in a pot) has the pot's walls below it and is refused.
  Depth within ``SUPPORT_BAND`` inlier distances above the plane, or anywhere below it, is
  ``support``.  ``ExtentConfig.keep_support`` keeps it.
* **floaters**: depth pixels left after the above that hang in the air apart from the object (the
  sensor's flying pixels off the table's edges and the object's outline).  The kept points of all
  views go into a coarse occupancy grid (``FLOATER_VOXEL_FRACTION`` of the focus radius); a voxel
  counts as occupied when ``FLOATER_MIN_VIEWS`` views put a point in it (a flying pixel lies on one
  view's ray; with 1, chains of them along the rays join the object and stay).  The 26-connected
  components of the occupied voxels that hold at least ``FLOATER_KEEP_FRACTION`` of the largest
  one's view hits are the object; a point is kept when its voxel lies within ``FLOATER_DILATE``
  voxels of them (strand tips that one view alone sees).  Thin needles and strands are connected to
  their branch at that scale and stay.  ``ExtentConfig.floaters`` turns it off.

A capture with nothing but the object comes out unchanged (no plane passes the tests and every
point is inside the focus region).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from capture.extent_kernel import view_labels
from capture.orbit import closest_point_to_axes, estimate_up
from capture.sampling import cell_index
from capture.scan import MAX_SAMPLED_POINTS, Scan, ScanSet, bounds_from_points, every_kth_point
from capture.view_map import or_serial

#: Removal reasons, in the order they are decided.
REASONS = ("support", "far", "outside", "floaters")
#: Focus-region radius as a multiple of what a camera sees across its half diagonal at the focus centre.
FOCUS_MARGIN = 1.5
#: RANSAC inlier distance as a fraction of the focus radius (3.6 mm at a 0.36 m focus radius).
PLANE_DISTANCE_FRACTION = 0.01
#: Points within this many inlier distances above the accepted plane are support too (the band
#: a noisy sensor spreads the table over; the object loses as much of its foot).
SUPPORT_BAND = 1.5
#: Largest angle between the support's normal and the rig's up axis (degrees).
PLANE_MAX_TILT_DEG = 25.0
#: Least fraction of the focus region's points on the plane for it to be a support.
SUPPORT_MIN_FRACTION = 0.05
#: Largest fraction of the other focus-region points allowed below the plane (an object stands on it).
SUPPORT_MAX_BELOW = 0.02
#: Planes tried (each refused plane's inliers are set aside before the next fit).
PLANE_TRIES = 3
#: Points given to RANSAC (a seeded random subset of the focus region's points).
RANSAC_POINTS = 60000
RANSAC_ITERATIONS = 1000
RANSAC_SEED = 0
#: RANSAC hypotheses scored together (a (points x batch) distance matrix: 60000 x 64 doubles, 31 MB).
RANSAC_BATCH = 64
#: Floater grid: voxel edge as a fraction of the focus radius (7.2 mm at a 0.36 m focus radius).
FLOATER_VOXEL_FRACTION = 0.02
#: Views that must put a point in a voxel for it to be occupied (module docstring).
FLOATER_MIN_VIEWS = 2
#: Components holding at least this fraction of the largest component's view hits are object.
FLOATER_KEEP_FRACTION = 0.05
#: Voxels around the object's components whose points are kept too (single-view strand tips, noise;
#: with 1 a 128x96 fur ball lost 1 % of its depth pixels, with 2 0.08 %).
FLOATER_DILATE = 2


@dataclass(frozen=True)
class ExtentConfig:
    """Settings of :func:`remove_surroundings`."""

    #: Keep the support plane in the depth (``furrow model --keep-support``); far depth and clutter still go.
    keep_support: bool = False
    #: Multiple of the camera's half-diagonal view at the focus centre that bounds the focus region.
    focus_margin: float = FOCUS_MARGIN
    #: Remove floaters (depth apart from the object's connected occupancy; module docstring).
    floaters: bool = True
    #: Label each view's pixels in one compiled loop (capture.extent_kernel.view_labels); False: the
    #: numpy reference (:func:`_labels`, :func:`_floater_cells`, :func:`floater_relabel`), the same
    #: labels (tests/capture/test_extent.py states the tolerance).
    fast: bool = True

    def __post_init__(self) -> None:
        if not self.focus_margin > 0:
            raise ValueError(f"focus_margin must be > 0, got {self.focus_margin}")


@dataclass(frozen=True)
class ExtentReport:
    """What :func:`remove_surroundings` found and removed.

    Attributes:
        plane: (4,) float64 support plane (n_x, n_y, n_z, d), n . p + d = 0 with unit n pointing up
            (towards the cameras), metres; None when no support was found (or it was kept).
        plane_inlier_fraction: fraction of the focus region's points the plane holds (0 without one).
        focus_center: (3,) world point the rig looks at (metres).
        focus_radius: radius of the focus region (metres).
        up: (3,) unit rig up axis.
        removed: reason -> fraction of all depth pixels of the capture removed for it (``REASONS``).
        per_view: per scan, reason -> fraction of that scan's depth pixels removed.
        kept_support: True when the support was found but kept (``keep_support``).
    """

    plane: np.ndarray | None
    plane_inlier_fraction: float
    focus_center: np.ndarray
    focus_radius: float
    up: np.ndarray
    removed: dict = field(default_factory=dict)
    per_view: tuple = ()
    kept_support: bool = False

    def record(self) -> dict:
        """JSON-able summary (model.json params, ``furrow model --json``)."""
        return {"plane": None if self.plane is None else [round(float(v), 6) for v in self.plane],
                "plane_inlier_fraction": round(self.plane_inlier_fraction, 5),
                "kept_support": self.kept_support,
                "focus_center": [round(float(v), 5) for v in self.focus_center],
                "focus_radius": round(self.focus_radius, 5), "up": [round(float(v), 5) for v in self.up],
                "removed_fraction": {k: round(v, 6) for k, v in self.removed.items()},
                "removed_fraction_total": round(sum(self.removed.values()), 6)}


def focus_region(cameras, margin: float = FOCUS_MARGIN) -> tuple[np.ndarray, float]:
    """(centre (3,), radius) of the region the rig looks at (module docstring)."""
    center = closest_point_to_axes(cameras)
    r = []
    for c in cameras:
        half_diag = 0.5 * np.hypot(c.width / c.K[0, 0], c.height / c.K[1, 1])
        r.append(np.linalg.norm(c.center - center) * half_diag)
    return center, float(margin * np.median(r))


def ransac_plane(points: np.ndarray, threshold: float, iterations: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(plane (4,) unit normal and offset, indices of its inliers) of (N >= 3, 3) ``points``: the
    3-point hypothesis with the most points within ``threshold`` of it (seeded; RANSAC_BATCH
    hypotheses scored at a time), refined by a least-squares fit to its inliers, as Open3D's
    ``segment_plane`` does (whose import alone took 5 s here)."""
    rng = np.random.default_rng(seed)
    n = len(points)
    best, best_count = None, -1
    for lo in range(0, iterations, RANSAC_BATCH):
        k = min(RANSAC_BATCH, iterations - lo)
        tri = points[rng.integers(0, n, (k, 3))]
        nrm = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        norm = np.linalg.norm(nrm, axis=1)
        ok = norm > 0
        if not ok.any():
            continue
        nrm = nrm[ok] / norm[ok, None]
        off = -np.einsum("ij,ij->i", nrm, tri[ok, 0])
        count = np.count_nonzero(np.abs(points @ nrm.T + off) <= threshold, axis=0)
        j = int(np.argmax(count))
        if count[j] > best_count:
            best, best_count = np.append(nrm[j], off[j]), int(count[j])
    if best is None:
        return np.array([0.0, 0.0, 1.0, 0.0]), np.zeros(0, np.int64)
    inl = np.flatnonzero(np.abs(points @ best[:3] + best[3]) <= threshold)
    if len(inl) >= 3:  # least squares on the inliers: the normal is the smallest singular vector
        c = points[inl].mean(axis=0)
        nrm = np.linalg.svd(points[inl] - c, full_matrices=False)[2][-1]
        best = np.append(nrm, -nrm @ c)
        inl = np.flatnonzero(np.abs(points @ best[:3] + best[3]) <= threshold)
    return best, inl


def fit_support_plane(points: np.ndarray, up: np.ndarray, center: np.ndarray, cam_centers: np.ndarray,
                      threshold: float) -> tuple[np.ndarray | None, float]:
    """(plane (4,) with its normal towards ``up``, inlier fraction) of the support under the focus
    region's ``points`` (N, 3), or (None, 0.0) when no plane passes the tests of the module docstring."""
    pts = np.asarray(points, np.float64)
    if len(pts) > RANSAC_POINTS:
        pts = pts[np.random.default_rng(RANSAC_SEED).choice(len(pts), RANSAC_POINTS, replace=False)]
    n_all = len(pts)
    rest = pts
    cos_tilt = np.cos(np.radians(PLANE_MAX_TILT_DEG))
    for _ in range(PLANE_TRIES):
        if len(rest) < max(3, SUPPORT_MIN_FRACTION * n_all):
            break
        plane, inl = ransac_plane(rest, threshold, RANSAC_ITERATIONS, RANSAC_SEED)
        if plane[:3] @ up < 0:
            plane = -plane
        inl = np.asarray(inl, np.int64)
        h = rest @ plane[:3] + plane[3]
        others = np.ones(len(rest), bool)
        others[inl] = False
        below = np.mean(h[others] < -SUPPORT_BAND * threshold) if others.any() else 0.0
        if (plane[:3] @ up >= cos_tilt and len(inl) >= SUPPORT_MIN_FRACTION * n_all
                and center @ plane[:3] + plane[3] > 0 and np.all(cam_centers @ plane[:3] + plane[3] > 0)
                and below <= SUPPORT_MAX_BELOW):
            return plane, len(inl) / n_all
        rest = rest[others]
    return None, 0.0


def _labels(scan: Scan, center: np.ndarray, radius: float, plane: np.ndarray | None, band: float) -> np.ndarray:
    """(H, W) int8: 0 = kept / no depth, 1 + index in REASONS = removed for that reason."""
    lab = np.zeros(scan.depth.shape, np.int8)
    pts, mask = scan.camera.depth_to_points(scan.depth)
    if not len(pts):
        return lab
    out = np.zeros(len(pts), np.int8)
    if plane is not None:
        out[pts @ plane[:3] + plane[3] < band] = 1
    d = np.linalg.norm(pts - center, axis=1)
    z_center = scan.camera.world_to_cam(center)[2]
    beyond = (d > radius) & (out == 0)
    out[beyond] = np.where(scan.depth[mask][beyond] > z_center, 2, 3)
    lab[mask] = out
    return lab


def _floater_cells(scan: Scan, lab: np.ndarray, origin: np.ndarray, voxel: float, n: int):
    """(kept depth pixels (H, W) bool, their flat cell indices in the floater grid) of one view."""
    keep = (lab == 0) & np.isfinite(scan.depth) & (scan.depth > 0)
    pts, _ = scan.camera.depth_to_points(np.where(keep, scan.depth, 0.0))
    ijk = np.clip(cell_index(pts, origin, voxel), 0, n - 1)
    return keep, (ijk[:, 0] * n + ijk[:, 1]) * n + ijk[:, 2]


def floater_relabel(scan: Scan, lab: np.ndarray, grid) -> np.ndarray:
    """``lab`` with the kept depth pixels outside the object cells of ``grid`` (:func:`floater_grid`)
    set to the floaters' code."""
    if grid is None:
        return lab
    obj, origin, voxel, n = grid
    keep, flat = _floater_cells(scan, lab, origin, voxel, n)
    lab = lab.copy()
    sub = lab[keep]
    sub[~obj[flat]] = 1 + REASONS.index("floaters")
    lab[keep] = sub
    return lab


def depth_count_view(scan, k, arg):
    """Per view: its depth pixels (the sampling step of capture.scan.sampled_points)."""
    return None, int(np.count_nonzero(scan.depth > 0))


def sampled_points_view(scan, k, arg):
    """Per view: every ``step``-th of its depth points in row-major order, as
    ``capture.scan.sampled_points`` takes them (back-projected alone: the same values); ``arg``:
    the step, or (step, centre, radius) to keep only those within ``radius`` of ``centre`` (the
    focus region's points, each tested alone as over all views' points: the same points)."""
    step, sphere = (arg, None) if np.isscalar(arg) else (arg[0], arg[1:])
    pts = every_kth_point(scan, step)
    if sphere is not None and len(pts):
        pts = pts[np.linalg.norm(pts - sphere[0], axis=1) <= sphere[1]]
    return None, pts


def mapped_sampled_points(map_views, scans, max_points: int = MAX_SAMPLED_POINTS, counts=None,
                          sphere=None) -> np.ndarray:
    """``capture.scan.sampled_points`` of ``scans`` view by view through ``map_views`` (``counts``:
    the views' depth pixels when known; ``sphere``: (centre, radius) to keep only the points within
    it, tested in each view's pass)."""
    if counts is None:
        counts = map_views(depth_count_view, scans, None, "extent: depth")[1]
    step = max(1, -(-int(sum(counts)) // max(int(max_points), 1)))
    arg = step if sphere is None else (step, *sphere)
    pts = [p for p in map_views(sampled_points_view, scans, arg, "extent: points")[1] if len(p)]
    return np.concatenate(pts) if pts else np.zeros((0, 3))


def floater_cells_view(scan, k, arg):
    """Per view: the floater grid's cells its kept depth points fall in (unique flat indices);
    ``arg``: (the :func:`_labels` arguments after the scan, (origin, voxel, n), ExtentConfig.fast)."""
    labels, cells, fast = arg
    if fast:
        return None, view_labels(scan.depth, scan.camera, *labels, cells=cells)[1]
    return None, np.unique(_floater_cells(scan, _labels(scan, *labels), *cells)[1])


def removal_view(scan, k, arg):
    """Per view: (the scan with the removed depth at 0, or None when nothing is removed; its depth
    pixels and the pixels removed per reason); ``arg``: (the :func:`_labels` arguments after the
    scan, the packed floater grid or None, ExtentConfig.fast)."""
    labels, grid, fast = arg
    if grid is not None:
        grid = (np.unpackbits(grid[0], count=grid[4]).astype(bool), *grid[1:4])
    if fast:
        lab = view_labels(scan.depth, scan.camera, *labels, cells=None if grid is None else grid[1:],
                          obj=None if grid is None else grid[0])[0]
    else:
        lab = floater_relabel(scan, _labels(scan, *labels), grid)
    counts = {r: int(np.count_nonzero(lab == k + 1)) for k, r in enumerate(REASONS)}
    note = {"valid": int(np.count_nonzero(scan.valid)), **counts}
    if not lab.any():
        return None, note
    note["kept"] = note["valid"] - int(np.count_nonzero(lab))
    return Scan(scan.rgb, np.where(lab > 0, 0.0, scan.depth), scan.camera, scan.name, scan.alpha), note


def floater_grid(map_views, scans, labels, center: np.ndarray, radius: float, fast: bool = True):
    """(object cells (n^3,) bool, origin, voxel, n) of the floater test (module docstring), each
    view's cells through ``map_views`` (``labels``: the arguments of its :func:`_labels` after the
    scan; ``fast``: ExtentConfig.fast); None when no cell is seen often enough."""
    from scipy import ndimage

    voxel = FLOATER_VOXEL_FRACTION * radius
    n = int(np.ceil(2 * radius / voxel)) + 1
    origin = center - radius
    hits = np.zeros(n ** 3, np.int32)
    for cells in map_views(floater_cells_view, scans, (labels, (origin, voxel, n), fast), "extent: floaters")[1]:
        hits[cells] += 1
    occ = (hits >= FLOATER_MIN_VIEWS).reshape(n, n, n)
    comp, n_comp = ndimage.label(occ, structure=np.ones((3, 3, 3), bool))
    if n_comp == 0:
        return None
    weight = ndimage.sum(hits.reshape(n, n, n), comp, np.arange(1, n_comp + 1))
    obj = np.isin(comp, 1 + np.flatnonzero(weight >= FLOATER_KEEP_FRACTION * weight.max()))
    if FLOATER_DILATE > 0:
        obj = ndimage.binary_dilation(obj, np.ones((3, 3, 3), bool), iterations=FLOATER_DILATE)
    return obj.ravel(), origin, voxel, n


def remove_surroundings(scanset: ScanSet, cfg: ExtentConfig | None = None, keep=None,
                        map_views=None) -> tuple[ScanSet, ExtentReport]:
    """``scanset`` with the depth of everything but the object set to 0 (module docstring), its
    bounds shrunk to the remaining depth (never grown), and the report.  Colour and mattes are kept.
    Views are worked on one at a time, each pass through ``map_views(fn, scans, arg, description)
    -> (views, notes)`` (capture.view_map; default: in this process, each changed scan through
    ``keep``; the pipeline's runner gives its pool of processes): depth points for the plane,
    floater cells, the removal, points for the bounds."""
    cfg = cfg or ExtentConfig()
    map_views = or_serial(map_views, keep)
    cams = scanset.cameras
    up = estimate_up(cams)
    center, radius = focus_region(cams, cfg.focus_margin)
    thr = PLANE_DISTANCE_FRACTION * radius
    focus = mapped_sampled_points(map_views, scanset.scans, sphere=(center, radius))
    plane, frac = fit_support_plane(focus, up, center, np.array([c.center for c in cams]), thr) \
        if len(focus) >= 3 else (None, 0.0)
    kept = plane is not None and cfg.keep_support
    labels = (center, radius, None if kept else plane, SUPPORT_BAND * thr)
    grid = floater_grid(map_views, scanset.scans, labels, center, radius, cfg.fast) if cfg.floaters else None
    packed = None if grid is None else (np.packbits(grid[0]), *grid[1:], len(grid[0]))
    scans, notes = map_views(removal_view, scanset.scans, (labels, packed, cfg.fast), "extent: removal")
    n_valid = sum(n["valid"] for n in notes)
    totals = {r: sum(n[r] for n in notes) for r in REASONS}
    per_view = tuple({r: (n[r] / n["valid"] if n["valid"] else 0.0) for r in REASONS} for n in notes)
    removed_any = any("kept" in n for n in notes)
    out = scanset
    if removed_any:
        counts = [n.get("kept", n["valid"]) for n in notes]
        out = ScanSet(tuple(scans), _shrunk_bounds(scanset.bounds, mapped_sampled_points(map_views, scans,
                                                                                          counts=counts)),
                      scanset.metadata)
    removed = {r: (totals[r] / n_valid if n_valid else 0.0) for r in REASONS}
    return out, ExtentReport(plane, frac, center, radius, up, removed, per_view, kept)


def _shrunk_bounds(bounds: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """``bounds`` intersected with the robust box of the scans' remaining depth points ``pts``
    (capture.scan.sampled_points; capture.io.auto_bounds)."""
    from capture.io import AUTO_BOUNDS_MARGIN, AUTO_BOUNDS_PERCENTILES

    if len(pts) < 2:
        return bounds
    lo, hi = np.percentile(pts, AUTO_BOUNDS_PERCENTILES[0], axis=0), np.percentile(pts, AUTO_BOUNDS_PERCENTILES[1],
                                                                                   axis=0)
    auto = bounds_from_points(np.stack([lo, hi]), AUTO_BOUNDS_MARGIN)
    b = np.stack([np.maximum(bounds[0], auto[0]), np.minimum(bounds[1], auto[1])])
    return b if np.all(b[1] > b[0]) else bounds

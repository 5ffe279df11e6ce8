"""Signed distance volumes from posed range scans (docs/methods.md §1.1 step 1).

Consensus fusion in the spirit of Wheeler, Sato & Ikeuchi (1998), vectorised over voxels:

1. **Per scan** (:func:`scan_maps`): normals from depth gradients (one-sided differences,
   the side with the smaller depth step, so strand edges keep a normal), oriented towards the
   camera; pixels seen at more than ``max_grazing_deg`` are not used as surface samples.
2. **Pass 1, every voxel x, every scan** (streamed, O(voxels) memory): project x to its
   nearest pixel; with measured depth D and the voxel's z-depth z, count
   ``free`` (D - z > agree: the scan saw through x), ``nodata`` (x projects onto a pixel with
   no return, and none within SILHOUETTE_PX), ``occluded`` (z - D > trunc) and ``near`` (a valid surface sample
   within trunc: point-to-plane distance d = n . (x - p) of the pixel's point p and normal n).
3. **Pass 2, voxels with a near sample** (the band, chunked): every scan's sample
   (d_i, n_i) is compared with every other's; samples i, j *agree* when their normals are
   within ``agree_normal_deg`` and the nearest points on their tangent planes,
   x - d_i n_i and x - d_j n_j, lie within ``agree`` metres.  A sample has *consensus* when at
   least ``quorum`` samples (itself included) agree with it (the quorum drops to the number of
   scans whose image contains x, so a lone scan still counts).  The consensus sample nearest the
   surface (smallest |d|) is chosen and the voxel's distance is the view-cosine weighted mean
   of the samples agreeing with it.  More scans seeing through x than supporting it cancel it.
   A voxel with samples but no consensus whose nearest (unconfirmed) cluster of samples puts
   it in front of the surface is outside; unconfirmed samples never make a voxel inside.
4. **Sign elsewhere** (space carving with votes, :func:`carve_sign`): x is outside when
   free >= min(carve_quorum, #scans that see x), or free + nodata >= carve_ratio * occluded; voxels fewer than
   min(carve_quorum, #scans) scans contain are outside; the rest (hidden behind the surface in every view) are inside.
5. **Completion** (:func:`volume.completion.complete_sdf`): outside the consensus band the distance is the
   Euclidean distance transform of the sign field, so it is finite everywhere.

The Open3D TSDF peer (:mod:`volume.tsdf`) uses steps 2, 4, 5 too, with its own band.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy import ndimage

from capture.depth_normals import depth_normals
from capture.sampling import voxel_centres
from capture.scan import Scan, ScanSet
from volume.completion import complete_sdf
from volume.grid import flat_voxel_indices, voxel_centers

#: Voxels per chunk in pass 1 (memory ~ 40 bytes per voxel per array).
PASS1_CHUNK = 1 << 19
#: Band voxels per chunk in pass 2 (memory ~ 5 * scans^2 bytes per voxel).
PASS2_CHUNK = 4096
#: Pass 1 keeps a voxel for pass 2 when |D - z| cos < NEAR_SLACK * trunc (slack for curvature).
NEAR_SLACK = 1.5
#: A near sample must also lie within this many truncation distances along the ray.
PROJ_FACTOR = 3.0
#: A no-return pixel votes "empty" only when no pixel within this radius has depth: a voxel
#: projecting next to a silhouette is ambiguous at pixel resolution.
SILHOUETTE_PX = 1
#: Pixel diameter and spatial sigma of the bilateral depth filter (see FusionConfig.smooth_sigma_z).
BILATERAL_DIAMETER = 5
BILATERAL_SIGMA_PX = 1.5
#: Implementations of passes 1 and 2 (FusionConfig.backend).
BACKENDS = ("numba", "numpy")


@dataclass(frozen=True)
class FusionConfig:
    """Parameters of the consensus fusion (docs/methods.md §1.1; Wheeler-Sato-Ikeuchi 1998)."""

    trunc_voxels: float = 3.0
    """Half-width of the band of measured distances, in voxels."""
    min_trunc: float = 0.0
    """Lower bound (metres) on the band half-width, e.g. 3x the depth noise."""
    agree_voxels: float = 1.5
    """Two samples agree in position when their nearest points are within this many voxels..."""
    min_agree: float = 0.0015
    """...or within this many metres, whichever is larger (about 2-3x the depth noise)."""
    agree_normal_deg: float = 45.0
    """Two samples agree in normal when their normals are within this angle (degrees)."""
    quorum: int = 3
    """Samples (itself included) that must agree for a sample to count (capped by #views)."""
    carve_quorum: int = 2
    """Free/no-return votes needed to carve a voxel (capped by the views that see it)."""
    carve_ratio: float = 0.25
    """...and at least this fraction of the views that see the voxel occluded."""
    max_grazing_deg: float = 78.0
    """Pixels whose normal is further than this from the view ray give no surface sample."""
    smooth_sigma_z: float = 0.003
    """Range sigma (metres) of the bilateral filter applied to depth before normals and planes
    are computed (depth edges larger than this are kept); 0 disables."""
    map_oversample: float = 2.0
    """When the depth was resampled up to the colour's size (scan-set metadata ``depth_size``: a phone's
    256x192 under 1920x1440 colour), the per-view maps are computed at this many times the measured
    size, capped at the colour's (volume.stream.native_scale; 'numba' backend); 0 = at the colour's size."""
    backend: str = "numba"
    """Compiled kernels, 'numba' (passes 1-2 in volume.fusion_jit, the distance transform of
    the ``edt`` package), or 'numpy' (vectorised numpy passes and scipy's transform: the reference)."""

    def __post_init__(self) -> None:
        if self.backend not in BACKENDS:
            raise ValueError(f"fusion backend must be one of {BACKENDS}, got {self.backend!r}")
        if self.trunc_voxels <= 0 or self.agree_voxels <= 0 or self.quorum < 1 or self.carve_quorum < 1:
            raise ValueError(f"invalid FusionConfig {self}")
        if not 0 < self.agree_normal_deg <= 180 or not 0 < self.max_grazing_deg < 90:
            raise ValueError(f"invalid angles in FusionConfig {self}")

    def trunc(self, w: float) -> float:
        return max(self.trunc_voxels * w, self.min_trunc)

    def agree(self, w: float) -> float:
        return max(self.agree_voxels * w, self.min_agree)


@dataclass(frozen=True)
class ScanMaps:
    """Per-scan arrays for fusion (world frame).

    Attributes:
        depth: (H*W,) float32 z-depth in metres, 0 = none.
        normal: (H*W, 3) float32 unit world normal towards the camera (0 where invalid).
        offset: (H*W,) float32 n . p for the pixel's world point p (metres).
        cosine: (H*W,) float32 |n . view ray|, 0 where the pixel gives no surface sample.
        void: (H*W,) bool, no depth within ``SILHOUETTE_PX`` pixels (a clear no-return).
        P: (3, 4) float64 projection K [R | t]; W, H: image size.
    """

    depth: np.ndarray
    normal: np.ndarray
    offset: np.ndarray
    cosine: np.ndarray
    void: np.ndarray
    P: np.ndarray
    W: int
    H: int


def scan_maps(scan: Scan, max_grazing_deg: float, smooth_sigma_z: float = 0.0, rect=None) -> ScanMaps:
    """Normals from depth gradients and the plane offsets of every pixel of ``scan``.

    ``rect`` (x0, y0, w, h): only that rectangle of the image (the arrays are its pixels,
    row-major; ``W``, ``H`` stay the image's); equal to the full map's pixels there when the
    rectangle keeps BILATERAL_DIAMETER pixels of no depth around every depth (volume.stream)."""
    cam = scan.camera
    x0, y0, rw, rh = (0, 0, cam.width, cam.height) if rect is None else (int(r) for r in rect)
    depth = np.asarray(scan.depth[y0:y0 + rh, x0:x0 + rw], np.float32)
    valid = depth > 0
    if smooth_sigma_z > 0 and valid.any():
        import cv2

        sm = cv2.bilateralFilter(depth, BILATERAL_DIAMETER, float(smooth_sigma_z), BILATERAL_SIGMA_PX)
        depth = np.where(valid, sm, 0).astype(np.float32)
    v, u = np.mgrid[y0:y0 + rh, x0:x0 + rw].astype(np.float64)
    grid = np.stack([u, v], axis=-1)
    rays = cam.pixel_rays(grid)  # (h, w, 3), z = 1
    pc = rays * depth[..., None].astype(np.float64)
    n, ok = depth_normals(pc, valid, "smaller_step")  # facing the camera
    ray_u = rays / np.linalg.norm(rays, axis=-1, keepdims=True)
    cosine = np.abs(np.sum(n * ray_u, axis=-1))
    ok &= cosine >= np.cos(np.radians(max_grazing_deg))
    R = cam.cam_from_world[:3, :3]
    nw = n @ R  # camera -> world for row vectors: n_w = R^T n_c
    pw = cam.unproject(grid, depth)
    off = np.sum(nw * pw, axis=-1)
    nw[~ok] = 0.0
    off[~ok] = 0.0
    P = cam.K @ cam.cam_from_world[:3, :]
    void = ~ndimage.binary_dilation(valid, np.ones((3, 3), bool), iterations=SILHOUETTE_PX)
    return ScanMaps(depth.reshape(-1), nw.reshape(-1, 3).astype(np.float32), off.reshape(-1).astype(np.float32),
                    np.where(ok, cosine, 0.0).reshape(-1).astype(np.float32), void.reshape(-1), P,
                    cam.width, cam.height)


def _lookup(m: ScanMaps, x: np.ndarray):
    """Nearest-pixel lookup of voxel centres x (M, 3) float32: (pixel flat index, in-image, z)."""
    P = m.P.astype(np.float32)
    h = x @ P[:, :3].T
    h += P[:, 3]
    z = h[:, 2]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        inv = np.reciprocal(z)
        u = h[:, 0] * inv
        v = h[:, 1] * inv
        u += np.float32(0.5)
        v += np.float32(0.5)
        inb = (z > 0) & (u >= 0) & (u < m.W) & (v >= 0) & (v < m.H)
    ui = np.where(inb, u, 0).astype(np.int32)  # u >= 0 here: truncation is floor
    vi = np.where(inb, v, 0).astype(np.int32)
    return vi * np.int32(m.W) + ui, inb, z


def _samples(m: ScanMaps, x: np.ndarray, trunc: float, refine: bool = False):
    idx, inb, z = _lookup(m, x)
    D = np.where(inb, m.depth[idx], 0.0)
    has = D > 0
    proj = D - z
    cos = np.where(has, m.cosine[idx], 0.0)
    n = m.normal[idx]
    d = np.einsum("ij,ij->i", n, x) - m.offset[idx]
    if refine:
        # one closest-point step: re-sample the plane at the pixel of the foot point x - d n,
        # which removes most of the tangent-plane error on curved surfaces
        idx2, inb2, _ = _lookup(m, (x - d[:, None] * n).astype(np.float32))
        ok2 = inb2 & (m.cosine[idx2] > 0) & (cos > 0)
        n2 = m.normal[idx2]
        d2 = np.einsum("ij,ij->i", n2, x) - m.offset[idx2]
        ok2 &= np.abs(d2 - d) < trunc
        d = np.where(ok2, d2, d)
        n = np.where(ok2[:, None], n2, n)
        cos = np.where(ok2, m.cosine[idx2], cos)
    near = has & (cos > 0) & (np.abs(d) < trunc) & (np.abs(proj) < PROJ_FACTOR * trunc)
    return inb, has, proj, near, d, n, cos, inb & m.void[idx]


@dataclass(frozen=True)
class FusedSdf:
    """A fused signed distance volume of one resolution.

    Attributes:
        values: (L, L, L) float32 signed distance (metres, positive outside) at voxel centres;
            None while the completion (:func:`complete_sdf`) is deferred, see :func:`completed`.
        band: (L, L, L) bool, voxels whose value comes from the fused measurements.
        support: (L, L, L) uint8, scans that support the band value (0 outside the band).
        seen: (L, L, L) uint8, scans in whose image the voxel projects.
        origin, voxel_size, resolution: the grid (see volume.grid).
        near_mask: (L, L, L) bool, voxels with at least one near sample (pass 1).
        measured, measured_mask: the *measured* field Eq. 1 checks (volume.pyramid): at voxels
            with a surface sample, the distance of the nearest-surface cluster of samples chosen
            as in pass 2 but without the quorum (confirmed or not); elsewhere undefined.
        pending: (band values (L, L, L) float32, outside (L, L, L) bool) kept while ``values``
            is None: everything :func:`complete_sdf` needs.
    """

    values: np.ndarray | None
    band: np.ndarray
    support: np.ndarray
    seen: np.ndarray
    origin: np.ndarray
    voxel_size: float
    resolution: int
    near_mask: np.ndarray
    measured: np.ndarray | None = None
    measured_mask: np.ndarray | None = None
    pending: tuple | None = None


def completed(f: FusedSdf, backend: str = "numba") -> FusedSdf:
    """``f`` with its values (the deferred distance-transform completion done; else ``f`` itself)."""
    if f.values is not None:
        return f
    bvals, outside = f.pending
    return replace(f, values=complete_sdf(bvals, f.band, outside, f.voxel_size, backend), pending=None)


def _votes(m: ScanMaps, x: np.ndarray, trunc: float, free_margin: float):
    """Pass-1 votes of one scan for voxel centres x: (seen, free, nodata, occluded, near) bool."""
    idx, inb, z = _lookup(m, x)
    D = np.where(inb, m.depth[idx], np.float32(0))
    has = D > 0
    proj = D - z
    cos = m.cosine[idx]
    aproj = np.abs(proj)
    # a superset of pass 2's test (plane distance ~ |proj| cos for a locally planar surface)
    near = has & (cos > 0) & (aproj < PROJ_FACTOR * trunc) & (aproj * cos < np.float32(NEAR_SLACK * trunc))
    return inb, has & (proj > free_margin), inb & m.void[idx], has & (proj < -trunc), near


def prepare_maps(maps, backend: str):
    """What the backend's passes take: a volume.fusion_jit.PackedMaps for 'numba' (packed once
    per call; pass one in to share it between levels), the list of ScanMaps for 'numpy'."""
    if backend == "numba":
        from volume.fusion_jit import pack_maps

        return pack_maps(maps)
    if not isinstance(maps, (list, tuple)):
        raise TypeError("the numpy fusion backend takes the list of ScanMaps, not packed maps")
    return list(maps)


def carve_votes(maps: list[ScanMaps], origin, w: float, L: int, trunc: float, free_margin: float,
                voxels: np.ndarray | None = None, progress=None, backend: str = "numpy"):
    """Pass 1: counts (free, nodata, occluded, seen, near), uint8 arrays over ``voxels``
    (flat indices into the L^3 grid, C order; None = every voxel)."""
    maps = prepare_maps(maps, backend)
    if backend == "numba":
        from volume.fusion_jit import carve_votes_jit

        return carve_votes_jit(maps, origin, w, L, trunc, free_margin, voxels, PROJ_FACTOR, NEAR_SLACK,
                               PASS1_CHUNK, progress)
    n = L ** 3 if voxels is None else len(voxels)
    free = np.zeros(n, np.uint8)
    nodata = np.zeros(n, np.uint8)
    occ = np.zeros(n, np.uint8)
    seen = np.zeros(n, np.uint8)
    near = np.zeros(n, np.uint8)
    chunks = range(0, n, PASS1_CHUNK)
    for s in (progress(chunks) if progress else chunks):
        e = min(n, s + PASS1_CHUNK)
        if voxels is None:
            x = voxel_centers(origin, w, L, s, e, np.float32)
        else:
            x = _centers_of(voxels[s:e], origin, w, L)
        sl = slice(s, e)
        for m in maps:
            inb, fr, nd, oc, nr = _votes(m, x, trunc, free_margin)
            seen[sl] += inb
            free[sl] += fr
            nodata[sl] += nd
            occ[sl] += oc
            near[sl] += nr
    return free, nodata, occ, seen, near


def _centers_of(flat: np.ndarray, origin, w: float, L: int) -> np.ndarray:
    return voxel_centres(flat_voxel_indices(flat, L), origin, w).astype(np.float32)


def upsample2(a: np.ndarray) -> np.ndarray:
    """(L, L, L) -> (2L, 2L, 2L): every voxel becomes its 8 children."""
    return a.repeat(2, 0).repeat(2, 1).repeat(2, 2)


#: Coarse-to-fine: fine voxels are evaluated where the coarse |d| is within this many coarse
#: voxels (plus the fine truncation), or next to a coarse voxel with a near sample.
COARSE_MARGIN_VOXELS = 1.5


def carve_field(maps: list[ScanMaps], origin, w: float, L: int, cfg: FusionConfig, coarse=None, progress=None):
    """Sign field (outside (L^3,) bool), seen (L^3,) uint8 and near (L^3,) uint8 of pass 1.

    With ``coarse`` (the FusedSdf of resolution L/2 on the same cube) only the fine voxels near
    the coarse surface or coarse near samples are evaluated; the rest inherit the coarse sign
    (their value is then filled by the distance transform anyway).
    """
    trunc = cfg.trunc(w)
    n = L ** 3
    if coarse is None or coarse.resolution * 2 != L:
        free, nodata, occ, seen, near = carve_votes(maps, origin, w, L, trunc, cfg.agree(w), None, progress,
                                                    cfg.backend)
        return carve_sign(free, nodata, occ, seen, cfg, len(maps)), seen, near
    wc = coarse.voxel_size
    keep = (np.abs(coarse.values) <= COARSE_MARGIN_VOXELS * wc + trunc) | coarse.near_mask
    cand = np.nonzero(upsample2(keep).reshape(-1))[0]
    outside = upsample2(coarse.values > 0).reshape(-1)
    seen = upsample2(coarse.seen).reshape(-1).copy()
    near = np.zeros(n, np.uint8)
    free, nodata, occ, sn, nr = carve_votes(maps, origin, w, L, trunc, cfg.agree(w), cand, progress, cfg.backend)
    outside[cand] = carve_sign(free, nodata, occ, sn, cfg, len(maps))
    seen[cand] = sn
    near[cand] = nr
    return outside, seen, near


def carve_sign(free, nodata, occ, seen, cfg: FusionConfig, n_scans: int) -> np.ndarray:
    """True where the votes say outside (docs/methods.md §1.1; step 4 of the module docstring).

    Measured free space is strong evidence: ``carve_quorum`` views (capped by the views that
    contain x) carve.  No-return pixels are weak (they include holes): they count with the
    free votes only when they also reach ``carve_ratio`` of the views that saw x occluded.
    Voxels that fewer than min(carve_quorum, n_scans) views contain are outside: nothing can
    be said about them, and calling them inside would grow walls where the frusta end.
    """
    q = np.minimum(cfg.carve_quorum, seen.astype(np.int32))
    empty = free.astype(np.int32) + nodata
    strong = (free >= q) & (free > 0)
    # weak votes: no quorum beyond carve_ratio * occluded, which keeps voxels hidden in most
    # views (the interior) from being carved by holes; at the periphery of the frusta a
    # single clear no-return view is all the evidence there is
    weak = (empty >= cfg.carve_ratio * occ) & (empty > 0)
    return strong | weak | (seen < min(cfg.carve_quorum, n_scans))


def gather_samples(maps: list[ScanMaps], x: np.ndarray, trunc: float):
    """Every scan's sample for band voxels x (M, 3) float32: d (M,S) plane distance, nrm (M,S,3),
    cw (M,S) view cosine, ok (M,S) usable near sample, fr (M,) scans that see through x."""
    M, S = len(x), len(maps)
    d = np.zeros((M, S), np.float32)
    nrm = np.zeros((M, S, 3), np.float32)
    cw = np.zeros((M, S), np.float32)
    ok = np.zeros((M, S), bool)
    fr = np.zeros(M, np.int32)
    for k, m in enumerate(maps):
        _, has, proj, nr, dk, nk, ck, _ = _samples(m, x, trunc, refine=True)
        d[:, k], nrm[:, k], cw[:, k], ok[:, k] = dk, nk, ck, nr
        fr += has & (proj > trunc)
    return d, nrm, cw, ok, fr


def consensus_from_samples(d, nrm, cw, ok, fr, n_see, cfg: FusionConfig, w: float):
    """Step 3 of the module docstring, vectorised over voxels and sample pairs.

    Returns (has consensus, value, support, has a nearest cluster, its value without quorum);
    :func:`volume.fusion_reference.consensus_reference` is the per-voxel loop it is tested against.
    """
    agree_d = cfg.agree(w)
    nn = np.matmul(nrm, nrm.transpose(0, 2, 1))  # (M, S, S) normal dot products
    pos2 = d[:, :, None] ** 2 + d[:, None, :] ** 2 - 2 * d[:, :, None] * d[:, None, :] * nn
    agree = (nn > np.cos(np.radians(cfg.agree_normal_deg))) & (pos2 < agree_d ** 2)
    agree &= ok[:, :, None] & ok[:, None, :]
    count = agree.sum(2)
    quorum = np.clip(np.minimum(cfg.quorum, n_see), 1, None)
    has_c, value, support = _nearest_cluster(d, cw, agree, ok & (count >= quorum[:, None]))
    has_c &= fr <= support  # more scans see through x than support it: not a surface
    # the same choice without the quorum: the unconfirmed measurement Eq. 1 looks at
    has1, value1, _ = _nearest_cluster(d, cw, agree, ok)
    return has_c, value.astype(np.float32), support, has1, value1.astype(np.float32)


def _nearest_cluster(d, cw, agree, cand):
    """Per voxel, the candidate sample nearest to it (smallest |d| among ``cand`` (M, S)) and the
    samples agreeing with it: (has one (M,), their view-cosine-weighted mean d, their count)."""
    M = len(d)
    key = np.where(cand, np.abs(d), np.inf)
    c = np.argmin(key, axis=1)
    has = np.isfinite(key[np.arange(M), c])
    members = agree[np.arange(M), c, :] & has[:, None]
    wsum = (members * cw).sum(1)
    value = np.where(wsum > 0, (members * cw * d).sum(1) / np.where(wsum > 0, wsum, 1), 0.0)
    return has, value, members.sum(1)


def consensus_band(maps: list[ScanMaps], x: np.ndarray, trunc: float, cfg: FusionConfig, w: float,
                   n_see: np.ndarray):
    """Pass 2 for band voxels x (M, 3): see :func:`consensus_from_samples`."""
    return consensus_from_samples(*gather_samples(maps, x, trunc), n_see, cfg, w)


def fuse_consensus(scanset: ScanSet, origin, voxel_size: float, resolution: int, cfg: FusionConfig | None = None,
                   maps: list[ScanMaps] | None = None, coarse: FusedSdf | None = None, progress=None,
                   complete: bool = True) -> FusedSdf:
    """Consensus signed distance volume of ``scanset`` on the given grid (module docstring).

    ``coarse``: the volume of resolution L/2 on the same cube, to evaluate pass 1 only near
    its surface (coarse-to-fine; see :func:`carve_field`).  ``complete=False`` defers step 5
    (the distance transforms, most of the cost at 256^3): ``values`` is None until
    :func:`completed`; the measured field Eq. 1 reads is there either way.
    """
    cfg = cfg or FusionConfig()
    L, w = int(resolution), float(voxel_size)
    origin = np.asarray(origin, np.float64)
    trunc = cfg.trunc(w)
    maps = maps if maps is not None else [scan_maps(s, cfg.max_grazing_deg, cfg.smooth_sigma_z) for s in scanset.scans]
    maps = prepare_maps(maps, cfg.backend)
    outside, seen, near = carve_field(maps, origin, w, L, cfg, coarse, progress)
    cand = np.nonzero(near)[0]
    band = np.zeros(L ** 3, bool)
    bvals = np.zeros(L ** 3, np.float32)
    support = np.zeros(L ** 3, np.uint8)
    meas = np.zeros(L ** 3, np.float32)
    mmask = np.zeros(L ** 3, bool)
    # the quorum drops only to the number of scans whose image contains x (a lone scan counts)
    n_obs = seen[cand].astype(np.int32)
    if cfg.backend == "numba":
        from volume.fusion_jit import consensus_jit

        parts = [(cand, consensus_jit(maps, cand, origin, w, L, n_obs, trunc, PROJ_FACTOR, cfg.agree(w),
                                      cfg.agree_normal_deg, cfg.quorum))]
    else:
        xc = _centers_of(cand, origin, w, L)
        parts = ((cand[s:s + PASS2_CHUNK], consensus_band(maps, xc[s:s + PASS2_CHUNK], trunc, cfg, w,
                                                          n_obs[s:s + PASS2_CHUNK]))
                 for s in range(0, len(cand), PASS2_CHUNK))
    for cs, (has, val, sup, has1, val1) in parts:
        # unconfirmed samples may say "in front of a surface" (outside), never "inside"
        outside[cs[~has & has1 & (val1 > 0)]] = True
        i1 = cs[has1]
        meas[i1] = val1[has1]
        mmask[i1] = True
        idx = cs[has]
        band[idx] = True
        bvals[idx] = np.clip(val[has], -trunc, trunc)
        support[idx] = sup[has]
    shape = (L, L, L)
    f = FusedSdf(None, band.reshape(shape), support.reshape(shape), seen.reshape(shape), origin, w, L,
                 (near > 0).reshape(shape), meas.reshape(shape), mmask.reshape(shape),
                 (bvals.reshape(shape), outside.reshape(shape)))
    return completed(f, cfg.backend) if complete else f

"""Compiled (numba) kernels of the consensus fusion's two passes (docs/methods.md §1.1; volume.fusion).

The vectorised numpy passes of :mod:`volume.fusion` evaluate every (voxel, scan) pair with
some thirty array operations and every pair of samples of a band voxel (S^2 per voxel, most
of them not near samples on fur); these loops do the same arithmetic per voxel and stop early:
a scan the voxel does not project into costs one projection, and the agreement of pass 2 runs
over the near samples only.  Same float32 arithmetic and thresholds as the numpy passes, which
stay as the reference (``FusionConfig.backend = "numpy"``) and are compared with these in
tests/volume/test_fusion_jit.py: votes, samples and consensus agree except where a float32
projection lands within rounding of a pixel edge or a threshold (stated tolerances there).

Scans are packed once per fusion (:func:`pack_maps`): per-pixel arrays concatenated, with
each scan's first pixel, width and height.  A scan's records may cover only a rectangle of its
image (``PackedMaps.rect``: the object's footprint plus a margin, volume.stream): a pixel of the
image outside it reads the shared record VOID_ROW (no depth, a clear no-return), which is what a
full-frame map holds there when the rectangle keeps every pixel within SILHOUETTE_PX of a depth.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
from numba import njit

#: numba compiles each kernel once per machine and caches it beside this file (__pycache__).
JIT_OPTIONS = {"cache": True, "nogil": True, "error_model": "numpy"}
#: Voxels visited together, scan by scan (one scan's images stay in the cache).
BLOCK = 4096
#: Threads of both passes (None: the cores this process may run on; 1: one, as before).  Each voxel's
#: votes and consensus are its own, so chunks of voxels run side by side with the same results.
FUSE_THREADS: int | None = None


#: Columns of PackedMaps.pixel: one 32-byte record per pixel, so a lookup touches one cache line.
DEPTH, COSINE, OFFSET, NX, NY, NZ, VOID = range(7)
RECORD = 8
#: Row of PackedMaps.pixel read by every pixel outside a scan's rectangle: no depth, void.
VOID_ROW = 0


@dataclass(frozen=True)
class PackedMaps:
    """Every scan's ScanMaps (volume.fusion) packed into one array of pixel records.

    Attributes:
        pixel: (1 + sum of w*h, RECORD) float32: depth (m), cosine, plane offset (m), world normal
            (3), void (1.0 = a clear no-return); row VOID_ROW is the shared empty record, then
            one row per pixel of each scan's rectangle in turn (row-major).
        P: (S, 3, 4) float32 projections; start: (S,) int64 first row of each scan;
        W, H: (S,) int64 image sizes.
        rect: (S, 4) int64 (x0, y0, w, h) of each scan's rectangle of records (pixels).
    """

    pixel: np.ndarray
    P: np.ndarray
    start: np.ndarray
    W: np.ndarray
    H: np.ndarray
    rect: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.rect is None:
            object.__setattr__(self, "rect", np.stack([np.zeros_like(self.W), np.zeros_like(self.W), self.W, self.H],
                                                      axis=1).reshape(-1, 4).astype(np.int64))

    def __len__(self) -> int:
        return len(self.start)


def pack_maps(maps) -> PackedMaps:
    """PackedMaps of a list of volume.fusion.ScanMaps (or the PackedMaps itself)."""
    if isinstance(maps, PackedMaps):
        return maps
    maps = list(maps)
    sizes = np.array([len(m.depth) for m in maps], np.int64)
    start = 1 + np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64) if maps else np.zeros(0, np.int64)
    pixel = empty_records(int(sizes.sum()))
    for m, a in zip(maps, start):
        write_records(pixel[a:a + len(m.depth)], m)
    P = np.stack([np.asarray(m.P, np.float32) for m in maps]) if maps else np.zeros((0, 3, 4), np.float32)
    return PackedMaps(pixel, np.ascontiguousarray(P), start, np.array([m.W for m in maps], np.int64),
                      np.array([m.H for m in maps], np.int64))


def empty_records(n: int) -> np.ndarray:
    """(1 + n, RECORD) float32 records, zero, with row VOID_ROW the shared void record."""
    pixel = np.zeros((1 + n, RECORD), np.float32)
    pixel[VOID_ROW, VOID] = 1.0
    return pixel


def write_records(rows: np.ndarray, m) -> None:
    """Fill ``rows`` (len(m.depth), RECORD) from a volume.fusion.ScanMaps."""
    rows[:, DEPTH], rows[:, COSINE], rows[:, OFFSET] = m.depth, m.cosine, m.offset
    rows[:, NX:NZ + 1] = m.normal
    rows[:, VOID] = m.void


@njit(**JIT_OPTIONS)
def _center(flat, origin, w, L):
    """World centre (float32, computed in float64 as volume.fusion._centers_of) of a flat voxel index."""
    i = flat // (L * L)
    r = flat - i * L * L
    j = r // L
    k = r - j * L
    return (np.float32(origin[0] + (i + 0.5) * w), np.float32(origin[1] + (j + 0.5) * w),
            np.float32(origin[2] + (k + 0.5) * w))


@njit(**JIT_OPTIONS)
def _scan(P, W, H, rect, start, s):
    """Scan s's projection as a tuple (12 float32 entries of P, width and height as float32,
    its rectangle (x0, y0, w, h) and first row as integers), hoisted out of the voxel loops."""
    return ((P[s, 0, 0], P[s, 0, 1], P[s, 0, 2], P[s, 0, 3], P[s, 1, 0], P[s, 1, 1], P[s, 1, 2], P[s, 1, 3],
             P[s, 2, 0], P[s, 2, 1], P[s, 2, 2], P[s, 2, 3]), np.float32(W[s]), np.float32(H[s]),
            (rect[s, 0], rect[s, 1], rect[s, 2], rect[s, 3]), start[s])


@njit(**JIT_OPTIONS)
def _project(scan, x0, x1, x2):
    """(row of the pixel's record, VOID_ROW outside the scan's rectangle, or -1 outside the
    image; z) of a float32 point, as volume.fusion._lookup."""
    p, Wf, Hf, r, first = scan
    z = p[8] * x0 + p[9] * x1 + p[10] * x2 + p[11]
    inv = np.float32(1.0) / z
    u = (p[0] * x0 + p[1] * x1 + p[2] * x2 + p[3]) * inv + np.float32(0.5)
    v = (p[4] * x0 + p[5] * x1 + p[6] * x2 + p[7]) * inv + np.float32(0.5)
    if z > 0 and u >= 0 and u < Wf and v >= 0 and v < Hf:
        iu = int(u) - r[0]
        iv = int(v) - r[1]
        if iu < 0 or iv < 0 or iu >= r[2] or iv >= r[3]:
            return VOID_ROW, z
        return first + iv * r[2] + iu, z
    return -1, z


@njit(**JIT_OPTIONS)
def _centers(flat, lo, hi, origin, w, L, xs):
    """Centres of the voxels flat[lo:hi] into xs[:hi - lo] (float32, as volume.fusion._centers_of)."""
    for t in range(lo, hi):
        xs[t - lo, 0], xs[t - lo, 1], xs[t - lo, 2] = _center(flat[t], origin, w, L)


@njit(**JIT_OPTIONS)
def pass1_votes(flat, origin, w, L, pixel, P, start, W, H, rect, trunc, free_margin, proj_factor,
                near_slack, free, nodata, occ, seen, near):
    """Pass 1 (volume.fusion.carve_votes) for the voxels ``flat``: adds each scan's votes into
    the uint8 counters (free, nodata, occluded, seen, near), indexed like ``flat``.  Blocks of
    BLOCK voxels are visited scan by scan, so one image at a time is in the cache."""
    tr = np.float32(trunc)
    fm = np.float32(free_margin)
    lim_proj = np.float32(proj_factor * trunc)
    lim_near = np.float32(near_slack * trunc)
    xs = np.empty((BLOCK, 3), np.float32)
    for lo in range(0, len(flat), BLOCK):
        hi = min(len(flat), lo + BLOCK)
        _centers(flat, lo, hi, origin, w, L, xs)
        for s in range(len(start)):
            scan = _scan(P, W, H, rect, start, s)
            for t in range(lo, hi):
                px, z = _project(scan, xs[t - lo, 0], xs[t - lo, 1], xs[t - lo, 2])
                if px < 0:
                    continue
                rec = pixel[px]
                seen[t] += 1
                if rec[VOID] > 0:
                    nodata[t] += 1
                D = rec[DEPTH]
                if D > 0:
                    proj = D - z
                    if proj > fm:
                        free[t] += 1
                    if proj < -tr:
                        occ[t] += 1
                    c = rec[COSINE]
                    a = abs(proj)
                    if c > 0 and a < lim_proj and a * c < lim_near:
                        near[t] += 1


@njit(**JIT_OPTIONS)
def _sample(x0, x1, x2, scan, pixel, tr, lim_proj):
    """One scan's refined sample of a voxel (volume.fusion._samples, refine=True):
    (near, d, n0, n1, n2, cos, sees through)."""
    px, z = _project(scan, x0, x1, x2)
    if px < 0:
        return False, np.float32(0), np.float32(0), np.float32(0), np.float32(0), np.float32(0), False
    rec = pixel[px]
    D = rec[DEPTH]
    has = D > 0
    proj = D - z
    through = has and proj > tr
    cos = rec[COSINE] if has else np.float32(0)
    n0, n1, n2 = rec[NX], rec[NY], rec[NZ]
    d = n0 * x0 + n1 * x1 + n2 * x2 - rec[OFFSET]
    # one closest-point step at the pixel of the foot point x - d n
    f0, f1, f2 = x0 - d * n0, x1 - d * n1, x2 - d * n2
    px2, _ = _project(scan, f0, f1, f2)
    if px2 >= 0 and cos > 0:
        r2 = pixel[px2]
        if r2[COSINE] > 0:
            m0, m1, m2 = r2[NX], r2[NY], r2[NZ]
            d2 = m0 * x0 + m1 * x1 + m2 * x2 - r2[OFFSET]
            if abs(d2 - d) < tr:
                d, n0, n1, n2, cos = d2, m0, m1, m2, r2[COSINE]
    near = has and cos > 0 and abs(d) < tr and abs(proj) < lim_proj
    return near, d, n0, n1, n2, cos, through


@njit(**JIT_OPTIONS)
def _cluster(c, cnt, d, nrm, cw, cos_n, agree2):
    """(support, cosine-weighted mean d) of the samples agreeing with sample ``c``."""
    sup = 0
    ws = np.float32(0)
    wd = np.float32(0)
    for j in range(cnt):
        nn = nrm[c, 0] * nrm[j, 0] + nrm[c, 1] * nrm[j, 1] + nrm[c, 2] * nrm[j, 2]
        pos2 = d[c] * d[c] + d[j] * d[j] - np.float32(2) * d[c] * d[j] * nn
        if nn > cos_n and pos2 < agree2:
            sup += 1
            ws += cw[j]
            wd += cw[j] * d[j]
    return sup, (wd / ws if ws > 0 else np.float32(0))


@njit(**JIT_OPTIONS)
def pass2_consensus(flat, origin, w, L, n_see, pixel, P, start, W, H, rect, trunc, proj_factor,
                    agree_d, cos_normal, quorum, has_c, value, support, has1, value1):
    """Pass 2 (volume.fusion.consensus_band) for the band voxels ``flat``: fills has_c, value,
    support, has1, value1 (the arrays of volume.fusion.consensus_from_samples).  Samples are
    gathered scan by scan over blocks of BLOCK voxels (cache), then each voxel's near samples
    are compared pairwise."""
    S = len(start)
    tr = np.float32(trunc)
    lim_proj = np.float32(proj_factor * trunc)
    agree2 = np.float32(agree_d * agree_d)
    cos_n = np.float32(cos_normal)
    xs = np.empty((BLOCK, 3), np.float32)
    d = np.empty((BLOCK, S), np.float32)
    nrm = np.empty((BLOCK, S, 3), np.float32)
    cw = np.empty((BLOCK, S), np.float32)
    cnt = np.zeros(BLOCK, np.int64)
    fr = np.zeros(BLOCK, np.int64)
    for lo in range(0, len(flat), BLOCK):
        hi = min(len(flat), lo + BLOCK)
        _centers(flat, lo, hi, origin, w, L, xs)
        cnt[:] = 0
        fr[:] = 0
        for s in range(S):
            scan = _scan(P, W, H, rect, start, s)
            for b in range(hi - lo):
                ok, ds, a0, a1, a2, cs, through = _sample(xs[b, 0], xs[b, 1], xs[b, 2], scan, pixel, tr, lim_proj)
                fr[b] += through
                if ok:
                    k = cnt[b]
                    d[b, k], nrm[b, k, 0], nrm[b, k, 1], nrm[b, k, 2], cw[b, k] = ds, a0, a1, a2, cs
                    cnt[b] = k + 1
        for b in range(hi - lo):
            _consensus_one(lo + b, cnt[b], fr[b], d[b], nrm[b], cw[b], n_see, quorum, cos_n, agree2,
                           has_c, value, support, has1, value1)


@njit(**JIT_OPTIONS)
def _consensus_one(t, cnt, fr, d, nrm, cw, n_see, quorum, cos_n, agree2, has_c, value, support, has1, value1):
    """Step 3 of volume.fusion's docstring for one voxel's ``cnt`` near samples (scan order)."""
    q = max(min(quorum, n_see[t]), 1)
    best = -1
    best1 = -1
    for i in range(cnt):
        if best1 < 0 or abs(d[i]) < abs(d[best1]):
            best1 = i
        if best >= 0 and not abs(d[i]) < abs(d[best]):
            continue
        count = 0
        for j in range(cnt):
            nn = nrm[i, 0] * nrm[j, 0] + nrm[i, 1] * nrm[j, 1] + nrm[i, 2] * nrm[j, 2]
            pos2 = d[i] * d[i] + d[j] * d[j] - np.float32(2) * d[i] * d[j] * nn
            count += nn > cos_n and pos2 < agree2
        if count >= q:
            best = i
    if best >= 0:
        sup, val = _cluster(best, cnt, d, nrm, cw, cos_n, agree2)
        has_c[t] = fr <= sup
        value[t] = val
        support[t] = sup
    if best1 >= 0:
        has1[t] = True
        value1[t] = _cluster(best1, cnt, d, nrm, cw, cos_n, agree2)[1]


def carve_votes_jit(pm: PackedMaps, origin, w: float, L: int, trunc: float, free_margin: float,
                    voxels: np.ndarray | None, proj_factor: float, near_slack: float, chunk: int, progress=None):
    """Pass-1 counts (free, nodata, occluded, seen, near) uint8 over ``voxels`` (flat indices;
    None = every voxel), as volume.fusion.carve_votes."""
    n = L ** 3 if voxels is None else len(voxels)
    out = [np.zeros(n, np.uint8) for _ in range(5)]
    o = np.asarray(origin, np.float64)
    step = max(1, min(chunk, -(-n // (2 * fuse_threads()))))  # at least two chunks a thread

    def one(s):
        e = min(n, s + step)
        flat = np.arange(s, e, dtype=np.int64) if voxels is None else np.asarray(voxels[s:e], np.int64)
        pass1_votes(flat, o, float(w), int(L), pm.pixel, pm.P, pm.start, pm.W, pm.H, pm.rect,
                    float(trunc), float(free_margin), float(proj_factor), float(near_slack),
                    *(a[s:e] for a in out))

    _side_by_side(one, range(0, n, step), progress)
    return tuple(out)


def fuse_threads() -> int:
    """Threads of the two passes: FUSE_THREADS, else the cores this process may run on."""
    from capture.plate_threads import cores

    if FUSE_THREADS is not None:
        return max(1, int(FUSE_THREADS))
    return cores()


def _side_by_side(fn, starts, progress=None) -> None:
    """``fn(start)`` for every chunk start on fuse_threads() threads (each writes its own slice of
    the outputs; the kernels let go of the GIL), ``progress`` wrapping the chunks as they finish."""
    starts = list(starts)
    n = fuse_threads()
    if n == 1 or len(starts) < 2:
        for s in (progress(starts) if progress else starts):
            fn(s)
        return
    with ThreadPoolExecutor(n, thread_name_prefix="fuse") as pool:
        futures = [pool.submit(fn, s) for s in starts]
        for f in (progress(futures) if progress else futures):
            f.result()


def consensus_jit(pm: PackedMaps, flat: np.ndarray, origin, w: float, L: int, n_see: np.ndarray, trunc: float,
                  proj_factor: float, agree_d: float, agree_normal_deg: float, quorum: int):
    """Pass 2 for band voxels (flat indices): (has consensus, value, support, has a nearest
    cluster, its value) as volume.fusion.consensus_band."""
    M = len(flat)
    has_c, value, support = np.zeros(M, bool), np.zeros(M, np.float32), np.zeros(M, np.int64)
    has1, value1 = np.zeros(M, bool), np.zeros(M, np.float32)
    flat, n_see = np.asarray(flat, np.int64), np.asarray(n_see, np.int64)
    o = np.asarray(origin, np.float64)
    step = max(BLOCK, -(-M // (4 * fuse_threads())))  # band voxels cost unevenly: four chunks a thread

    def one(s):
        sl = slice(s, min(M, s + step))
        pass2_consensus(flat[sl], o, float(w), int(L), n_see[sl], pm.pixel, pm.P, pm.start, pm.W, pm.H, pm.rect,
                        float(trunc), float(proj_factor), float(agree_d), math.cos(math.radians(agree_normal_deg)),
                        int(quorum), has_c[sl], value[sl], support[sl], has1[sl], value1[sl])

    _side_by_side(one, range(0, M, step))
    return has_c, value, support, has1, value1

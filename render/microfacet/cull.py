"""Exact culling of microfacet slice tiles: numpy twin of ``microfacet/shaders/microfacet_cull.glsl``.

On llvmpipe a fragment costs the whole shader whatever its branches take (only the early depth
test skips work), and most slice fragments are discarded by Eq. 2: on the fur ball at E = 8 the
slices of the 8^3 level rasterise 48 fragments per visible pixel, 12 % of them alive.  So the
compute pass splits every slice quad into G x G tiles of about TILE_PX drawn pixels and keeps
only the tiles where a fragment *can* be drawn (docs/methods.md §1.4):

* a fragment passes camera i only if that camera's RGBz depth d at the fragment's nearest texel
  is valid (d > 0) and |d - D| < l/2, D the fragment's own z-depth in camera i;
* on a tile (a rectangle of the slice plane) D is affine, so it lies between the smallest and
  largest D of the tile's four corners, and the nearest texels of its fragments lie in the
  pixel box of the corners' projections (convex: every corner in front of the camera);
* the min / max of the valid depths over that box come from a min / max pyramid of each depth
  map (:func:`depth_bounds_pyramid`, at most 3 x 3 blocks read per camera and tile).

A fragment is drawn only if one of the first K_BLEND + N_FALLBACK candidates passes it (the
"vote" and "any" rules of microfacet_geometry.shade_fragments both need a PASS), and under
"vote" only if the passing blend weight is at least ALPHA_VOTE of the seeing weight: a tile on
which no candidate can pass, or where the blend cameras certain to see through it outvote those
that may pass (:func:`tiles_drawable`), holds no drawn fragment: dropping it changes nothing in
the frame (tests/render/microfacet/test_microfacet_cull.py compares culled and unculled frames).  These
are shade()'s rules restated as bounds: a change to them must change :func:`tiles_drawable`
and tile_drawable() in the shader too (the frame comparisons fail otherwise).  A camera with a
tile corner behind it never culls the tile (the pixel box is then unbounded); the part of a box
outside the image is dropped (fragments there are NO_VIEW in that camera).
"""

from __future__ import annotations

import numpy as np

from render.microfacet import geometry as mg

#: Target side of a slice tile in drawn (supersampled) pixels.  The slices of the fur ball's 8^3
#: level span ~100 output pixels; measured there (prepass CPU ms, 1x1 / 2x2 samples): tiles of
#: 8 px 59 / 108, 16 px 38 / 90, 32 px 34 / 94, 64 px 35 / 115, whole slices 42 / 148
#: (render.json of furrow bench render; smaller tiles cull more but cost more primitives).
TILE_PX = 32.0
#: Most tiles per slice side.
MAX_TILES = 16
#: Margin added around the pixel box of a tile's corners (pixels; float32 interpolation noise).
PIX_MARGIN = 0.01
#: Margin added to the Eq. 2 tolerance in the cull test: relative, and absolute (metres).
TOL_MARGIN_REL = 1e-4
TOL_MARGIN_ABS = 1e-5
#: Stored "min" of a block without a valid depth (the largest half float: no D lies above it).
EMPTY_MIN = 65504.0
#: Blocks per axis read from the depth-bounds pyramid per box (the finest level where it fits).
BOUND_BLOCKS = 3
#: Margin of the vote test (float32 sums of the weights on the GPU).
VOTE_MARGIN = 1e-6


def depth_bounds_pyramid(depth: np.ndarray) -> list[np.ndarray]:
    """Min / max pyramid of depth maps.

    Args:
        depth: (N, H, W) z-depths in metres as the GPU stores them (0 = none).
    Returns:
        levels k = 0 .. K: (N, ceil(H / 2^k), ceil(W / 2^k), 2) float32, [..., 0] the smallest and
        [..., 1] the largest valid depth of each 2^k x 2^k block; (EMPTY_MIN, 0) where the block has
        none.  The last level is 1 x 1.
    """
    d = np.asarray(depth, np.float32)
    if d.ndim != 3:
        raise ValueError(f"depth maps must be (N, H, W), got {d.shape}")
    valid = d > 0
    lv = np.stack([np.where(valid, d, EMPTY_MIN), np.where(valid, d, 0.0)], axis=-1).astype(np.float32)
    levels = [lv]
    while lv.shape[1] > 1 or lv.shape[2] > 1:
        n, h, w, _ = lv.shape
        pad = np.empty((n, h + h % 2, w + w % 2, 2), np.float32)
        pad[..., 0], pad[..., 1] = EMPTY_MIN, 0.0
        pad[:, :h, :w] = lv
        blocks = pad.reshape(n, pad.shape[1] // 2, 2, pad.shape[2] // 2, 2, 2)
        lv = np.stack([blocks[..., 0].min(axis=(2, 4)), blocks[..., 1].max(axis=(2, 4))], axis=-1)
        levels.append(lv)
    return levels


def pack_pyramid(levels: list[np.ndarray]) -> tuple[np.ndarray, list[int]]:
    """The pyramid as the GPU reads it: a flat uint32 array (per level, camera-major, rows,
    columns; each word = half(min) | half(max) << 16, GLSL packHalf2x16) and the word offset of
    every level.  The depths must be representable in half floats (the RGBz texture's)."""
    words, offsets, at = [], [], 0
    for lv in levels:
        h = lv.astype(np.float16)
        if not np.array_equal(h.astype(np.float32), lv):
            raise ValueError("depth bounds must be half floats (the RGBz depths as the GPU stores them)")
        u = h.view(np.uint16).astype(np.uint32)
        words.append((u[..., 0] | (u[..., 1] << 16)).reshape(-1))
        offsets.append(at)
        at += words[-1].size
    return np.concatenate(words), offsets


def block_bounds(levels: list[np.ndarray], cam: int, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(T, 2) min / max of the valid depths of camera ``cam`` over the pixel boxes [lo, hi]
    ((T, 2) inclusive x, y): read from the finest level k where each box spans at most
    BOUND_BLOCKS blocks per axis (2^k <= span < 2^(k+1); a superset of the box: conservative)."""
    span = np.max(hi - lo, axis=1)
    k = np.where(span > 1, np.floor(np.log2(np.maximum(span, 1))).astype(np.int64), 0)
    k = np.minimum(k, len(levels) - 1)
    out = np.empty((len(lo), 2), np.float32)
    for kk in np.unique(k):
        m = k == kk
        lv = levels[kk][cam]
        a, b = lo[m] >> kk, hi[m] >> kk
        mins = np.full(m.sum(), EMPTY_MIN, np.float32)
        maxs = np.zeros(m.sum(), np.float32)
        for dy in range(BOUND_BLOCKS):
            for dx in range(BOUND_BLOCKS):
                x = np.minimum(a[:, 0] + dx, b[:, 0])
                y = np.minimum(a[:, 1] + dy, b[:, 1])
                mins = np.minimum(mins, lv[y, x, 0])
                maxs = np.maximum(maxs, lv[y, x, 1])
        out[m, 0], out[m, 1] = mins, maxs
    return out


def cull_tolerance(spacing: float) -> float:
    """Eq. 2's tolerance l/2 grown by the cull margins."""
    return 0.5 * spacing * (1.0 + TOL_MARGIN_REL) + TOL_MARGIN_ABS


def tile_tests(cam, levels: list[np.ndarray], cam_index: int, corners: np.ndarray, spacing: float):
    """What camera ``cam`` (index ``cam_index`` in the pyramid) can say on each tile, given its
    (T, 4, 3) world corners: (may_pass, free), two (T,) bool arrays -- it may pass Eq. 2
    somewhere on the tile; it certainly sees through all of it (the tile's pixel box inside its
    image, and no depth there or a depth at least FREE_FACTOR l/2 behind every point: FREE)."""
    T = len(corners)
    pr = mg.project_h(cam, corners.reshape(-1, 3)).reshape(T, 4, 3)
    z = pr[..., 2]
    behind = (z <= 0).any(axis=1)
    zs = np.where(z > 0, z, 1.0)
    size = np.array([cam.width, cam.height])
    uv = np.clip(pr[..., :2] / zs[..., None], -2.0, float(size.sum()) + 2.0)  # as the shader, before int
    lo0 = np.floor(uv.min(axis=1) + 0.5 - PIX_MARGIN).astype(np.int64)
    hi0 = np.floor(uv.max(axis=1) + 0.5 + PIX_MARGIN).astype(np.int64)
    lo, hi = np.maximum(lo0, 0), np.minimum(hi0, size - 1)
    inside = (lo == lo0).all(axis=1) & (hi == hi0).all(axis=1)
    ok = ~behind & ~(hi < lo).any(axis=1)
    tol = cull_tolerance(spacing)
    may, free = behind.copy(), np.zeros(T, bool)
    if ok.any():
        bb = block_bounds(levels, cam_index, lo[ok], hi[ok])
        zmin, zmax = z[ok].min(axis=1), z[ok].max(axis=1)
        may[ok] = (bb[:, 1] > zmin - tol) & (bb[:, 0] < zmax + tol)
        free[ok] = inside[ok] & (bb[:, 0] >= zmax + mg.FREE_FACTOR * tol)
    return may, free


def tiles_drawable(may: np.ndarray, free: np.ndarray, weights: np.ndarray, rule: str = "vote") -> np.ndarray:
    """(T,) bool: can a fragment of each tile be drawn (shade_fragments' rules)?

    Args:
        may, free: (T, N) tile_tests of the first N = K_BLEND + n_fallback candidates (False
            for missing candidates).
        weights: (K_BLEND,) the voxel's blend weights.
        rule: "vote": the blend cameras certain to see through a tile (weight F) outvote those
            that may pass it (weight P) when P (1 - ALPHA_VOTE) < ALPHA_VOTE F - VOTE_MARGIN
            (F > 0 is seen weight, so the fallback never runs); else, and under "any", some
            candidate must be able to pass.
    """
    any_pass = may.any(axis=1)
    if rule != "vote":
        return any_pass
    k = mg.K_BLEND
    P = (may[:, :k] * weights).sum(axis=1)
    F = (free[:, :k] * weights).sum(axis=1)
    outvoted = (F > mg.WEIGHT_EPS) & (P * (1 - mg.ALPHA_VOTE) < mg.ALPHA_VOTE * F - VOTE_MARGIN)
    return any_pass & ~outvoted


def tile_count(half_extents: np.ndarray, s: np.ndarray, focal: float, tile_px: float = TILE_PX) -> np.ndarray:
    """Tiles per side of each slice: its larger side on screen (``focal`` px per unit of
    depth s) over ``tile_px``, rounded up, in 1..MAX_TILES."""
    side = 2.0 * np.max(np.atleast_2d(half_extents), axis=1) * focal / np.maximum(s, 1e-12)
    return np.clip(np.ceil(side / tile_px), 1, MAX_TILES).astype(np.int64)


def tile_edges(half: float, g: int) -> np.ndarray:
    """(g + 1,) tile edges of a half extent split g ways: half * (-1 + 2 i / g)."""
    return np.array([half * (-1.0 + 2.0 * i / g) for i in range(g + 1)])


def select_tiles(centers: np.ndarray, w: float, eye_pos: np.ndarray, eye_right: np.ndarray, eye_up: np.ndarray,
                 spacing: float, near: float, cameras, levels: list[np.ndarray], focal: float,
                 tile_px: float = TILE_PX, n_fallback: int | None = None, rule: str = "vote") -> dict:
    """The tiles the compute pass draws (twin of microfacet_select.glsl with culling).

    Returns a dict of arrays, one row per kept tile: ``voxel`` and ``n`` (the slice), ``rect``
    (M, 4) = (x0, x1, y0, y1) its extent along the slice axes a, b (metres, the slice centre at 0).
    """
    n_proj = mg.K_BLEND + (mg.N_FALLBACK if n_fallback is None else int(n_fallback))
    c = np.asarray(centers, np.float64).reshape(-1, 3)
    vox, n = mg.slice_distances(c, w, eye_pos, spacing, near)
    v, a, b = mg.slice_frame(c, eye_pos, eye_right, eye_up)
    idx, wts = mg.select_cameras(c, mg.footprint_radius(w), eye_pos, cameras)
    s = n * spacing
    ha, hb = mg.slice_half_extents(c[vox], w, eye_pos, v[vox], a[vox], b[vox], s)
    g = tile_count(np.stack([ha, hb], 1), s, focal, tile_px)
    rows = {"voxel": [np.zeros(0, np.int64)], "n": [np.zeros(0, np.int64)], "rect": [np.zeros((0, 4))]}
    for j in range(len(vox)):
        ea, eb = tile_edges(ha[j], g[j]), tile_edges(hb[j], g[j])
        ty, tx = np.meshgrid(np.arange(g[j]), np.arange(g[j]), indexing="ij")
        rect = np.stack([ea[tx.ravel()], ea[tx.ravel() + 1], eb[ty.ravel()], eb[ty.ravel() + 1]], 1)
        q = eye_pos + s[j] * v[vox[j]]
        corners = q + rect[:, [0, 1, 0, 1], None] * a[vox[j]] + rect[:, [2, 2, 3, 3], None] * b[vox[j]]
        may = np.zeros((len(rect), n_proj), bool)
        free = np.zeros((len(rect), n_proj), bool)
        for k in range(n_proj):
            ci = idx[vox[j], k]
            if ci >= 0:
                may[:, k], free[:, k] = tile_tests(cameras[ci], levels, int(ci), corners, spacing)
        keep = tiles_drawable(may, free, np.where(idx[vox[j], :mg.K_BLEND] >= 0, wts[vox[j]], 0.0), rule)
        rows["voxel"].append(np.full(keep.sum(), vox[j]))
        rows["n"].append(np.full(keep.sum(), n[j]))
        rows["rect"].append(rect[keep])
    return {k: np.concatenate(x) for k, x in rows.items()}

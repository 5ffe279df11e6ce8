"""Tile culling and the two-pass path of the microfacet renderer (render/microfacet/cull.py,
microfacet_select.glsl, microfacet_prepass_frag.glsl, microfacet_colour_frag.glsl): the depth
bounds by brute force, the GPU's tiles against the numpy twin, and frames unchanged by both."""

from __future__ import annotations

import numpy as np
import pytest

from capture.camera import Camera, image_axes, look_at
from render.methods import RenderOptions
from render.microfacet import cull as mcull
from render.microfacet.gl import RGBZ_DTYPE, MicrofacetRenderer
from render.owner import near_far
from tests import scenes as scene
from tests.conftest import assert_images_close

ONE = RenderOptions(supersample=1)
#: Culled / two-pass frames vs the one-pass frame of all slices: colour difference per value and
#: share of pixels allowed to differ (the colour pass shades the ray / plane intersection, the
#: one-pass path interpolated projections: texel-boundary ties).
SAME_MEAN_TOL = 1e-3
SAME_MAX_TOL = 1e-3
SAME_OUTLIER_FRAC = 0.005
#: Depth of the drawn samples: metres allowed for all but SAME_OUTLIER_FRAC of them, and for all.
DEPTH_TOL_M = 1e-5
DEPTH_MAX_M = 1e-3
#: GPU (float32) vs twin (float64) tiles: share of slices whose kept tiles may differ (tile
#: counts and cull tests that tie within float32 rounding).
TILE_MISMATCH_FRAC = 0.01


@pytest.fixture(scope="module")
def model():
    return scene.build_model(scene.ring_cameras(12))


def _renderer(gl_ctx, model, cull, prepass, **kw):
    return MicrofacetRenderer(gl_ctx, model.pyramid.levels, model.rgbz, model.bounds,
                              ONE, cull=cull, prepass=prepass, **kw)


# ------------------------------------------------------------------ the depth bounds
def test_depth_bounds_pyramid_by_brute_force():
    rng = np.random.default_rng(3)
    d = rng.uniform(0.3, 0.5, (2, 13, 22)).astype(np.float32)
    d[rng.random(d.shape) < 0.4] = 0.0
    d[1, :8, :8] = 0.0  # a block with no depth at all
    levels = mcull.depth_bounds_pyramid(d)
    assert levels[-1].shape[1:3] == (1, 1)
    for k, lv in enumerate(levels):
        s = 2**k
        assert lv.shape == (2, -(-13 // s), -(-22 // s), 2)
        for c in range(2):
            for by in range(lv.shape[1]):
                for bx in range(lv.shape[2]):
                    blk = d[c, by * s:(by + 1) * s, bx * s:(bx + 1) * s]
                    v = blk[blk > 0]
                    want = (v.min(), v.max()) if v.size else (mcull.EMPTY_MIN, 0.0)
                    assert tuple(lv[c, by, bx]) == pytest.approx(want), (k, c, by, bx)


def test_pack_pyramid_round_trip():
    d = np.random.default_rng(0).uniform(0.3, 0.5, (3, 9, 7)).astype(np.float16).astype(np.float32)
    levels = mcull.depth_bounds_pyramid(d)
    words, offsets = mcull.pack_pyramid(levels)
    for lv, at in zip(levels, offsets):
        w = words[at:at + lv[..., 0].size]
        lo = (w & 0xFFFF).astype(np.uint16).view(np.float16).astype(np.float32)
        hi = (w >> 16).astype(np.uint16).view(np.float16).astype(np.float32)
        np.testing.assert_array_equal(lo, lv[..., 0].reshape(-1))
        np.testing.assert_array_equal(hi, lv[..., 1].reshape(-1))
    with pytest.raises(ValueError, match="half"):
        mcull.pack_pyramid(mcull.depth_bounds_pyramid(np.full((1, 2, 2), 0.30001, np.float32)))


def test_block_bounds_hold_every_box():
    rng = np.random.default_rng(5)
    d = rng.uniform(0.3, 0.5, (1, 40, 57)).astype(np.float32)
    d[rng.random(d.shape) < 0.3] = 0.0
    levels = mcull.depth_bounds_pyramid(d)
    lo = np.stack([rng.integers(0, 57, 500), rng.integers(0, 40, 500)], 1)
    hi = np.minimum(lo + rng.integers(0, 30, (500, 2)), [56, 39])
    bb = mcull.block_bounds(levels, 0, lo, hi)
    for (x0, y0), (x1, y1), (mn, mx) in zip(lo, hi, bb):
        v = d[0, y0:y1 + 1, x0:x1 + 1]
        v = v[v > 0]
        if v.size:
            assert mn <= v.min() and mx >= v.max()


# ------------------------------------------------------------------ GPU tiles vs twin
def test_gpu_tiles_match_twin(gl_ctx, model):
    r = _renderer(gl_ctx, model, cull=True, prepass=True, tile_px=4.0)  # several tiles per slice at 96x72
    try:
        eye = scene.ring_cameras(12, phase_deg=7, elevations=(22,))[0]
        fr = r.render(eye, tolerance_px=2.0, level=8)
        rec = r.read_slices(fr.stats.tiles)
        lv = model.pyramid.levels[1]
        right, up = image_axes(eye)
        depth = model.rgbz.depth.astype(RGBZ_DTYPE).astype(np.float32)
        tw = mcull.select_tiles(lv.centers(), lv.voxel_size, eye.center, right, up, fr.stats.spacing,
                                near_far(eye, model.bounds)[0], model.rgbz.cameras, mcull.depth_bounds_pyramid(depth),
                                float(eye.K[0, 0]), r.tile_px)
        assert len(np.unique(tw["voxel"] * 1000 + tw["n"])) < len(tw["voxel"])  # slices split into tiles

        def tiles(d):  # (voxel, n) -> rectangles, sorted
            out = {}
            for v, n, rect in zip(d["voxel"].tolist(), d["n"].tolist(), d["rect"]):
                out.setdefault((v, n), []).append(rect)
            return {k: np.array(sorted(map(tuple, x))) for k, x in out.items()}

        gpu, twin = tiles(rec), tiles(tw)
        same = sum(1 for k in gpu.keys() & twin.keys()
                   if gpu[k].shape == twin[k].shape and np.allclose(gpu[k], twin[k], atol=1e-6))
        assert len(twin) - same <= TILE_MISMATCH_FRAC * len(twin), (len(gpu), len(twin), same)
        assert len(gpu) - same <= TILE_MISMATCH_FRAC * len(twin), (len(gpu), len(twin), same)
    finally:
        r.release()


def test_culling_drops_tiles(gl_ctx, model):
    """Culling removes tiles (so the comparisons below test something), and the tile count of an
    unculled frame is its slice count."""
    r = _renderer(gl_ctx, model, cull=False, prepass=False)
    try:
        eye = scene.ring_cameras(12, phase_deg=7, elevations=(22,))[0]
        whole = r.render(eye, tolerance_px=2.0, level=8, read=False).stats
        r.cull, r.tile_px = True, 4.0
        culled = r.render(eye, tolerance_px=2.0, level=8, read=False).stats
        assert whole.tiles == whole.facets == culled.facets
        grid = culled.tiles  # tiles kept ...
        r.cull, r.tile_px = True, 1e9  # ... and with one tile per slice
        per_slice = r.render(eye, tolerance_px=2.0, level=8, read=False).stats.tiles
        assert per_slice < whole.tiles and grid > per_slice
    finally:
        r.release()


# ------------------------------------------------------------------ frames unchanged
def _eyes(model):
    K = model.rgbz.cameras[0].K
    return {"between inputs": scene.ring_cameras(12, phase_deg=15, elevations=(5,))[2],
            "inside the bounds": Camera(K, look_at([0.11, -0.09, 0.1], [0.0, 0.0, 0.0]), 96, 72),
            "grazing": Camera(K, look_at([0.0, 0.001, 0.45], [0.0, 0.0, 0.0]), 96, 72)}


@pytest.mark.parametrize("supersample", [1, 2])
def test_cull_and_prepass_change_nothing(gl_ctx, model, supersample):
    ref = _renderer(gl_ctx, model, cull=False, prepass=False)
    fast = _renderer(gl_ctx, model, cull=True, prepass=True, tile_px=4.0)  # many small tiles at 96x72
    try:
        for what, eye in _eyes(model).items():
            for opts in ({"tolerance_px": 2.0}, {"tolerance_px": 8.0}, {"level": 32}):
                a = ref.render(eye, supersample=supersample, **opts)
                b = fast.render(eye, supersample=supersample, **opts)
                assert a.stats.facets == b.stats.facets
                assert np.mean(a.alpha != b.alpha) <= SAME_OUTLIER_FRAC, (what, opts)
                assert_images_close(b.rgb, a.rgb, mean_tol=SAME_MEAN_TOL, max_tol=SAME_MAX_TOL,
                                    outlier_frac=SAME_OUTLIER_FRAC, what=f"{what} {opts}")
                both = a.mask & b.mask  # depth: tiles are other triangles (interpolation ties)
                dz = np.abs(b.depth[both] - a.depth[both])
                assert np.mean(dz > DEPTH_TOL_M) <= SAME_OUTLIER_FRAC and dz.max() <= DEPTH_MAX_M, (what, opts)
    finally:
        ref.release()
        fast.release()


def test_record_overflow_grows_the_buffer(gl_ctx, model):
    r = _renderer(gl_ctx, model, cull=True, prepass=True)
    try:
        eye = _eyes(model)["between inputs"]
        want = r.render(eye, tolerance_px=2.0)
        r.max_records = 7  # far too small: the frame must select again into a larger buffer
        got = r.render(eye, tolerance_px=2.0)
        assert r.max_records >= got.stats.tiles > 7
        np.testing.assert_array_equal(got.alpha, want.alpha)
        np.testing.assert_allclose(got.rgb, want.rgb, atol=1e-6)
    finally:
        r.release()


def test_refinement_never_changes_what_is_drawn(gl_ctx, model):
    """The pre-pass decides without the parallax refinement (microfacet_prepass_frag.glsl): in the
    one-pass path the refinement may change a fragment's colour, never whether it is drawn."""
    r = _renderer(gl_ctx, model, cull=False, prepass=False)
    try:
        recoloured = 0
        for what, eye in _eyes(model).items():
            for level in (8, 32):
                a = r.render(eye, level=level, refine=0)
                b = r.render(eye, level=level, refine=2)
                np.testing.assert_array_equal(a.alpha, b.alpha, err_msg=f"{what}, level {level}")
                recoloured += int(np.sum(np.any(a.rgb != b.rgb, axis=-1)))
        assert recoloured > 100  # the refinement did act
    finally:
        r.release()

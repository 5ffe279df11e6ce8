"""Gather reads a model's views as their crops (render/crops.py, issue 24): a compact model renders
exactly the frames of the dense model its store decodes to, the crops path matches the numpy twin
(on full frames, RgbzImages.view) within test_gather's tolerances, and only the crops are uploaded."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from render.gather import reference as gr
from render.points import reference as pr
from tests import scenes as scene
from tests.render.gather.test_gather import assert_frame_matches_twin
from volume.model import RgbzImages

EYES = [(2, 17.0), (7, 10.0), (4, 3.0)]


@pytest.fixture(scope="module")
def models():
    dense = scene.build_model(scene.ring_cameras(12))
    alpha = scene.with_alpha(dense, scene.soft_matte(dense.rgbz.depth))
    # margin 0: the crops end at the object's last pixel, so every bilinear / cubic footprint on
    # a silhouette reaches outside its crop (the shader's empty-outside rule is exercised)
    return {"opaque": scene.compact(dense, margin=0), "alpha": scene.compact(alpha, margin=0)}


def _eye(i, phase):
    return scene.ring_cameras(12, phase_deg=phase, elevations=(12,))[i]


def _frames(ctx, model, cfg):
    from render.gather.gl import GatherRenderer

    with GatherRenderer.from_model(ctx, model, config=cfg) as r:
        return [r.render(_eye(i, p)) for i, p in EYES], r.tex.size, r.uploaded_bytes


@pytest.mark.parametrize("kind", ["opaque", "alpha"])
@pytest.mark.parametrize("resample", ["cubic", "linear"])
def test_compact_model_renders_the_dense_frames_exactly(gl_ctx, models, kind, resample):
    r = models[kind].rgbz  # a fresh store of the same crops (nothing decoded yet)
    comp = replace(models[kind], rgbz=RgbzImages.from_crops(r.cameras, [r.encoded(n) for n in range(len(r))]))
    cfg = gr.GatherConfig(resample=resample)
    rects = comp.rgbz.rects
    W, H = comp.rgbz.size
    assert np.all(rects[:, 2] * rects[:, 3] < W * H), "every crop smaller than its frame"
    fc, size_c, bytes_c = _frames(gl_ctx, comp, cfg)
    assert comp.rgbz._dense is None, "the renderer never decoded the full stacks"
    fd, size_d, bytes_d = _frames(gl_ctx, scene.densified(comp), cfg)
    assert size_c == (rects[:, 2].max(), rects[:, 3].max(), len(rects)) and size_d == (W, H, len(rects))
    assert bytes_c < bytes_d
    for a, b in zip(fc, fd):
        assert a.mask.sum() > 300
        for x, y in ((a.rgb, b.rgb), (a.alpha, b.alpha), (a.depth, b.depth)):
            np.testing.assert_array_equal(x, y)


@pytest.mark.parametrize("kind", ["opaque", "alpha"])
def test_crops_path_matches_numpy_twin(gl_ctx, models, kind):
    """The twin samples full frames (RgbzImages.view, float16 as the GPU stores them)."""
    from render.gather.gl import GatherRenderer

    m = models[kind]
    r = m.rgbz
    views = [r.view(n) for n in range(len(r))]
    rgb, depth = (np.stack([v[k] for v in views]).astype(np.float16).astype(np.float32) for k in (0, 1))
    alpha = None if kind == "opaque" else np.stack([v[2] for v in views]).astype(np.float16).astype(np.float32)
    clouds = pr.back_project(r.cameras, rgb, depth)
    cfg = gr.GatherConfig(resample="cubic")
    with GatherRenderer.from_model(gl_ctx, m, config=cfg) as rr:
        for i, p in EYES[:2]:
            eye = _eye(i, p)
            t_rgb, t_a, t_z, n = gr.gather_frame(eye, clouds, r.cameras, rgb, depth, m.bounds.mean(0), cfg, alpha=alpha)
            fr = rr.render(eye)
            assert fr.stats.facets == n > 0
            back = None
            if alpha is not None:
                zb = gr.frame_depths(eye, clouds, r.cameras, rgb, depth, m.bounds.mean(0), cfg, back=True,
                                     fine=rr.fine)[1]
                back = (zb, rr.read_back_depth(eye))
            assert_frame_matches_twin(fr, t_rgb, t_a, t_z, back)


def test_a_frame_uploads_only_the_views_it_reads(gl_ctx, models):
    """Nothing is uploaded before the first frame; a frame uploads its depth and blend views'
    crops and points (the first frame of a large capture reads a handful of views); load() the rest."""
    from render.gather.gl import GatherRenderer

    m = models["alpha"]
    cfg = gr.GatherConfig()
    with GatherRenderer.from_model(gl_ctx, m, config=cfg) as r:
        assert r.uploaded_bytes == 0 and not r.crops.loaded.any()
        eye = _eye(*EYES[0])
        depth_cams, blend, _ = r.views(eye)
        fr = r.render(eye)
        assert fr.mask.any()
        want = set(depth_cams) | set(blend)
        assert set(np.flatnonzero(r.crops.loaded)) == want and len(want) <= cfg.k_depth + cfg.k_blend < len(m.rgbz)
        rects = m.rgbz.rects
        texel_bytes = sum(int(rects[i, 2] * rects[i, 3]) * (8 + 2) for i in want)  # RGBA16F + R16F
        assert r.crops.bytes == texel_bytes
        r.load()
        assert r.crops.loaded.all() and np.all(r.counts >= 0)
        again = r.render(eye)
    for x, y in ((fr.rgb, again.rgb), (fr.alpha, again.alpha), (fr.depth, again.depth)):
        np.testing.assert_array_equal(x, y)



def test_a_small_cache_replaces_views_and_keeps_the_frames(gl_ctx, models):
    """With 4 resident views (a frame's k_depth + k_blend) eyes around the ring replace views in
    the cache; every frame equals the one of a renderer holding all views."""
    from render.gather.gl import GatherRenderer

    m = models["alpha"]
    eyes = [_eye(i, p) for i, p in EYES] + [_eye(*EYES[0])]
    with GatherRenderer(gl_ctx, m.rgbz, m.bounds, resident=4) as small, GatherRenderer.from_model(gl_ctx, m) as full:
        assert small.tex.size[2] == 4
        for eye in eyes:
            a, b = small.render(eye), full.render(eye)
            assert small.crops.loaded.sum() <= 4
            for x, y in ((a.rgb, b.rgb), (a.alpha, b.alpha), (a.depth, b.depth)):
                np.testing.assert_array_equal(x, y)
        assert small.crops.bytes > full.crops.bytes, "views were replaced and written again"

"""The gather method: its GLSL against the numpy twin (render/gather/reference.py), the twin's
pieces by hand, and the hard cases (one camera, eye inside the bounds, grazing eye, no depth)."""

from __future__ import annotations

import numpy as np
import pytest

from capture.camera import Camera, look_at
from render.gather import reference as gr
from render.gather.fine_depth import use_fine
from render.methods import create_renderer
from render.points import reference as pr
from tests import scenes as scene
from volume.model import Model, RgbzImages

#: GPU (float32) against the float64 twin.  llvmpipe snaps point positions to 1/256 pixel and
#: breaks ties on a splat's edge its own way, so a point within 1/256 px of covering a pixel
#: centre may cover it on one side and not on the other (checked: snapping the twin's splat
#: centres to that grid leaves only exact ties, 3 of 1215 pixels in the first case below).
#: Such a pixel gets another front depth (relative difference > DEPTH_RTOL), hence another
#: colour; at the 96 x 72 pixels of these views they are 0.5-1.1 % of the drawn pixels.  Every
#: other drawn pixel must have the twin's colour within COLOUR_TOL.
COVERAGE_MISMATCH_FRAC = 2e-3
DEPTH_RTOL = 1e-5
DEPTH_MISMATCH_FRAC = 2e-2
COLOUR_TOL = 1e-4


@pytest.fixture(scope="module")
def model():
    return scene.build_model(scene.ring_cameras(12))


def _twin(eye, model, cfg=None):
    clouds = pr.back_project(model.rgbz.cameras, model.rgbz.rgb, model.rgbz.depth)
    return gr.gather_frame(eye, clouds, model.rgbz.cameras, model.rgbz.rgb, model.rgbz.depth, model.bounds.mean(0),
                           cfg or gr.GatherConfig())


def _with_rgbz(model, rgbz):
    return Model(model.pyramid, rgbz, model.spheres, model.mesh_vertices, model.mesh_faces, model.mesh_colors,
                 model.bounds)


def assert_frame_matches_twin(fr, rgb, alpha, depth, back=None) -> None:
    """A GPU frame against the numpy twin's (rgb, alpha, depth): the coverage within
    COVERAGE_MISMATCH_FRAC, the front depth within DEPTH_RTOL on all but DEPTH_MISMATCH_FRAC of the
    pixels both draw, and there the colour and alpha within COLOUR_TOL.  ``back``: the second layer's
    (twin z, GPU z) (reference.py step 3), whose splat edges may differ alike: a pixel counts as the
    same only where they agree too."""
    assert np.mean(fr.mask != (alpha > 0)) <= COVERAGE_MISMATCH_FRAC
    both = fr.mask & (alpha > 0)
    same = both & (np.abs(fr.depth - depth) <= DEPTH_RTOL * depth)
    if back is not None:
        zb, gb = back
        same &= np.abs(gb - zb) <= DEPTH_RTOL * np.maximum(zb, gb)
    assert 1 - same.sum() / both.sum() <= DEPTH_MISMATCH_FRAC
    np.testing.assert_allclose(fr.alpha[same], alpha[same], atol=COLOUR_TOL)
    np.testing.assert_allclose(fr.rgb[same], rgb[same], atol=COLOUR_TOL)


@pytest.mark.parametrize("i,phase,resample", [(2, 17.0, "cubic"), (7, 10.0, "cubic"), (4, 3.0, "cubic"),
                                               (7, 10.0, "linear")])
def test_gpu_matches_numpy_twin(gl_ctx, model, i, phase, resample):
    from render.gather.gl import GatherRenderer

    eye = scene.ring_cameras(12, phase_deg=phase, elevations=(12,))[i]
    cfg = gr.GatherConfig(resample=resample)
    rgb, cov, depth, n = _twin(eye, model, cfg)
    with GatherRenderer.from_model(gl_ctx, model, config=cfg) as r:
        fr = r.render(eye)
    assert fr.stats.facets == n > 0 and fr.stats.supersample == 1
    assert cov.sum() > 500
    assert_frame_matches_twin(fr, rgb, cov, depth)


def test_eye_on_a_kept_camera_reproduces_its_photo(model):
    """The kept camera takes ~all the weight (1 / ANGLE_EPS against 1 / 30 degrees), sees itself
    (visibility 1) and its bilinear colour at its own pixel centres is the texel."""
    k = 5
    eye = model.rgbz.cameras[k]
    rgb, cov, _, _ = _twin(eye, model)
    own = model.rgbz.depth[k] > 0
    assert np.mean(cov[own] > 0) > 0.99
    inner = own & (cov > 0)
    other_w = 1.0 / np.radians(30.0)
    share = (1.0 / pr.ANGLE_EPS) / (1.0 / pr.ANGLE_EPS + other_w)
    err = np.abs(rgb[inner] - model.rgbz.rgb[k][inner]).max(-1)
    assert np.percentile(err, 99) <= (1 - share) * 1.0 + 1e-6


def test_cubic_is_catmull_rom():
    """Keys' cubic with a = -0.5 interpolates the texels and reproduces quadratics exactly
    (away from the clamped border); its weights sum to 1."""
    y, x = np.mgrid[0:8, 0:9].astype(np.float64)
    img = (0.5 * x * x - 0.3 * x * y + 2.0 * y + 1.0)[..., None]
    rng = np.random.default_rng(0)
    uv = rng.uniform(1.0, 6.0, (50, 2))
    np.testing.assert_allclose(gr.cubic(img, uv)[:, 0], 0.5 * uv[:, 0] ** 2 - 0.3 * uv[:, 0] * uv[:, 1]
                               + 2.0 * uv[:, 1] + 1.0, atol=1e-9)
    grid = np.array([[3.0, 4.0], [0.0, 0.0], [8.0, 7.0]])
    np.testing.assert_allclose(gr.cubic(img, grid)[:, 0], img[[4, 0, 7], [3, 0, 8], 0])
    np.testing.assert_allclose(gr.cubic_weights(rng.uniform(0, 1, 20)).sum(-1), 1.0)


def test_soft_visibility_by_hand():
    d = np.array([0.5, 0.503, 0.5, 0.0, 0.5])
    z = np.array([0.5, 0.5, 0.6, 0.5, 0.5])
    inside = np.array([True, True, True, True, False])
    v = gr.visibility(d, z, inside, sigma=0.003, floor=0.2)
    np.testing.assert_allclose(v, [1.0, np.exp(-0.5), 0.2, 0.2, 0.0])


def test_config_is_validated():
    for bad in (dict(k_blend=0), dict(splat_px=1.5), dict(vis_sigma_m=0.0), dict(vis_floor=1.5), dict(resample="x")):
        with pytest.raises(ValueError):
            gr.GatherConfig(**bad)


def test_gather_hard_cases(gl_ctx, model):
    """One camera; an eye inside the bounds; a grazing (top-down) eye; a model with no depth."""
    cams = model.rgbz.cameras
    centre = model.bounds.mean(0)
    eye = scene.ring_cameras(12, phase_deg=10)[0]
    m1 = _with_rgbz(model, RgbzImages(model.rgbz.rgb[:1], model.rgbz.depth[:1], cams[:1]))
    with create_renderer("gather", gl_ctx, m1) as r:
        fr = r.render(eye)
        rgb, cov, _, _ = _twin(eye, m1)
        assert fr.mask.sum() > 100 and np.mean(fr.mask != (cov > 0)) <= COVERAGE_MISMATCH_FRAC
        inside = Camera(eye.K, look_at(centre, centre + np.array([0.3, 0.0, 0.0])), eye.width, eye.height)
        fi = r.render(inside)
        assert np.all(np.isfinite(fi.rgb)) and np.all(fi.depth >= 0)
    with create_renderer("gather", gl_ctx, model) as r:
        top = Camera(eye.K, look_at(centre + np.array([0, 0, 0.45]), centre, (0.0, 1.0, 0.0)), eye.width, eye.height)
        ft = r.render(top)
        rgb, cov, _, _ = _twin(top, model)
        assert ft.mask.any() and np.mean(ft.mask != (cov > 0)) <= COVERAGE_MISMATCH_FRAC
    m0 = _with_rgbz(model, RgbzImages(model.rgbz.rgb, np.zeros_like(model.rgbz.depth), cams))
    with create_renderer("gather", gl_ctx, m0) as r:
        fe = r.render(eye)
        assert not fe.mask.any() and fe.stats.facets == 0


def test_shared_context_state_is_left_as_found(gl_ctx, model):
    """The splat pass sets the point size on a context the viewer and the tests share; it puts it
    back (a leaked size of 2 shifted every later 1-pixel point by one pixel)."""
    from render.gather.gl import GatherRenderer

    before = gl_ctx.point_size
    eye = scene.ring_cameras(12, phase_deg=10.0, elevations=(12,))[3]
    with GatherRenderer.from_model(gl_ctx, model) as r:
        r.render(eye)
    assert gl_ctx.point_size == before


@pytest.fixture(scope="module")
def alpha_model(model):
    return scene.with_alpha(model, scene.soft_matte(model.rgbz.depth))


@pytest.mark.parametrize("i,phase,resample", [(2, 17.0, "cubic"), (7, 10.0, "linear")])
def test_alpha_gpu_matches_numpy_twin(gl_ctx, alpha_model, i, phase, resample):
    """With a matte: premultiplied colour and alpha blended alike on the GPU and in the twin."""
    eye = scene.ring_cameras(12, phase_deg=phase, elevations=(12,))[i]
    (rgb, a, depth), fr, back = twin_and_gpu_with_matte(gl_ctx, alpha_model, eye, gr.GatherConfig(resample=resample))
    assert np.mean((a > 0) & (a < 0.999)) > 0.05, "the matte gives partial pixels"
    assert_frame_matches_twin(fr, rgb, a, depth, back)


def twin_and_gpu_with_matte(gl_ctx, m, eye, cfg):
    """((rgb, alpha, depth) of the twin, the GPU frame, (twin, GPU) second-layer z) of model ``m`` with its matte at
    ``eye`` (fine depth as each decides it; they must agree)."""
    from render.gather.gl import GatherRenderer

    clouds = pr.back_project(m.rgbz.cameras, m.rgbz.rgb, m.rgbz.depth)
    rgb, a, depth, _ = gr.gather_frame(eye, clouds, m.rgbz.cameras, m.rgbz.rgb, m.rgbz.depth, m.bounds.mean(0), cfg,
                                       alpha=m.rgbz.alpha)
    fine = use_fine(cfg.fine_depth, m.rgbz.alpha)
    zb = gr.frame_depths(eye, clouds, m.rgbz.cameras, m.rgbz.rgb, m.rgbz.depth, m.bounds.mean(0), cfg, back=True,
                         fine=fine)[1]
    with GatherRenderer.from_model(gl_ctx, m, config=cfg) as r:
        assert r.fine == fine
        fr = r.render(eye)
        gb = r.read_back_depth(eye)
    return (rgb, a, depth), fr, (zb, gb)


def test_alpha_blends_premultiplied_colour(model):
    """Twin by hand: a fringe pixel keeps the views' foreground colour (premult / alpha = straight
    colour of the views when they agree), not black; an opaque matte gives the matte-less frame.  With
    no second layer (reference.py step 3: at the silhouette, where taps fall off the object, it puts
    the sphere behind under the partial pixel; tested in test_gather_back.py)."""
    eye = scene.ring_cameras(12, phase_deg=10.0, elevations=(12,))[7]
    clouds = pr.back_project(model.rgbz.cameras, model.rgbz.rgb, model.rgbz.depth)
    args = (eye, clouds, model.rgbz.cameras, model.rgbz.rgb, model.rgbz.depth, model.bounds.mean(0),
            gr.GatherConfig(back_gap_m=0.0, fine_depth="off"))   # the same depth with and without a matte
    rgb0, a0, d0, _ = gr.gather_frame(*args)
    half = np.where(model.rgbz.depth > 0, 0.5, 0.0).astype(np.float32)
    rgb1, a1, d1, _ = gr.gather_frame(*args, alpha=half)
    ones = (model.rgbz.depth > 0).astype(np.float32)
    rgb2, a2, _, _ = gr.gather_frame(*args, alpha=ones)
    inner = (a0 > 0) & (np.abs(a1 - 0.5) < 1e-6)  # all taps inside the matte
    assert inner.mean() > 0.05
    # a constant matte 0.5: alpha 0.5 wherever the blend cameras measured depth, the straight colour unchanged
    np.testing.assert_allclose(rgb1[inner] / a1[inner, None], rgb0[inner], atol=1e-5)
    assert np.all(a1[(a0 > 0) & (d1 > 0)] <= 0.5 + 1e-6)
    assert set(np.unique(a0)) <= {0.0, 1.0}
    np.testing.assert_allclose(rgb2, rgb0, atol=1e-5)


def test_no_matte_is_the_opaque_path(gl_ctx, model):
    """alpha None: the shader without HAS_ALPHA (the path of the matte-less method), a 0 / 1 alpha;
    a matte of ones on the depth gives the same colour wherever its taps all lie on the depth
    (elsewhere the taps off the object now count as transparent, not as their colour); over black
    both frames are the same everywhere (the matte is 0 where the photos are black).  With no second
    layer (see test_alpha_blends_premultiplied_colour)."""
    from render.gather.gl import GatherRenderer

    eye = scene.ring_cameras(12, phase_deg=10.0, elevations=(12,))[7]
    ones = scene.with_alpha(model, (model.rgbz.depth > 0).astype(np.float32))
    cfg = gr.GatherConfig(back_gap_m=0.0)
    with create_renderer("gather", gl_ctx, model) as r, GatherRenderer.from_model(gl_ctx, ones, config=cfg) as r1:
        assert r.alpha_tex is None and r1.alpha_tex is not None
        fr, f1 = r.render(eye), r1.render(eye)
    assert set(np.unique(fr.alpha)) <= {0.0, 1.0}
    assert not np.any(f1.mask & ~fr.mask)
    full = f1.alpha > 1 - 1e-6
    assert full.sum() > 0.5 * fr.mask.sum()  # 96 x 72: edges and views seeing past the object are many
    np.testing.assert_allclose(f1.rgb[full], fr.rgb[full], atol=1e-5)
    black = model.rgbz.depth == 0
    assert np.all(model.rgbz.rgb[black] == 0), "the test scene's photos are black off the object"
    np.testing.assert_allclose(f1.rgb[f1.mask], fr.rgb[f1.mask], atol=1e-5)

"""Gather's second depth layer (render/gather/reference.py step 3): a "trunk" seen through a row of
"needles" whose partial alpha the kept views see against the empty background (parallax puts the trunk
elsewhere behind them), rendered from a view between the kept ones against its exact matte; the twin's
pieces by hand; the GPU against the twin."""

from __future__ import annotations

import numpy as np
import pytest

from render.gather import reference as gr
from render.points import reference as pr
from tests import scenes as scene
from tests.render.gather.test_gather import COLOUR_TOL, COVERAGE_MISMATCH_FRAC, DEPTH_RTOL
from volume.model import Model, RgbzImages

#: The scene (world metres; the eye at azimuth 0 looks down -x, world +z up): a sheet of horizontal
#: needle rows at x = SHEET_X, each row covering NEEDLE_COVER of its pixels (a partial alpha), rows
#: ROW_PERIOD apart (half of the period is needle, half gap); an opaque trunk at x = TRUNK_X behind it.
SHEET_X, SHEET_Y, SHEET_Z = 0.04, 0.06, 0.05
ROW_PERIOD = 0.0048
NEEDLE_COVER = 0.5
TRUNK_X, TRUNK_Y, TRUNK_Z = -0.02, 0.008, 0.08
NEEDLE_RGB = np.array([0.1, 0.4, 0.1])
TRUNK_RGB = np.array([0.3, 0.15, 0.05])
#: Kept views at +-KEPT_DEG (and 180 degrees from them: never the nearest); the eye at 0.
KEPT_DEG = 20.0
SIZE = (160, 120)


def _plane(o, d, x0):
    """Ray parameter and hit point of the rays (o, d) on the plane x = x0 (inf where parallel or behind)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (x0 - o[:, 0]) / d[:, 0]
    t = np.where(np.isfinite(t) & (t > 0), t, np.inf)
    return t, o + np.where(np.isfinite(t), t, 0.0)[:, None] * d


def render_view(cam):
    """Exact (straight rgb (H, W, 3), z-depth (H, W) of the surface the pixel centre's ray hits first,
    alpha (H, W): NEEDLE_COVER on a needle row plus the rest where the trunk is behind it, 1 on the
    trunk, 0 elsewhere) of the scene seen by ``cam``."""
    rays = cam.pixel_rays(cam.pixel_grid().reshape(-1, 2))
    dc = rays / np.linalg.norm(rays, axis=1, keepdims=True)
    d = dc @ cam.world_from_cam[:3, :3].T
    o = np.broadcast_to(cam.center, d.shape)
    ts, ps = _plane(o, d, SHEET_X)
    tt, pt = _plane(o, d, TRUNK_X)
    sheet = np.isfinite(ts) & (np.abs(ps[:, 1]) < SHEET_Y) & (np.abs(ps[:, 2]) < SHEET_Z)
    needle = sheet & (np.mod(ps[:, 2], ROW_PERIOD) < ROW_PERIOD / 2)
    trunk = np.isfinite(tt) & (np.abs(pt[:, 1]) < TRUNK_Y) & (np.abs(pt[:, 2]) < TRUNK_Z)
    alpha = np.where(needle, NEEDLE_COVER + (1 - NEEDLE_COVER) * trunk, trunk.astype(float))
    premult = NEEDLE_COVER * needle[:, None] * NEEDLE_RGB + ((1 - NEEDLE_COVER * needle) * trunk)[:, None] * TRUNK_RGB
    rgb = np.where(alpha[:, None] > 0, premult / np.maximum(alpha, 1e-9)[:, None], 0.0)
    z = np.where(needle, ts, np.where(trunk, tt, 0.0)) * dc[:, 2]
    H, W = cam.height, cam.width
    return rgb.reshape(H, W, 3), z.reshape(H, W), alpha.reshape(H, W)


def cameras():
    kept = scene.ring_cameras(4, *SIZE, elevations=(0.0,), azimuths=(KEPT_DEG, -KEPT_DEG, 180 + KEPT_DEG,
                                                                      180 - KEPT_DEG))
    return kept, scene.ring_cameras(1, *SIZE, elevations=(0.0,), azimuths=(0.0,))[0]


@pytest.fixture(scope="module")
def trunk_model():
    kept, eye = cameras()
    rgb, z, a = (np.stack(x).astype(np.float32) for x in zip(*[render_view(c) for c in kept]))
    bounds = np.array([[TRUNK_X - 0.01, -SHEET_Y, -TRUNK_Z], [SHEET_X + 0.01, SHEET_Y, TRUNK_Z]])
    base = scene.build_model(kept)
    m = Model(base.pyramid, RgbzImages(rgb, z, tuple(kept), a), base.spheres, base.mesh_vertices, base.mesh_faces,
              base.mesh_colors, bounds)
    return m, eye, render_view(eye)


def _twin(m, eye, cfg):
    r = m.rgbz
    clouds = pr.back_project(r.cameras, r.rgb, r.depth)
    return gr.gather_frame(eye, clouds, r.cameras, np.asarray(r.rgb), np.asarray(r.depth), m.bounds.mean(0), cfg,
                           alpha=np.asarray(r.alpha))


def _regions(eye, true_a):
    """The eye's pixels inside the sheet whose truth is solid (a needle row or a gap over the trunk) and
    those whose truth is a needle row over nothing."""
    rays = eye.pixel_rays(eye.pixel_grid().reshape(-1, 2))
    _, ps = _plane(np.broadcast_to(eye.center, rays.shape), rays @ eye.world_from_cam[:3, :3].T, SHEET_X)
    in_sheet = ((np.abs(ps[:, 1]) < SHEET_Y) & (np.abs(ps[:, 2]) < SHEET_Z)).reshape(true_a.shape)
    return in_sheet & (true_a > 0.99), in_sheet & (true_a > 0) & (true_a < 0.99)


def test_the_trunk_shows_through_the_needles(trunk_model):
    """Without the second layer the eye's needle rows in front of the trunk gather the kept views' 0.5
    (their trunk is elsewhere) and the gaps between them the needles' splats: mean alpha 0.28 where the
    truth is 1.  With it the trunk behind them counts (mean 0.83, alpha MSE 5x lower), and the needle
    rows over nothing, with no solid surface behind, keep exactly their alpha."""
    m, eye, (true_rgb, _, true_a) = trunk_model
    over, sheet_only = _regions(eye, true_a)
    assert over.sum() > 150 and sheet_only.sum() > 500
    want = true_rgb * true_a[..., None]
    (rgb0, a0, _, _), (rgb1, a1, _, _) = (_twin(m, eye, gr.GatherConfig(back_gap_m=g, fine_depth="off"))
                                          for g in (0.0, 0.02))
    assert a0[over].mean() < 0.5 and a1[over].mean() > 0.75
    mse0, mse1 = (np.mean((a - true_a)[over] ** 2) for a in (a0, a1))
    assert mse1 < 0.25 * mse0
    err0, err1 = (np.mean(np.abs(c - want)[over]) for c in (rgb0, rgb1))
    assert err1 < 0.5 * err0
    np.testing.assert_array_equal(a1[sheet_only], a0[sheet_only])
    np.testing.assert_array_equal(rgb1[sheet_only], rgb0[sheet_only])


def test_back_depth_by_hand():
    """Splats of 1 pixel: the farthest point where it lies more than the gap behind the front, only where
    there is a front."""
    eye = scene.ring_cameras(1, 8, 6, elevations=(0.0,), azimuths=(0.0,))[0]
    uv = np.array([[2.0, 3.0]] * 4 + [[5.0, 1.0]])
    z = np.array([0.40, 0.41, 0.43, 0.45, 0.5])
    cloud = pr.Cloud(eye.unproject(uv, z), np.zeros((5, 3)))
    front = np.zeros((6, 8))
    front[3, 2] = 0.40
    b = gr.back_depth(eye, [cloud], 1, front, 0.02)
    assert b[3, 2] == pytest.approx(0.45) and np.count_nonzero(b) == 1   # the farthest; (5, 1) has no front
    assert np.count_nonzero(gr.back_depth(eye, [cloud], 1, front, 0.05)) == 0   # 0.45 is within this gap


def test_under_back_by_hand():
    """g = solid(a_b) (1 - solid(a_f)), solid(x) = clip((x - 0.6) / 0.4, 0, 1)."""
    col_b = np.array([[0.4, 0.4, 0.8]])
    for af, ab, g in ((0.5, 0.8, 0.5), (0.5, 0.6, 0.0), (0.5, 0.3, 0.0), (0.5, 1.0, 1.0), (0.7, 1.0, 0.75),
                      (0.8, 0.9, 0.375), (1.0, 1.0, 0.0)):
        col = np.array([[0.2, 0.1, 0.0]]) * af
        c2, a2 = gr.under_back(col, np.array([af]), col_b * ab, np.array([ab]), 0.6)
        np.testing.assert_allclose(a2, af + (1 - af) * g)
        np.testing.assert_allclose(c2, col + (1 - af) * g * col_b)


@pytest.mark.parametrize("resample", ["linear", "cubic"])
def test_gpu_matches_twin_with_the_second_layer(gl_ctx, trunk_model, resample):
    """The GPU's second layer (gather_back_frag.glsl) and composite against the twin: where the front and
    the second layer's depths agree (test_gather's tolerances: splat-edge ties may differ), colour and
    alpha within COLOUR_TOL."""
    from render.gather.gl import GatherRenderer

    m, eye, _ = trunk_model
    cfg = gr.GatherConfig(resample=resample)
    rgb, a, depth, _ = _twin(m, eye, cfg)
    r = m.rgbz
    idx, _ = pr.nearest_views(eye, r.cameras, m.bounds.mean(0), cfg.k_depth)
    used = [pr.back_project([r.cameras[i]], r.rgb[i:i + 1], r.depth[i:i + 1])[0] for i in idx]
    with GatherRenderer.from_model(gl_ctx, m, config=cfg) as ren:
        back = gr.back_depth(eye, used, cfg.splat_px, gr.front_depth(eye, used, cfg.splat_px, ren.fine)[0],
                             cfg.back_gap_m)
        fr = ren.render(eye)
        gb = ren.read_back_depth(eye)
    assert np.mean(fr.mask != (a > 0)) <= COVERAGE_MISMATCH_FRAC
    both = fr.mask & (a > 0)
    same = (both & (np.abs(fr.depth - depth) <= DEPTH_RTOL * depth)
            & (np.abs(gb - back) <= DEPTH_RTOL * np.maximum(back, gb)))
    assert same.sum() >= 0.97 * both.sum() and np.count_nonzero(same & (back > 0)) > 100
    np.testing.assert_allclose(fr.alpha[same], a[same], atol=COLOUR_TOL)
    np.testing.assert_allclose(fr.rgb[same], rgb[same], atol=COLOUR_TOL)


def test_a_draft_frame_leaves_the_second_layer_out(gl_ctx, trunk_model):
    """RenderOptions.draft (the viewer's moving frames): the frame of the config without a second layer,
    exactly; the still frame differs where the trunk shows through."""
    from render.gather.gl import GatherRenderer

    m, eye, _ = trunk_model
    with GatherRenderer.from_model(gl_ctx, m) as r, \
            GatherRenderer.from_model(gl_ctx, m, config=gr.GatherConfig(back_gap_m=0.0)) as r0:
        draft, still, one = r.render(eye, draft=True), r.render(eye), r0.render(eye)
    for x, y in ((draft.rgb, one.rgb), (draft.alpha, one.alpha), (draft.depth, one.depth)):
        np.testing.assert_array_equal(x, y)
    assert np.count_nonzero(np.abs(still.alpha - one.alpha) > 0.1) > 100

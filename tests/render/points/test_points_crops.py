"""The points method reads a model's views as their crops (render/crops.py, issue 24): a view's
cloud from its crop is the cloud of its full frame (render.points.reference.back_project), and a
compact model renders exactly the frames of the dense model its store decodes to."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from render.methods import create_renderer
from render.points import reference as pr
from tests import scenes as scene
from volume.model import RgbzImages


@pytest.fixture(scope="module", params=["opaque", "alpha"])
def compact_model(request):
    dense = scene.build_model(scene.ring_cameras(12))
    if request.param == "alpha":
        dense = scene.with_alpha(dense, scene.soft_matte(dense.rgbz.depth))
    return scene.compact(dense, margin=0)


def test_crop_cloud_is_the_full_frame_cloud(compact_model):
    r = compact_model.rgbz
    for n in (0, 5, 11):
        rect, rgb, depth, alpha = r.crop(n)
        assert rect[2] * rect[3] < r.size[0] * r.size[1]
        c = pr.back_project_crop(r.cameras[n], rect, rgb, depth, alpha)
        f_rgb, f_depth, f_alpha = r.view(n)
        (ref,) = pr.back_project([r.cameras[n]], f_rgb[None], f_depth[None], None if f_alpha is None else f_alpha[None])
        assert len(c.points) > 100
        np.testing.assert_array_equal(c.points, ref.points)
        np.testing.assert_array_equal(c.colours, ref.colours)


def test_compact_model_renders_the_dense_frames_exactly(gl_ctx, compact_model):
    r = compact_model.rgbz
    comp = replace(compact_model, rgbz=RgbzImages.from_crops(r.cameras, [r.encoded(n) for n in range(len(r))]))
    eyes = [scene.ring_cameras(12, phase_deg=p, elevations=(12,))[i] for i, p in ((2, 17.0), (7, 10.0))]
    with create_renderer("points", gl_ctx, comp) as rc:
        fc = [rc.render(e) for e in eyes]
    assert comp.rgbz._dense is None, "the renderer never decoded the full stacks"
    with create_renderer("points", gl_ctx, scene.densified(comp)) as rd:
        fd = [rd.render(e) for e in eyes]
    for a, b in zip(fc, fd):
        assert a.mask.sum() > 300
        for x, y in ((a.rgb, b.rgb), (a.alpha, b.alpha), (a.depth, b.depth)):
            np.testing.assert_array_equal(x, y)


def test_a_frame_back_projects_only_its_views(gl_ctx, compact_model):
    eye = scene.ring_cameras(12, phase_deg=10.0, elevations=(12,))[7]
    with create_renderer("points", gl_ctx, compact_model) as r:
        assert r.clouds.loaded == 0
        assert r.render(eye).mask.any()
        assert r.clouds.loaded == pr.N_VIEWS < len(compact_model.rgbz)

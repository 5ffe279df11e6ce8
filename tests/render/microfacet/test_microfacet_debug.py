"""The microfacet renderer's debug outputs (RenderOptions.debug: dominant camera, Eq. 2
rejections) against the numpy twin (microfacet_reference.reference_render with ``debug``)."""

from __future__ import annotations

import numpy as np
import pytest

from render.methods import RenderOptions
from render.microfacet.geometry import DEBUG_KEPT, DEBUG_REJECTED
from render.microfacet.gl import RGBZ_DTYPE, MicrofacetRenderer
from render.microfacet.reference import reference_render
from tests import scenes as scene

#: Share of pixels allowed to differ between GPU (float32) and twin (float64): texel-boundary
#: and slice-edge ties, as for the colour (tests/render/microfacet/test_microfacet.py TWIN_OUTLIER_FRAC).
OUTLIER_FRAC = 0.005
ONE = RenderOptions(supersample=1)


@pytest.fixture(scope="module")
def model():
    return scene.build_model(scene.ring_cameras(12))


def twin(model, eye, level, spacing, debug):
    lv = model.pyramid.levels[level]
    rgb = model.rgbz.rgb.astype(RGBZ_DTYPE).astype(np.float64)
    depth = model.rgbz.depth.astype(RGBZ_DTYPE).astype(np.float64)
    return reference_render(eye, lv.centers(), lv.voxel_size, spacing, model.rgbz.cameras, rgb, depth,
                            model.bounds, debug=debug)


@pytest.mark.parametrize("mode", ["instanced", "geometry"])
def test_debug_outputs_match_the_twin(gl_ctx, model, mode):
    r = MicrofacetRenderer.from_model(gl_ctx, model, ONE.changed_for("microfacet", mode=mode))
    try:
        eye = scene.ring_cameras(12, phase_deg=7, elevations=(22,))[0]
        colour = r.render(eye, tolerance_px=2.0, level=16)
        cams = r.render(eye, tolerance_px=2.0, level=16, debug="camera")
        rej = r.render(eye, tolerance_px=2.0, level=16, debug="rejections")
        spacing = colour.stats.spacing
        # the camera view draws exactly the colour view's pixels, each with a camera index + 1
        assert np.array_equal(cams.mask, colour.mask)
        codes = np.rint(cams.rgb[..., 0]).astype(int)
        assert codes[cams.mask].min() >= 1 and codes[cams.mask].max() <= len(model.rgbz.cameras)
        assert len(np.unique(codes[cams.mask])) >= 2
        img, alive, _ = twin(model, eye, 2, spacing, "camera")
        differ = (codes != np.rint(img[..., 0]).astype(int)) | (alive != cams.mask)
        assert differ.mean() <= OUTLIER_FRAC, differ.mean()
        # rejections: kept where the colour view draws, rejected-only pixels around them
        rc = np.rint(rej.rgb[..., 0]).astype(int)
        assert set(np.unique(rc[rej.mask])) <= {DEBUG_KEPT, DEBUG_REJECTED}
        assert np.mean((rc == DEBUG_KEPT) != colour.mask) <= OUTLIER_FRAC
        assert (rc == DEBUG_REJECTED).sum() > 0.05 * colour.mask.sum()   # Eq. 2 carves a visible share
        img, alive, _ = twin(model, eye, 2, spacing, "rejections")
        differ = (rc != np.rint(img[..., 0]).astype(int)) | (alive != rej.mask)
        assert differ.mean() <= OUTLIER_FRAC, differ.mean()
        # the colour output is unchanged by having drawn the debug ones
        again = r.render(eye, tolerance_px=2.0, level=16)
        np.testing.assert_array_equal(again.rgb, colour.rgb)
    finally:
        r.release()


def test_debug_option_validated(gl_ctx, model):
    with pytest.raises(ValueError, match="debug"):
        RenderOptions.for_method("microfacet", debug="nosuch")
    with MicrofacetRenderer.from_model(gl_ctx, model, ONE) as r:
        with pytest.raises(ValueError, match="supersample 1"):
            r.render(scene.ring_cameras(12)[0], debug="camera", supersample=2)

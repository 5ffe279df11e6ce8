"""Fixed-mesh VDTM baseline: GPU vs numpy twin, input pose, vertex-colour floor."""

from __future__ import annotations

import numpy as np
import pytest

from capture.scan import to_uint8_srgb
from render.mesh.gl import MeshColourRenderer, VdtmRenderer
from render.mesh.raster.gl import RasterMesh
from render.mesh.raster.reference import rasterize_reference
from render.mesh.reference import vdtm_reference
from render.methods import RenderOptions
from tests import scenes as scene
from tests.conftest import assert_images_close, image_diff_stats

#: Share of pixels allowed to differ between the GL rasteriser and the numpy one (edges,
#: texel-boundary ties) and the colour tolerance per value.
EDGE_FRAC = 0.01
COLOUR_TOL = 2e-3
#: One sample per pixel: the numpy twin shades pixel centres.
ONE = RenderOptions(supersample=1)


@pytest.fixture(scope="module")
def model():
    return scene.build_model(scene.ring_cameras(12))


def test_vdtm_matches_numpy_twin(gl_ctx, model):
    r = VdtmRenderer.from_model(gl_ctx, model, ONE)
    try:
        eye = scene.ring_cameras(12, phase_deg=13, elevations=(20,))[2]
        fr = r.render(eye)
        ras = rasterize_reference(RasterMesh(model.mesh_vertices, model.mesh_faces, model.mesh_colors), eye)
        ref = vdtm_reference(eye, ras.depth, ras.color, model.rgbz.cameras, model.rgbz.rgb, r.vis_depth,
                             r.vis_tol)
        assert np.mean(fr.mask != ras.mask) <= EDGE_FRAC
        both = fr.mask & ras.mask
        assert_images_close(fr.rgb, ref.astype(np.float32), mean_tol=COLOUR_TOL, max_tol=COLOUR_TOL,
                            outlier_frac=EDGE_FRAC, mask=both, what="vdtm vs twin")
    finally:
        r.release()


def test_vdtm_input_pose(gl_ctx, model):
    """At an input camera the baseline shows that camera's image inside the mesh silhouette
    (which differs from the true one by the marching-cubes error: compare inside both)."""
    r = VdtmRenderer.from_model(gl_ctx, model, ONE)
    try:
        cam = model.rgbz.cameras[4]
        fr = r.render(cam)
        inside = fr.mask & (model.rgbz.depth[4] > 0)
        st = image_diff_stats(to_uint8_srgb(fr.rgb), to_uint8_srgb(model.rgbz.rgb[4]), inside)
        assert st["psnr"] > 40.0, st
    finally:
        r.release()


def test_vertex_colour_floor(gl_ctx, model):
    cam = model.rgbz.cameras[0]
    with MeshColourRenderer.from_model(gl_ctx, model, ONE) as r:
        fr = r.render(cam)
    inside = fr.mask & (model.rgbz.depth[0] > 0)
    assert inside.sum() > 0.9 * (model.rgbz.depth[0] > 0).sum()
    st = image_diff_stats(to_uint8_srgb(fr.rgb), to_uint8_srgb(model.rgbz.rgb[0]), inside)
    assert st["psnr"] > 25.0, st  # smooth procedural colour, vertex-interpolated


def test_vdtm_alpha_matches_numpy_twin(gl_ctx, model):
    """With a matte: premultiplied colour + alpha blended on the GPU as in the twin (the vertex
    colour fallback opaque); mesh-colour samples no RGBz and keeps its coverage as alpha."""
    from render.microfacet.rgbz_textures import RGBZ_DTYPE, rgbz_array

    ma = scene.with_alpha(model, scene.soft_matte(model.rgbz.depth))
    r = VdtmRenderer.from_model(gl_ctx, ma, ONE)
    try:
        eye = scene.ring_cameras(12, phase_deg=13, elevations=(20,))[2]
        fr = r.render(eye)
        ras = rasterize_reference(RasterMesh(model.mesh_vertices, model.mesh_faces, model.mesh_colors), eye)
        pm = rgbz_array(ma.rgbz.rgb, ma.rgbz.depth, ma.rgbz.alpha)[..., :3].astype(np.float64)
        rgba = np.concatenate([pm, ma.rgbz.alpha.astype(RGBZ_DTYPE).astype(np.float64)[..., None]], -1)
        ref = vdtm_reference(eye, ras.depth, ras.color, model.rgbz.cameras, rgba, r.vis_depth, r.vis_tol)
        both = fr.mask & ras.mask
        assert np.mean((ref[..., 3] > 0.05) & (ref[..., 3] < 0.95) & both) > 0.02  # partial alpha to carry
        assert_images_close(fr.rgb, ref[..., :3].astype(np.float32), mean_tol=COLOUR_TOL, max_tol=COLOUR_TOL,
                            outlier_frac=EDGE_FRAC, mask=both, what="vdtm rgb with alpha vs twin")
        assert_images_close(fr.alpha[..., None], ref[..., 3:].astype(np.float32), mean_tol=COLOUR_TOL,
                            max_tol=COLOUR_TOL, outlier_frac=EDGE_FRAC, mask=both, what="vdtm alpha vs twin")
    finally:
        r.release()
    with MeshColourRenderer.from_model(gl_ctx, ma, ONE) as mc, MeshColourRenderer.from_model(gl_ctx, model, ONE) as m0:
        np.testing.assert_array_equal(mc.render(eye).alpha, m0.render(eye).alpha)

"""The renderer interface (render.methods, render.owner, render.frame): every registered method
builds from a model, returns a Frame, changes options per frame without re-uploading, and
releases idempotently."""

from __future__ import annotations

import numpy as np
import pytest

from capture.camera import Camera, gl_ndc_depth_to_z, gl_rows_to_image, look_at
from render.antialias import box_resolve
from render.frame import Frame
from render.methods import METHODS, RenderOptions, create_renderer, method_class, method_spec
from render.owner import NEAR_FRACTION_INSIDE, mat4_bytes, near_far
from tests import scenes as scene
from tests.conftest import assert_images_close

#: Methods whose one-sample frames have soft edges (3D Gaussians: every pixel an alpha blend).


@pytest.fixture(scope="module")
def model():
    return scene.build_model(scene.ring_cameras(12))


def _eye(i=2):
    return scene.ring_cameras(12, phase_deg=17, elevations=(12,))[i]


@pytest.mark.parametrize("name", list(METHODS))
def test_every_method_returns_a_frame(gl_ctx, model, name):
    eye = _eye()
    with create_renderer(name, gl_ctx, model, RenderOptions(supersample=1)) as r:
        assert r.name == name and r.alive
        fr = r.render(eye)
        assert isinstance(fr, Frame) and fr.size == (eye.width, eye.height)
        assert fr.rgb.dtype == fr.alpha.dtype == fr.depth.dtype == np.float32
        assert fr.mask.sum() > 200, "the scene fills a good part of the view"
        if method_spec(name).alpha == "soft":  # semi-transparent primitives: every pixel a blend
            assert fr.alpha.min() >= 0 and fr.alpha.max() <= 1 and (fr.alpha > 0.99).sum() > 200
        else:
            assert set(np.unique(fr.alpha)) <= {0.0, 1.0}  # one sample: drawn or not
        assert np.all(fr.depth[~fr.mask] == 0) and np.all(fr.rgb[~fr.mask] == 0)
        # depth of the drawn pixels: on the object (within the scene's bounding spheres' depth range)
        near, far = near_far(eye, scene.BOUNDS)
        assert np.all((fr.depth[fr.mask] > near) & (fr.depth[fr.mask] < far))
        st = fr.stats.record()
        assert st.get("facets", 1) > 0 and st["supersample"] == 1 and st["ms"] > 0  # facets: where counted
        empty = r.render(eye, read=False)
        assert not empty.mask.any() and empty.stats.facets == fr.stats.facets
    assert not r.alive
    r.release()  # idempotent
    with pytest.raises(RuntimeError, match="release"):
        r.render(eye)


@pytest.mark.parametrize("name", [m for m in METHODS if method_spec(m).supersample])
def test_supersampled_frame_is_resolve_of_its_samples(gl_ctx, model, name):
    """Every method that supersamples goes through the one GPU resolve: the frame equals the
    numpy box resolve of the samples it drew (colour mean, nearest depth).  (``points`` draws one
    sample per pixel whatever the options: tests/render/points/test_points.py.)"""
    eye = _eye(5)
    with create_renderer(name, gl_ctx, model) as r:
        fr = r.render(eye, supersample=2)
        # the GL owner that drew the samples (mesh-colour draws with its mesh rasteriser)
        owner = getattr(r, "rasterizer", r)
        big_c, big_d = owner.frame_samples()
        near, far = owner.planes(eye) if owner is not r else near_far(eye, model.bounds)
    col, d01 = box_resolve(gl_rows_to_image(big_c), gl_rows_to_image(big_d), 2)
    np.testing.assert_allclose(fr.rgb, col[..., :3], atol=1e-6)
    np.testing.assert_allclose(fr.alpha, col[..., 3], atol=1e-6)
    assert 0 < np.mean((fr.alpha > 0) & (fr.alpha < 1)) < 0.2  # fractional only at edges
    z = gl_ndc_depth_to_z(d01, near, far)
    np.testing.assert_allclose(fr.depth[fr.mask], z[fr.mask], rtol=1e-5)


def test_mesh_colour_honours_supersample(gl_ctx, model):
    """mesh-colour at S x S samples = the S x S box average of one-sample frames of the scaled eye."""
    eye = _eye(7)
    with create_renderer("mesh-colour", gl_ctx, model) as r:
        a = r.render(eye, supersample=2)
        big = r.render(eye.scaled(2), supersample=1)
    H, W = eye.height, eye.width
    ref = big.rgb.reshape(H, 2, W, 2, 3).mean(axis=(1, 3))
    assert_images_close(a.rgb, ref, mean_tol=1e-6, max_tol=1e-5, what="mesh-colour supersampled vs averaged")
    np.testing.assert_allclose(a.alpha, big.alpha.reshape(H, 2, W, 2).mean(axis=(1, 3)), atol=1e-6)
    assert a.stats.supersample == 2


def test_options_change_per_frame_without_reupload(gl_ctx, model):
    eye = _eye()
    with create_renderer("microfacet", gl_ctx, model, RenderOptions(supersample=1)) as r:
        a = r.render(eye)
        levels = [lv.resolution for lv in r.levels]
        uploads = (r.tex, r.cam_buf, r.slice_buf, *[b for bufs in r.voxel_bufs for b in bufs])
        for opts in (dict(refine=0), dict(mode="geometry"), dict(supersample=2), dict(tolerance_px=2.0),
                     dict(level=levels[1]), dict(refine=0)):
            r.render(eye, **opts)
        assert (r.tex, r.cam_buf, r.slice_buf, *[b for bufs in r.voxel_bufs for b in bufs]) == uploads
        # programs: one per (kind, refine, debug output) used, compiled once (the instanced path's
        # visibility pre-pass and compute pass never refine)
        assert sorted(r._programs) == [("colour", 0, None), ("colour", 2, None), ("geometry", 2, None),
                                       ("prepass", 0, None), ("select", 0, None)]
        b = r.render(eye)  # back to the renderer's options: the same frame (up to depth ties between
        # slices, whose draw order follows the compute pass's atomic counter)
        assert_images_close(b.rgb, a.rgb, mean_tol=1e-4, max_tol=1e-6, outlier_frac=0.002, what="same options again")
        assert a.stats.level == b.stats.level and a.stats.facets == b.stats.facets


def test_registry_and_options():
    assert set(METHODS) == {"microfacet", "mesh-vdtm", "mesh-colour", "points", "gather", "splat"}
    for name in METHODS:
        assert method_class(name).name == name == method_spec(name).name
    with pytest.raises(ValueError, match="unknown rendering method"):
        method_class("nope")
    # the shared options are RenderOptions' own; a method's are its spec's dataclass
    mf = RenderOptions.for_method("microfacet", supersample=1, tolerance_px=4.0, refine=0)
    assert mf.supersample == 1 and mf.of("microfacet").tolerance_px == 4.0 and mf.of("microfacet").refine_steps == 0
    assert RenderOptions().of("microfacet").refine_steps == 2 and RenderOptions().of("gather") is None
    with pytest.raises(ValueError, match="has no option tolerance_px"):
        RenderOptions().changed_for("mesh-vdtm", tolerance_px=4.0)
    with pytest.raises(ValueError, match="has no option"):
        RenderOptions().changed_for("microfacet", nope=1)
    assert RenderOptions().changed_for("points", supersample=3).supersample == 3  # shared: any method may carry it
    for bad in (dict(supersample=0), dict(refine=-1), dict(refine=9), dict(mode="x"), dict(tolerance_px=0.0),
                dict(spacing=-1.0), dict(level=0), dict(debug="nosuch")):
        with pytest.raises(ValueError):
            RenderOptions.for_method("microfacet", **bad)
    with pytest.raises(ValueError, match="must be MicrofacetOptions"):
        RenderOptions(methods={"microfacet": 3})


def test_render_rejects_a_bare_tolerance(gl_ctx, model):
    with create_renderer("mesh-vdtm", gl_ctx, model) as r:
        with pytest.raises(TypeError, match="tolerance_px"):
            r.render(_eye(), 8.0)


def test_mat4_bytes_is_column_major():
    m = np.arange(16, dtype=np.float64).reshape(4, 4)
    got = np.frombuffer(mat4_bytes(m), np.float32)
    assert got.tolist() == m.T.reshape(-1).tolist()  # GLSL mat4: columns one after the other


def test_near_far_holds_the_box_and_handles_an_eye_inside():
    eye = _eye()
    near, far = near_far(eye, scene.BOUNDS)
    b = scene.BOUNDS
    corners = np.array([[b[i, 0], b[j, 1], b[k, 2]] for i in (0, 1) for j in (0, 1) for k in (0, 1)])
    z = eye.world_to_cam(corners)[:, 2]
    assert 0 < near < z.min() and far > z.max()
    inside = Camera(eye.K, look_at(np.zeros(3), (1.0, 0.0, 0.0)), eye.width, eye.height)  # at the box centre
    n2, f2 = near_far(inside, b)
    assert n2 == pytest.approx(NEAR_FRACTION_INSIDE * np.linalg.norm(b[1] - b[0]))
    assert f2 > inside.world_to_cam(corners)[:, 2].max()

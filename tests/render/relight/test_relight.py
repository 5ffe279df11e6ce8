"""The relighting GL owner (render.relight.gl.Relighter): its two passes against their numpy twins, a
Lambertian object relit against the rasteriser's shading under the new map, the identity, the
model without capture lighting."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from render.frame import Frame, FrameStats
from render.mesh.raster.gl import Lighting, MeshRasterizer, RasterMesh
from render.relight.gl import NotRelightable, RelightConfig, Relighter
from render.relight.reference import apply_reference, share_volume_reference
from render.shading.envmap import EnvMap, procedural_sky
from render.shading.irradiance import irradiance_table
from tests import scenes as scene
from volume.model import CaptureLighting

#: The stats of the hand-made frames relit here.
STATS = FrameStats(0, 0, supersample=1)

#: Share-volume twin: float32 GLSL against float64 numpy; a voxel whose sphere test or band test
#: flips (a point on a sphere's surface) may differ, so all but this share of voxels agree to 1e-3.
SHARE_FLIP_SHARE = 0.005
#: Apply twin: relative tolerance on the relit colour (float32 trilinear lookups and gradients).
APPLY_RTOL = 1e-3


_sun_sky = scene.sun_sky_env


@pytest.fixture(scope="module")
def model():
    cams = scene.ring_cameras(8)
    m = scene.build_model(cams)
    return dataclasses.replace(m, capture_env=CaptureLighting(procedural_sky(32).data, np.array([0, 0, 1.0]), 0, "sky"))


def _frame_of(res) -> Frame:
    return Frame(res.color, res.alpha, res.depth, STATS)


def test_twins(gl_ctx, model):
    cam = scene.ring_cameras(8, 96, 72)[1]
    rng = np.random.default_rng(0)
    dep = np.where(rng.random((72, 96)) < 0.7, rng.uniform(0.25, 0.45, (72, 96)), 0.0).astype(np.float32)
    fr = Frame(rng.random((72, 96, 3), dtype=np.float32), (dep > 0).astype(np.float32), dep, STATS)
    cfg = RelightConfig(kernel="wrap", volume_res=16, visibility=True, strands=True)
    with Relighter(gl_ctx, model, procedural_sky(32), _sun_sky(), cfg) as rel:
        ref = share_volume_reference(rel.raw, rel.smooth, rel.capture, rel.new, model.spheres)
        d = np.abs(ref - rel.share_volume).max(-1)
        assert (ref < 0.98).any()  # the spheres do shade part of the band
        assert np.mean(d > 1e-3) <= SHARE_FLIP_SHARE and d.mean() < 1e-4, (np.mean(d > 1e-3), d.mean())
        out = rel.apply(fr, cam)
        want = apply_reference(fr.rgb, fr.depth, cam, rel.smooth, rel.share_volume, rel.capture, rel.new,
                               strands=rel.strands, hair=rel.hair, strand_weight=cfg.strand_weight,
                               **rel.config.gain_kwargs())
        np.testing.assert_allclose(out.rgb, want, rtol=APPLY_RTOL, atol=1e-6)
        np.testing.assert_array_equal(out.rgb[dep == 0], fr.rgb[dep == 0])  # no depth: unchanged
        assert out.alpha is fr.alpha or np.array_equal(out.alpha, fr.alpha)


def test_auto_kernel_twin(gl_ctx, model):
    """Kernel "auto": the transfer fitted to the model's capture views is a mixed kernel, and the GLSL
    apply pass with it agrees with the numpy twin; a fixed mix exercising every basis kernel does too."""
    from render.shading import transfer as rl

    cam = scene.ring_cameras(8, 96, 72)[3]
    rng = np.random.default_rng(4)
    dep = np.where(rng.random((72, 96)) < 0.8, rng.uniform(0.25, 0.45, (72, 96)), 0.0).astype(np.float32)
    fr = Frame(rng.random((72, 96, 3), dtype=np.float32), (dep > 0).astype(np.float32), dep, STATS)
    for cfg in (RelightConfig(kernel="auto", volume_res=16),
                RelightConfig(kernel=rl.mix_kernel([0.1, 0.2, 0.3, 0.4]), forward=0.7, forward_g=0.6, volume_res=16)):
        with Relighter(gl_ctx, model, procedural_sky(32), _sun_sky(), cfg) as rel:
            assert rel.config.kernel.startswith(rl.MIX_PREFIX) and (rel.fit is not None) == (cfg.kernel == "auto")
            out = rel.apply(fr, cam)
            want = apply_reference(fr.rgb, fr.depth, cam, rel.smooth, rel.share_volume, rel.capture, rel.new,
                                   **rel.config.gain_kwargs())
        np.testing.assert_allclose(out.rgb, want, rtol=APPLY_RTOL, atol=1e-6)


def _random_strands(rel, rng):
    """A StrandColour on the relighter's cube with random tangents, scores and fibre colours (the twin
    must agree wherever the strand gain is blended in, whatever the capture views gave)."""
    from render.relight.strands import StrandColour, StrandField

    L = 12
    t = rng.normal(size=(L, L, L, 3))
    t /= np.linalg.norm(t, axis=-1, keepdims=True)
    field = StrandField(t, rng.uniform(0, 1, (L, L, L)), rel.raw.origin, rel.raw.voxel * rel.raw.resolution / L)
    fit = np.concatenate([rng.uniform(0.05, 1, (L, L, L, 3)), rng.uniform(0, 0.3, (L, L, L, 1))], -1)
    return StrandColour(field, fit.astype(np.float32))


def test_strand_twin(gl_ctx, model):
    """The strand branch of the apply pass (relight_hair.glsl) against its numpy twin, with random strands
    blended in almost everywhere and maps that differ in direction and colour."""
    cam = scene.ring_cameras(8, 96, 72)[2]
    rng = np.random.default_rng(3)
    dep = np.where(rng.random((72, 96)) < 0.8, rng.uniform(0.25, 0.45, (72, 96)), 0.0).astype(np.float32)
    fr = Frame(rng.random((72, 96, 3), dtype=np.float32), (dep > 0).astype(np.float32), dep, STATS)
    cfg = RelightConfig(volume_res=16, strands=True)
    red_sun = EnvMap((_sun_sky(sun=(-0.5, 0.6, 0.3)).data * np.array([1.0, 0.3, 0.1], np.float32)), "red")
    with Relighter(gl_ctx, model, _sun_sky(), red_sun, cfg) as rel:
        rel.set_strands(_random_strands(rel, rng))
        out = rel.apply(fr, cam)
        want = apply_reference(fr.rgb, fr.depth, cam, rel.smooth, rel.share_volume, rel.capture, rel.new,
                               strands=rel.strands, hair=rel.hair, strand_weight=cfg.strand_weight,
                               **rel.config.gain_kwargs())
        surface = apply_reference(fr.rgb, fr.depth, cam, rel.smooth, rel.share_volume, rel.capture, rel.new,
                                  **rel.config.gain_kwargs())
    assert np.abs(want - surface).max() > 0.05  # the strand branch does change the result
    np.testing.assert_allclose(out.rgb, want, rtol=APPLY_RTOL, atol=1e-5)


def test_lambertian_object_relit_like_the_rasteriser(gl_ctx, model):
    """A Lambertian object (the spheres, ambient light only, no shadows) shaded by the rasteriser
    under the capture map, relit with the Lambert kernel, against the same shading under the new
    map: close to exact where the single gain is far off (measured 42.2 dB against 21.9 dB)."""
    from render import metrics

    verts, faces = scene.mesh(64)
    mesh = RasterMesh(verts, faces, np.full((len(verts), 3), 0.6, np.float32))
    cam = scene.ring_cameras(8, 160, 120)[3]
    a_env, b_env = procedural_sky(32), _sun_sky()
    with MeshRasterizer(gl_ctx) as rast:
        rast.set_mesh(mesh)
        shots = []
        for env in (a_env, b_env):
            rast.set_lighting(Lighting(None, np.zeros((0, 3)), np.zeros((0, 3)), exposure=0.3, shadows=False,
                                       irradiance=irradiance_table(env, 32)))
            shots.append(rast.render(cam))
    m = dataclasses.replace(model, capture_env=CaptureLighting(a_env.data, np.array([0, 0, 1.0]), 0, "sky"))
    cfg = RelightConfig(kernel="lambert", visibility=False, forward=0.0, smooth=0.0, volume_res=64)
    with Relighter.from_model(gl_ctx, m, b_env, cfg) as rel:
        relit = rel.apply(_frame_of(shots[0]), cam).rgb
        gain = shots[0].color * rel.global_gain.astype(np.float32)
    mask = shots[1].mask
    p_relit = metrics.psnr(shots[1].color, relit, mask)
    p_gain = metrics.psnr(shots[1].color, gain, mask)
    assert p_relit > 38.0 and p_relit > p_gain + 15.0, (p_relit, p_gain)


@pytest.mark.parametrize("strands", [False, True])
def test_same_map_is_the_identity(gl_ctx, model, strands):
    cam = scene.ring_cameras(8, 64, 48)[0]
    dep = np.full((48, 64), 0.35, np.float32)
    fr = Frame(np.full((48, 64, 3), 0.4, np.float32), np.ones((48, 64), np.float32), dep, STATS)
    with Relighter.from_model(gl_ctx, model, procedural_sky(32), RelightConfig(volume_res=16, strands=strands)) as rel:
        np.testing.assert_allclose(rel.apply(fr, cam).rgb, fr.rgb, rtol=1e-6)
        rel.set_new_env(_sun_sky())  # the viewer's switch: another map, another result
        assert np.abs(rel.apply(fr, cam).rgb - fr.rgb).max() > 0.05


def test_model_without_capture_lighting_cannot_be_relit(gl_ctx):
    m = scene.build_model(scene.ring_cameras(4))
    with pytest.raises(NotRelightable, match="cannot be relit.*--capture-env"):
        Relighter.from_model(gl_ctx, m, procedural_sky(16))


def test_config_is_validated():
    with pytest.raises(ValueError, match="kernel"):
        RelightConfig(kernel="phong")
    with pytest.raises(ValueError, match="sg_lobes"):
        RelightConfig(sg_lobes=0)

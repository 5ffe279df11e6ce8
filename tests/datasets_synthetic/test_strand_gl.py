"""The GL synthetic renderer (datasets_synthetic/strand_gl.py) against its numpy twins: the ring
formulas of strand_ribbon.glsl, the shadow-map lookups, the hair lobes, and whole images against
the numpy renderer (every strand a tube of triangles, the lobes in numpy), with stated tolerances."""

from __future__ import annotations

import numpy as np
import pytest

from datasets_synthetic.geometry import merge, tube_sweep
from datasets_synthetic.hair_shading import (
    ENV_SHADOW_MAP_SIZE,
    HairLighting,
    back_albedo,
    prepare_hair,
    strand_radiance,
)
from datasets_synthetic.lighting import LightingConfig, ambient_residual, resolve_env, scene_lighting
from datasets_synthetic.rig import TurntableRig
from datasets_synthetic.scenes import build_scene
from datasets_synthetic.strand_gl import StrandRasterizer
from datasets_synthetic.strand_shaders import load_synth_shader
from datasets_synthetic.strands import front_chain, ring_direction, silhouette_vertices, split_strands
from datasets_synthetic.synth_renderer import SceneRenderer
from render.mesh.raster.gl import SHADOW_BIAS_TEXELS, SHADOW_BOX_MARGIN, MeshRasterizer, RasterMesh
from render.mesh.raster.shadow_maps import light_view_projection, shadow_map_visibility
from render.shading.hair import HairParams, sigma_a_from_colour

#: Lobe pass against hair_shading.strand_radiance on the same inputs: max |diff| / the largest
#: radiance (float32 against float64; measured 1.0e-3 on 27,000 points x 11 lights).
LOBE_TOL_OF_PEAK = 3e-3
#: Shadow lookups in GLSL against shadow_map_visibility on the same map: mean |diff| (float32
#: against float64 point transforms: a point on a depth edge can flip a tap).
LOOKUP_MEAN_TOL = 1e-3
#: Visibility of the hair lights from the GL maps (surfaces + the strands' facets facing the light)
#: against the numpy renderer's (surfaces + whole tubes): mean |diff| per light, measured <= 1.1e-3
#: on a 3,000-strand fur ball (3 dominant + 8 cut lights).
VISIBILITY_MEAN_TOL = 3e-3

#: Whole images, GL against the numpy renderer (96 x 72, supersample 3, no film filter; what
#: follows the rasteriser, film filter, matte, sensor, is the same code for both).  The GL strands
#: are the tubes' own facets (same vertices, triangulation, depth and normals; the back faces are
#: not drawn, and where a segment twists the chain can differ by a facet at its silhouette), the
#: lobes agree to float32 round-off and the visibility to VISIBILITY_MEAN_TOL; the rest is where two
#: facets meet at equal depth (the plant's needles on their branches) and the order decides.
#: Over the pixels either covers, measured (fur ball chiang / plant chiang / fur ball Kajiya-Kay,
#: 2 views each): linear colour mean |diff| <= 3.9e-5 / 1.3e-4 / 4.1e-5; coverage mean |diff| 0 /
#: 4.3e-4 / 0, no pixel's coverage off by more than one supersample (1/9); depth where both cover
#: off by more than 1 mm on 0 / 0.13 % / 0 of the pixels; normals equal (median cosine 1.0).
IMAGE_COLOUR_MEAN_TOL = 1e-3
IMAGE_ALPHA_MEAN_TOL = 2e-3
IMAGE_ALPHA_SAMPLE = 1.0 / 9.0 + 1e-4
IMAGE_ALPHA_OUTLIERS = 2e-3
DEPTH_TOL_M = 1e-3
DEPTH_OUTLIERS = 5e-3


def _tubes(n=6, P=5, sides=3, seed=0):
    rng = np.random.default_rng(seed)
    start = rng.uniform(-0.02, 0.02, (n, 1, 3))
    d = rng.normal(size=(n, 1, 3))
    paths = start + d / np.linalg.norm(d, axis=-1, keepdims=True) * np.linspace(0, 0.02, P)[None, :, None]
    paths[:, :, 2] += 0.003 * np.sin(np.linspace(0, 3, P))[None]
    radii = np.linspace(4e-4, 1e-4, P)[None].repeat(n, 0)
    return paths, radii, tube_sweep(paths, radii, sides, rng.uniform(0.05, 0.8, (n, 3)))


def test_split_strands_recovers_rings_segments_and_surfaces():
    paths, radii, tubes = _tubes(n=4, P=5, sides=4)
    skin = RasterMesh(np.eye(3) * 0.05, np.array([[0, 1, 2]]), np.full((3, 3), 0.3))
    geo = split_strands(merge([skin, tubes]))
    assert geo.count == 20
    np.testing.assert_allclose(geo.points.centres, paths.reshape(-1, 3), atol=1e-7)
    np.testing.assert_allclose(geo.radius, radii.reshape(-1), rtol=1e-5)
    assert np.all(geo.sides == 4)
    expect = np.array([[s * 5 + p, s * 5 + p + 1] for s in range(4) for p in range(4)])
    assert np.array_equal(geo.segments, expect)
    # ring vertex k of every point is tube_sweep's vertex k
    ring = geo.points.centres[:, None] + geo.radius[:, None, None] * np.stack(
        [ring_direction(geo.points.tangents, geo.frame, k, 4) for k in range(4)], 1)
    np.testing.assert_allclose(ring.reshape(-1, 3), tubes.vertices, atol=2e-7)
    assert geo.surfaces is not None and len(geo.surfaces.faces) == 1
    np.testing.assert_array_equal(geo.surfaces.vertices, skin.vertices)


def test_front_chain_spans_the_silhouette():
    """The chain's vertices hold both rings' extreme vertices across the view (numpy twin)."""
    rng = np.random.default_rng(1)
    T = rng.normal(size=(500, 3))
    T /= np.linalg.norm(T, axis=1, keepdims=True)
    N = np.cross(T, rng.normal(size=(500, 3)))
    N /= np.linalg.norm(N, axis=1, keepdims=True)
    w = rng.normal(size=(500, 3))
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    for sides in (3, 4, 5, 8):
        s0 = silhouette_vertices(T, N, sides, w)
        start, count = front_chain(s0, s0, sides)
        x = np.stack([np.sum(ring_direction(T, N, k, sides) * np.cross(w, T), -1) for k in range(sides)], -1)
        assert np.all(count <= sides // 2 + 2)  # (one ring: its chain is never a single vertex)
        for i in range(len(T)):
            ks = [(start[i] + j) % sides for j in range(count[i])]
            assert ks[0] == np.argmax(x[i]) and ks[-1] == np.argmin(x[i])
            # the chain runs over the viewer's side: its inner vertices face w
            inner = ks[1:-1]
            assert all(np.dot(ring_direction(T[i], N[i], k, sides), w[i]) > -1e-9 for k in inner)


def test_ring_formulas_match_their_glsl(gl_ctx):
    """silhouette_vertices / front_chain of strand_ribbon.glsl against the numpy twins, exactly."""
    rng = np.random.default_rng(2)
    n = 256
    T = rng.normal(size=(n, 3))
    T /= np.linalg.norm(T, axis=1, keepdims=True)
    N = np.cross(T, rng.normal(size=(n, 3)))
    N /= np.linalg.norm(N, axis=1, keepdims=True)
    w0, w1 = (v / np.linalg.norm(v, axis=1, keepdims=True) for v in rng.normal(size=(2, n, 3)))
    sides = rng.integers(3, 9, n)
    src = ("#version 430\nlayout(local_size_x = 64) in;\n" + load_synth_shader("strand_ribbon.glsl") + """
layout(std430, binding = 0) readonly buffer In { vec4 data[]; };
layout(std430, binding = 1) writeonly buffer Out { ivec4 res[]; };
void main() {
    int i = int(gl_GlobalInvocationID.x);
    vec3 T = data[4 * i].xyz, N = data[4 * i + 1].xyz, w0 = data[4 * i + 2].xyz, w1 = data[4 * i + 3].xyz;
    int s = int(data[4 * i].w);
    ivec2 a = silhouette_vertices(T, N, s, w0), b = silhouette_vertices(T, N, s, w1);
    res[i] = ivec4(a, front_chain(a, b, s));
}""")
    data = np.zeros((n, 4, 4), np.float32)
    data[:, 0, :3], data[:, 0, 3], data[:, 1, :3], data[:, 2, :3], data[:, 3, :3] = T, sides, N, w0, w1
    cs = gl_ctx.compute_shader(src)
    bi, bo = gl_ctx.buffer(data.tobytes()), gl_ctx.buffer(reserve=n * 16)
    bi.bind_to_storage_buffer(0)
    bo.bind_to_storage_buffer(1)
    cs.run(n // 64)
    got = np.frombuffer(bo.read(), np.int32).reshape(n, 4)
    for o in (cs, bi, bo):
        o.release()
    d = data.astype(np.float64)
    for i in range(n):
        a = silhouette_vertices(d[i, 0, :3], d[i, 1, :3], sides[i], d[i, 2, :3])
        b = silhouette_vertices(d[i, 0, :3], d[i, 1, :3], sides[i], d[i, 3, :3])
        start, count = front_chain(a, b, sides[i])
        assert list(got[i]) == [a[0], a[1], start, count], (i, got[i], a, b, start, count)


@pytest.fixture(scope="module")
def furball_gl(gl_ctx):
    """A 3,000-strand fur ball under the studio map (3 dominant + 8 cut lights) in both renderers."""
    sc = build_scene("furball", 1, strands=3000)
    lc = LightingConfig(hair_env_lights=8)
    env = resolve_env(lc.env)
    lighting, _ = scene_lighting(env, lc)
    rest = ambient_residual(env, lc)
    with StrandRasterizer(gl_ctx) as g, MeshRasterizer(gl_ctx) as r:
        g.set_scene(sc.mesh, lighting, rest, "chiang", 8, True)
        hair = prepare_hair(r, sc.mesh, lighting, rest, "chiang", 8, True)
        yield sc, g, hair


def test_lobe_pass_matches_numpy(furball_gl):
    """strand_lobes_comp.glsl against hair_shading.strand_radiance with the same lights and visibility."""
    sc, g, hair = furball_gl
    vis = g.strand_visibility().astype(np.float64)
    sa = sigma_a_from_colour(hair.points.colours)
    ms = np.maximum(hair.points.colours - back_albedo(sa, HairParams(), hair.nodes), 0) / np.pi
    hl = HairLighting(hair.points, hair.dirs, hair.power, vis, sa, ms, hair.params, hair.nodes, hair.spread)
    eye = np.array([0.35, -0.2, 0.12])
    got = g.strand_radiance(eye)
    ref = strand_radiance(hl, eye)
    assert np.abs(got - ref).max() / ref.max() < LOBE_TOL_OF_PEAK


def test_visibility_lookups_match_numpy_and_the_tubes(furball_gl, gl_ctx):
    sc, g, hair = furball_gl
    vis = g.strand_visibility()
    # the ribbons' maps against the tubes' maps (the numpy renderer's), light by light
    diff = np.abs(vis - hair.visibility).mean(0)
    assert np.all(diff < VISIBILITY_MEAN_TOL), diff
    assert 0.1 < vis[:, :3].mean() < 0.9  # the fur shadows itself
    # the GLSL lookup against shadow_map_visibility on one map (the first cut light)
    b = sc.mesh.bounds
    centre, radius = 0.5 * (b[0] + b[1]), 0.5 * float(np.linalg.norm(b[1] - b[0])) * (1 + SHADOW_BOX_MARGIN)
    d = hair.dirs[3]
    vp = light_view_projection(d, centre, radius)
    depth = g._shadow_map(vp, d, ENV_SHADOW_MAP_SIZE).read_depth()
    bias = SHADOW_BIAS_TEXELS * 2 * radius / ENV_SHADOW_MAP_SIZE
    ref = shadow_map_visibility(hair.points.centres, depth, vp, d, bias)
    assert np.abs(vis[:, 3] - ref).mean() < LOOKUP_MEAN_TOL


def _both(scene, gl_ctx, hair="chiang", **over):
    sc = build_scene(scene, 1, **over)
    lc = LightingConfig(hair_env_lights=8, hair_model=hair)
    env = resolve_env(lc.env)
    lighting, _ = scene_lighting(env, lc)
    rest = ambient_residual(env, lc)
    cams = TurntableRig(views_per_ring=6, width=96, height=72).cameras(float(np.linalg.norm(sc.mesh.vertices,
                                                                                           axis=1).max()))[:2]
    out = {}
    for kind in ("numpy", "gl"):
        with SceneRenderer(gl_ctx, kind, 3, sc.mesh, lighting, rest, lc) as rend:
            out[kind] = [rend.render(c) for c in cams]
    return out["numpy"], out["gl"]


@pytest.mark.parametrize("scene, hair, over", [("furball", "chiang", {"strands": 1500}), ("plant", "chiang", {}),
                                               ("furball", "kajiya-kay", {"strands": 1500})])
def test_gl_images_match_the_numpy_renderer(gl_ctx, scene, hair, over):
    ref, got = _both(scene, gl_ctx, hair, **over)
    for a, b in zip(ref, got):
        fg = (a.alpha > 0) | (b.alpha > 0)
        assert fg.mean() > 0.05
        assert np.abs(a.color - b.color)[fg].mean() < IMAGE_COLOUR_MEAN_TOL
        da = np.abs(a.alpha - b.alpha)[fg]
        assert da.mean() < IMAGE_ALPHA_MEAN_TOL
        assert (da > IMAGE_ALPHA_SAMPLE).mean() < IMAGE_ALPHA_OUTLIERS
        both = a.mask & b.mask
        assert both.sum() > 0.95 * max(a.mask.sum(), b.mask.sum())
        assert (np.abs(a.depth - b.depth)[both] > DEPTH_TOL_M).mean() < DEPTH_OUTLIERS
        assert np.median(np.sum(a.normal * b.normal, -1)[both]) > 0.999


def test_gl_scene_without_strands_is_the_rasteriser(gl_ctx):
    ref, got = _both("torus", gl_ctx)
    for a, b in zip(ref, got):
        assert np.array_equal(a.alpha, b.alpha) and np.array_equal(a.depth, b.depth)
        assert np.abs(a.color - b.color).max() < 1e-3  # shadow lookups in GLSL against numpy: a few taps


def test_strands_that_are_not_tube_rings_are_refused():
    """A strand vertex run that is not a ring of equidistant vertices names the numpy renderer."""
    from datasets_synthetic.strands import StrandError
    from datasets_synthetic.synth import SynthConfig

    v = np.array([[0, 0, 0], [0.01, 0, 0], [0, 0.03, 0]], float)
    bad = RasterMesh(v, np.array([[0, 1, 2]]), np.full((3, 3), 0.5), tangents=np.tile([0, 0, 1.0], (3, 1)))
    with pytest.raises(StrandError, match="synth-renderer numpy"):
        split_strands(bad)
    with pytest.raises(ValueError, match="renderer must be one of"):
        SynthConfig(renderer="cuda")


#: The realism bench (furrow bench synth_realism) on a 12-view 160 x 120 fur ball made by each
#: renderer: the largest |GL - numpy| allowed per statistic (fractions of the image / of the
#: pixels, 8-bit luma and Laplacian units, dB).  Measured here: fg 0, fg_luma 0.003, sharp 0.016,
#: depth_cover 0, miss@k <= 0.00015, points PSNR 0.0005 dB, SSIM 0.0001, sharpness ratio 0.0003;
#: at the demo's 36 views 320 x 240 (seed 1, docs/synthetic.md): fur ball fg 1e-5, luma 0.001,
#: sharp 0.018, miss@k <= 0.00015, PSNR 0.003 dB, SSIM 0.0002; plant fg 3e-5, luma 0.017, sharp
#: 0.019, miss@k <= 0.0008, PSNR 0.005 dB, SSIM 0.001.
REALISM_TOL = {"fg": 2e-3, "fg_luma": 0.2, "sharp": 0.3, "depth_cover": 2e-3, "miss@1": 5e-3, "miss@2": 5e-3,
               "miss@4": 5e-3, "points_psnr": 0.05, "points_ssim": 5e-3, "points_sharp_ratio": 0.01}


def test_realism_bench_numbers_match(tmp_path, gl_ctx):
    from datasets_synthetic.sensor import SENSORS
    from datasets_synthetic.synth import SynthConfig, synthesize, write_capture
    from furrow.bench.synth_realism import capture_stats

    stats = {}
    for kind in ("numpy", "gl"):
        cfg = SynthConfig(scene="furball", seed=1, rig=TurntableRig(views_per_ring=12, width=160, height=120),
                          scene_params={"strands": 1500}, lighting=LightingConfig(hair_env_lights=8),
                          sensor=SENSORS["d435"], pixel_filter_px=0.5, renderer=kind)
        write_capture(synthesize(cfg, gl_ctx), tmp_path / kind)
        stats[kind] = capture_stats(tmp_path / kind)
    diff = {k: abs(stats["gl"][k] - stats["numpy"][k]) for k in REALISM_TOL}
    assert all(diff[k] <= REALISM_TOL[k] for k in REALISM_TOL), (diff, stats)

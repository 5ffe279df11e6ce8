"""Compositing into an environment (render/composite/pipeline.py): GL vs numpy twins, the ground shadow
ratio (SSDF + SG, seed 004 Eq. 16-17) vs Open3D ray casting, orientation, tone mapping."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest

from capture.camera import Camera, look_at, make_K
from render.composite.ground_shadow import (
    GroundPlane,
    ground_from_spheres,
    ratio_lookup,
    shadow_ratio,
    shadow_ratio_raycast,
    spheres_mesh,
)
from render.composite.pipeline import Compositor, composite_frame, normals_from_depth
from render.composite.reference import composite_reference, raycast_sphere
from render.composite.tonemap import TONE_WHITE, display_white, tonemap
from render.shading.envmap import SUN_DIR, EnvMap, bundled_envmap, procedural_sky
from render.shading.lights import LUMA
from render.shading.sg import sg_mixture_eval
from volume.model import SphereSet

#: GL (float32) vs numpy (float64) shadow-ratio grid: measured max 3e-4.
GRID_TWIN_TOL = 2e-3
#: Far from the object (test_shadow_falls_away_from_the_sun) the ray-cast of the SG lighting is above
#: FAR_UNSHADOWED, and the analytic ratio at most FAR_TOL below it.  The analytic (SSDF) ratio cuts a lobe at the
#: cone towards the nearest occluder, which over-occludes a broad lobe beside a small sphere: where the fit of the
#: procedural sky lands in the optimum with a sky lobe of sharpness 0.5 (the fit's floor; rel. error 0.060, an
#: AVX-512 BF16 machine, 2026-12-05; 0.053 elsewhere) the far ground reads 0.960-0.969 against the ray-cast's
#: 0.993-0.995 (a zenith lobe of sharpness 0.5 alone: 0.970).  Until 2026-12-05 this test asked for > 0.97 of the
#: analytic ratio alone, which held only for the other optimum.
FAR_UNSHADOWED = 0.99
FAR_TOL = 0.04
#: GL vs numpy composite, relative to the pixel value: float32 atan / bilinear weights; measured
#: max 2.3e-4 absolute on values up to ~10.
COMPOSITE_TWIN_REL = 1e-3
#: Ground shadow ratio (SSDF + fitted f_h, 10 SG lobes) vs ray casting the sphere meshes under the
#: SAME SG lighting, over the ground points where either is < 0.99 (the shadow), luminance:
#: measured mean / max (stop 49, the shadow's fit at SHADOW_SG_MAXITER): sunset 0.020 / 0.075, courtyard
#: 0.020 / 0.069, forest 0.015 / 0.072, studio (broad softboxes) 0.042 / 0.135 (0.053 / 0.232 with the fit
#: stopped unconverged at 300 iterations). The error is the SSDF's (nearest-occluder angle + f_h's one-cut
#: assumption), not the lighting's.
SHADOW_MEAN_TOL = 0.04
SHADOW_MAX_TOL = 0.12
#: the other maps (slow test), every map within these:
SHADOW_MEAN_TOL_ANY = 0.06
SHADOW_MAX_TOL_ANY = 0.2
#: ... and under the environment itself (adds the 10-lobe fit's error): measured mean / max (stop 49)
#: sunset 0.019 / 0.072, courtyard 0.021 / 0.070, forest 0.015 / 0.071, studio 0.049 / 0.167.
SHADOW_ENV_MEAN_TOL = 0.04
SHADOW_ENV_MAX_TOL = 0.12
SHADOW_ENV_MEAN_TOL_ANY = 0.06
SHADOW_ENV_MAX_TOL_ANY = 0.25

SPHERES = SphereSet(np.array([[0.0, 0.0, 0.1], [0.03, 0.02, 0.22]]), np.array([0.1, 0.05]))


@lru_cache(maxsize=4)
def _fit(name: str, k: int = 10):
    """(the map, its shadow lighting fit: the product's, render.composite.ground_shadow.shadow_sg_fit, for 10 lobes)."""
    from render.composite.ground_shadow import SHADOW_SG_K, SHADOW_SG_MAXITER, shadow_sg_fit
    from render.shading.sg_fit import fit_env_sg

    env = procedural_sky(64) if name == "procedural" else bundled_envmap(name)
    return env, shadow_sg_fit(env) if k == SHADOW_SG_K else fit_env_sg(env, k, maxiter=SHADOW_SG_MAXITER)


def _camera(w=160, h=120, eye=(0.8, -0.6, 0.35), target=(0.0, 0.0, 0.1), f=150.0):
    return Camera(make_K(f, f, (w - 1) / 2, (h - 1) / 2), look_at(eye, target), w, h)


def _sunset_sphere(colour, w=160, h=120):
    """(env, SG fit, camera, z, normals, flat ``colour`` on the sphere) of the first sphere under sunset."""
    env, fit = _fit("sunset", 10)
    cam = _camera(w, h)
    z, n = _sphere_render(cam, SPHERES.centers[0], SPHERES.radii[0])
    return env, fit, cam, z, n, np.where((z > 0)[..., None], np.array(colour), 0.0)


def _sphere_render(camera, centre, radius):
    """Analytic ray-sphere: z-depth (H, W) and world normals (H, W, 3) (0 off the sphere)."""
    return raycast_sphere(camera, centre, radius)


# -- tone mapping ------------------------------------------------------------------------------
@pytest.mark.parametrize("method", ["clamp", "reinhard"])
def test_tonemap_monotone_and_exposure_correct(method):
    x = np.concatenate([np.linspace(0, 10, 20001), np.logspace(-6, 5, 500)])
    x.sort()
    y = tonemap(x, 1.0, method)
    assert np.all(np.diff(y) >= 0), "tone map not monotone"
    assert y[0] == 0 and np.all((y >= 0) & (y <= 1))
    w = display_white(method)
    np.testing.assert_allclose(tonemap(np.array([w, 2 * w, 1e5]), 1.0, method), 1.0, rtol=0, atol=1e-12)
    assert tonemap(np.array([0.999 * w]), 1.0, method)[0] < 1.0
    for e in (0.25, 1.0, 3.0, 16.0):  # exposure e scales the scene value before the curve
        np.testing.assert_allclose(tonemap(x, e, method), tonemap(x * e, 1.0, method), rtol=1e-12, atol=0)
    # doubling the exposure of a dim value doubles the display value (slope 1 at 0 for both curves)
    small = np.array([1e-5])
    np.testing.assert_allclose(tonemap(small, 2.0, method) / tonemap(small, 1.0, method), 2.0, rtol=1e-4)
    with pytest.raises(ValueError):
        tonemap(x, 0.0, method)
    with pytest.raises(ValueError):
        tonemap(x, 1.0, "filmic")


def test_reinhard_white_point_formula():
    # extended Reinhard, independent evaluation: L (1 + L / Lw^2) / (1 + L)
    L, Lw = 1.5, TONE_WHITE
    assert tonemap(np.array([L]))[0] == pytest.approx(L * (1 + L / Lw**2) / (1 + L), rel=1e-12)


# -- geometry helpers --------------------------------------------------------------------------
def test_ground_from_spheres():
    g = ground_from_spheres(SPHERES)
    assert g.height == pytest.approx(0.0, abs=1e-12)  # lowest point: 0.1 - 0.1
    assert g.half_size > 0.27  # covers the object plus shadows
    g2 = ground_from_spheres(SPHERES, height=-0.05)
    assert g2.height == -0.05
    with pytest.raises(ValueError):
        GroundPlane(0.0, (0, 0), -1.0)


def test_normals_from_depth_on_a_sphere():
    cam = _camera(200, 150)
    z, n_true = _sphere_render(cam, np.array([0.0, 0.0, 0.1]), 0.1)
    n = normals_from_depth(z, cam)
    ok = np.linalg.norm(n, axis=-1) > 0
    ang = np.degrees(np.arccos(np.clip(np.sum(n[ok] * n_true[ok], -1), -1, 1)))
    assert ok.sum() > 0.8 * (z > 0).sum()
    assert np.median(ang) < 1.0 and np.percentile(ang, 95) < 5.0


def test_ratio_lookup_is_bilinear_and_one_outside():
    g = GroundPlane(0.0, (0.0, 0.0), 1.0, 4)
    grid = np.arange(16, dtype=np.float64).reshape(4, 4)[..., None].repeat(3, -1)
    # texel centres: x = -1 + (i + 0.5) * 0.5
    np.testing.assert_allclose(ratio_lookup(grid, g, np.array([-0.75, -0.75]))[0], 0.0)
    np.testing.assert_allclose(ratio_lookup(grid, g, np.array([-0.5, -0.75]))[0], 0.5)
    np.testing.assert_allclose(ratio_lookup(grid, g, np.array([-0.75, -0.5]))[0], 2.0)
    np.testing.assert_allclose(ratio_lookup(grid, g, np.array([1.5, 0.0])), 1.0)


# -- shadow ratio ------------------------------------------------------------------------------
def test_shadow_falls_away_from_the_sun():
    env, fit = _fit("procedural", 10)
    sph = SphereSet(np.array([[0.0, 0.0, 0.1]]), np.array([0.05]))
    g = GroundPlane(0.0, (0.0, 0.0), 0.4, 64)
    pts = g.grid_points().reshape(-1, 3)
    r = shadow_ratio(pts, sph, fit, 0.0) @ LUMA
    # the sun's shadow: the sphere centre projected along -sun onto the ground; its mirror image
    # (towards the sun) is lit. (The darkest point itself is near the contact, where the sky is
    # occluded too -- the ray-cast reference agrees on that.)
    expect = (sph.centers[0] - SUN_DIR * sph.centers[0, 2] / SUN_DIR[2])[:2]
    at = lambda xy: float(shadow_ratio(np.array([[xy[0], xy[1], 0.0]]), sph, fit, 0.0)[0] @ LUMA)
    assert at(expect) < at(-expect) - 0.3, (at(expect), at(-expect))
    assert r.min() < 0.6 and np.all(r <= 1 + 1e-9) and np.all(r > 0)
    # far from the object the ground is unshadowed: the ray-cast of the same lighting says so, and the analytic
    # ratio stays within FAR_TOL of it (FAR_TOL: the SSDF cone's over-occlusion of a broad lobe, below)
    far = np.linalg.norm(pts[:, :2] - expect, axis=1) > 0.35
    V, F = spheres_mesh(sph, 48)
    P = pts[far][::8]
    ref = shadow_ratio_raycast(P, V, F, lambda d: sg_mixture_eval(d, fit.axes, fit.lams, fit.mus), 8192) @ LUMA
    assert np.all(ref > FAR_UNSHADOWED), ref.min()
    assert np.all(r[far][::8] > ref - FAR_TOL), (r[far][::8] - ref).min()


def _shadow_errors(name):
    env, fit = _fit(name, 10)
    g = ground_from_spheres(SPHERES, resolution=24)
    pts = g.grid_points().reshape(-1, 3)
    pts = pts[np.linalg.norm(pts[:, :2], axis=1) > 0.02]  # not right under the contact point
    r = shadow_ratio(pts, SPHERES, fit, g.height) @ LUMA
    V, F = spheres_mesh(SPHERES, 48)
    ref_sg = shadow_ratio_raycast(pts, V, F, lambda d: sg_mixture_eval(d, fit.axes, fit.lams, fit.mus), 8192) @ LUMA
    ref_env = shadow_ratio_raycast(pts, V, F, env.sample, 8192) @ LUMA
    out = {}
    for lab, ref in (("sg", ref_sg), ("env", ref_env)):
        sh = (ref < 0.99) | (r < 0.99)
        d = np.abs(r - ref)[sh]
        out[lab] = (float(d.mean()), float(d.max()), int(sh.sum()))
    return out


def test_shadow_ratio_vs_raycast_sunset():
    e = _shadow_errors("sunset")
    assert e["sg"][2] > 30  # enough shadowed points to mean something
    assert e["sg"][0] < SHADOW_MEAN_TOL and e["sg"][1] < SHADOW_MAX_TOL, e
    assert e["env"][0] < SHADOW_ENV_MEAN_TOL and e["env"][1] < SHADOW_ENV_MAX_TOL, e


@pytest.mark.slow
@pytest.mark.parametrize("name", ["studio", "courtyard", "forest"])
def test_shadow_ratio_vs_raycast_other_maps(name):
    e = _shadow_errors(name)
    assert e["sg"][0] < SHADOW_MEAN_TOL_ANY and e["sg"][1] < SHADOW_MAX_TOL_ANY, e
    assert e["env"][0] < SHADOW_ENV_MEAN_TOL_ANY and e["env"][1] < SHADOW_ENV_MAX_TOL_ANY, e


# -- GL vs numpy -------------------------------------------------------------------------------
@pytest.mark.gl
def test_shadow_grid_gl_matches_numpy(gl_ctx):
    env, fit = _fit("sunset", 10)
    g = ground_from_spheres(SPHERES, resolution=32)
    with Compositor(gl_ctx) as c:
        grid = c.shadow_grid(SPHERES, fit, g)
    ref = shadow_ratio(g.grid_points().reshape(-1, 3), SPHERES, fit, g.height).reshape(grid.shape)
    assert ref.min() < 0.5  # a real shadow is in the grid
    assert np.abs(grid - ref).max() < GRID_TWIN_TOL


@pytest.mark.gl
def test_composite_gl_matches_numpy(gl_ctx):
    env, fit, cam, z, _, rgb = _sunset_sphere([0.6, 0.3, 0.2])
    g = ground_from_spheres(SPHERES, resolution=32)
    with Compositor(gl_ctx) as c:
        grid = c.shadow_grid(SPHERES, fit, g)
        got = c.composite(rgb, z, cam, env, 2.0, g)
        plain = c.composite(rgb, z, cam, env, 2.0, None)
    ref = composite_reference(rgb, z, cam, env, 2.0, g, grid)
    rel = np.abs(got - ref) / (1 + np.abs(ref))
    assert rel.max() < COMPOSITE_TWIN_REL, rel.max()
    # the shadow darkened some ground pixels, and nothing else
    ratio = (got + 1e-6) / (plain + 1e-6)
    assert (ratio < 0.7).all(-1).sum() > 100 and np.all(ratio < 1 + 1e-4)
    np.testing.assert_allclose(got[z > 0], 2.0 * rgb[z > 0], rtol=1e-6)


@pytest.mark.gl
def test_light_reflection_map_gl_matches_numpy(gl_ctx):
    """composite_frag.glsl's light-reflection map (sources from the studio's softboxes) vs
    render.shading.glare_maps.light_reflection_map through composite_reference."""
    from render.shading.glare_maps import light_source_map, light_sources

    env = bundled_envmap("studio")
    src = light_sources(light_source_map(env))
    cam = _camera(120, 90, eye=(0.5, 0.4, 0.25))
    z, n = _sphere_render(cam, np.array([0.0, 0.0, 0.1]), 0.1)
    rgb = np.where((z > 0)[..., None], 0.1, 0.0) * np.ones(3)
    spec = np.zeros((90, 120, 2))
    spec[z > 0] = (0.5, 300.0)
    spec[z > 0, 1] *= np.linspace(0.1, 3.0, int((z > 0).sum()))  # spatially varying exponent
    with Compositor(gl_ctx) as c:
        got = c.composite(rgb, z, cam, env, 1.0, None, n, spec, src)
    ref = composite_reference(rgb, z, cam, env, 1.0, None, None, n, spec, src)
    assert len(src.dirs) > 10 and ref[z > 0].max() > 5.0  # real highlights
    # float32 cos^n with n up to 900: measured max 3.4e-4 relative, mean 3.6e-7 absolute
    rel = np.abs(got - ref) / (0.05 + np.abs(ref))
    assert rel.max() < 2e-3, rel.max()
    assert np.abs(got - ref).mean() < 1e-4


@pytest.mark.gl
def test_background_orientation(gl_ctx):
    """A single bright texel of the map shows where the camera projects its direction."""
    data = np.full((64, 128, 3), 0.01, np.float32)
    i, j = 20, 90
    data[i, j] = 100.0
    env = EnvMap(data, "dot")
    d = env.pixel_directions()[i, j]
    cam = _camera(120, 90, eye=(0.0, 0.0, 0.0), target=d, f=100.0)
    uv, _ = cam.project(cam.center + d)
    with Compositor(gl_ctx) as c:
        img = c.composite(np.zeros((90, 120, 3)), np.zeros((90, 120)), cam, env, 1.0)
    peak = np.unravel_index(np.argmax(img.sum(-1)), img.shape[:2])
    assert abs(peak[1] - uv[0]) <= 1.0 and abs(peak[0] - uv[1]) <= 1.0, (peak, uv)


@pytest.mark.gl
def test_composite_frame_end_to_end(gl_ctx):
    env, fit, cam, z, n, rgb = _sunset_sphere([0.3, 0.3, 0.3])
    st = {}
    out = composite_frame(gl_ctx, rgb, z, cam, env, spheres=SPHERES, exposure=1.0, glare=False, sg_fit=fit, stats=st)
    assert out.shape == (120, 160, 3) and out.dtype == np.float32
    assert np.all((out >= 0) & (out <= 1))
    np.testing.assert_allclose(out[z > 0], tonemap(rgb[z > 0]), rtol=1e-5)
    lin = composite_frame(gl_ctx, rgb, z, cam, env, spheres=SPHERES, exposure=1.0, glare=False, sg_fit=fit,
                          output="linear")
    np.testing.assert_allclose(tonemap(lin), out, atol=1e-6)
    no_ground = composite_frame(gl_ctx, rgb, z, cam, env, spheres=SPHERES, ground=False, glare=False,
                                output="linear")
    assert (lin < no_ground - 1e-3).any(axis=-1).mean() > 0.01  # the shadow is there
    # a glossy sphere under the forest sun's light-reflection map shows a highlight; glare keeps energy
    env, fit = _fit("forest", 10)
    spec = np.zeros((120, 160, 2))
    spec[z > 0] = (1.0, 1000.0)
    st = {}
    hdr = composite_frame(gl_ctx, rgb, z, cam, env, spheres=SPHERES, glare=True, specular=spec, normals=n,
                          sg_fit=fit, output="linear", stats=st)
    no_glare = composite_frame(gl_ctx, rgb, z, cam, env, spheres=SPHERES, glare=False, specular=spec, normals=n,
                               sg_fit=fit, output="linear")
    assert st["bright_pixels"] > 0 and no_glare[z > 0].max() > TONE_WHITE
    np.testing.assert_allclose(hdr.sum((0, 1)), no_glare.sum((0, 1)), rtol=0.01)
    with pytest.raises(ValueError):
        composite_frame(gl_ctx, rgb[:10], z, cam, env)


@pytest.mark.gl
def test_other_up_axis_gives_the_same_frame(gl_ctx):
    """A capture whose world is turned (up = Q z) composites exactly like the +z-up one."""
    from render.composite.pipeline import rotation_to_z

    env, fit, cam, z, n, rgb = _sunset_sphere([0.2, 0.4, 0.6], 96, 72)
    spec = np.where((z > 0)[..., None], np.array([0.5, 200.0]), 0.0)
    kw = dict(sg_fit=fit, glare=False, specular=spec, output="linear")
    ref = composite_frame(gl_ctx, rgb, z, cam, env, spheres=SPHERES, normals=n, **kw)
    for up in ([0.0, 1.0, 0.0], [0.3, -0.5, 0.8], [0.0, 0.0, -1.0]):
        Q = rotation_to_z(up).T  # takes +z to up
        np.testing.assert_allclose(Q @ [0, 0, 1.0], np.asarray(up) / np.linalg.norm(up), atol=1e-12)
        T = np.eye(4)
        T[:3, :3] = Q.T
        cam_q = Camera(cam.K, cam.cam_from_world @ T, cam.width, cam.height)
        sph_q = SphereSet(SPHERES.centers @ Q.T, SPHERES.radii)
        got = composite_frame(gl_ctx, rgb, z, cam_q, env, spheres=sph_q, normals=n @ Q.T, up=up, **kw)
        np.testing.assert_allclose(got, ref, rtol=1e-4, atol=1e-5)


@pytest.mark.gl
def test_compositor_reuse_gives_the_same_frame(gl_ctx):
    env, fit, cam, z, _, rgb = _sunset_sphere([0.2, 0.4, 0.6], 96, 72)
    one = composite_frame(gl_ctx, rgb, z, cam, env, spheres=SPHERES, sg_fit=fit, glare=False)
    with Compositor(gl_ctx) as c:
        a = composite_frame(gl_ctx, rgb, z, cam, env, spheres=SPHERES, sg_fit=fit, glare=False, compositor=c)
        b = composite_frame(gl_ctx, rgb, z, cam, env, spheres=SPHERES, sg_fit=fit, glare=False, compositor=c)
        assert c._grid_key is not None and c._grid_key[0] is SPHERES  # grid cached, not recomputed
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(a, one)

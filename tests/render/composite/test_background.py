"""Alpha on the way out (render/composite/background.py, the compositor's matte): RGBA PNG round
trip with straight alpha, --background parsing, and compositing a soft-edged object over a colour
or a map against the analytic composite (no dark or bright fringe)."""

from __future__ import annotations

import numpy as np
import pytest

from capture.camera import look_at, make_K
from capture.scan import srgb_to_linear
from render.composite.background import (
    background_image,
    flatten,
    parse_background,
    parse_colour,
    rgba8,
    unpack_rgba8,
)
from render.frame import Frame, FrameStats
from render.shading.envmap import EnvMap

#: 8-bit round trip of premultiplied linear colour: straight colour within half an sRGB step
#: (slope of sRGB -> linear <= 2.4 / 1.055 per unit) plus half an alpha step.
ROUNDTRIP_TOL = 0.5 / 255 * (2.4 / 1.055) + 0.5 / 255
#: float32 flatten against the float64 analytic composite.
FLATTEN_TOL = 1e-6
#: GL compositor (float32, texture fetch of a constant map) against the analytic composite.
GL_COMPOSITE_TOL = 1e-5
#: The fringe a binary mask leaves on this object over white (linear): the test must see it.
BINARY_FRINGE_MIN = 0.2


def _soft_disc(W=64, H=48, r0=14.0, ramp=5.0, colour=(0.6, 0.25, 0.1)):
    """A disc of straight colour ``colour`` whose alpha ramps from 1 to 0 over ``ramp`` px at radius
    ``r0`` (the analytic fur fringe): (premult (H, W, 3), alpha (H, W), straight colour (3,))."""
    y, x = np.mgrid[0:H, 0:W].astype(np.float64)
    r = np.hypot(x - W / 2, y - H / 2)
    a = np.clip((r0 + ramp - r) / ramp, 0.0, 1.0)
    c = np.asarray(colour, np.float64)
    return a[..., None] * c, a, c


def test_rgba_png_roundtrip_is_straight_alpha(tmp_path):
    import cv2

    from capture.imageio import write_png

    pm, a, c = _soft_disc()
    img = rgba8(pm, a)
    write_png(tmp_path / "x.png", img)
    back = cv2.imread(str(tmp_path / "x.png"), cv2.IMREAD_UNCHANGED)
    assert back.shape == (48, 64, 4)
    back = back[..., [2, 1, 0, 3]]
    np.testing.assert_array_equal(back, img)
    # straight colour: every partially covered pixel stores the disc's own colour, not a darker one
    part = (a > 0.05) & (a < 0.95)
    assert part.sum() > 100
    np.testing.assert_allclose(srgb_to_linear(back[part, :3] / 255.0), np.broadcast_to(c, (part.sum(), 3)),
                               atol=0.5 / 255 * 2.4 / 1.055)
    pm2, a2 = unpack_rgba8(back)
    np.testing.assert_allclose(a2, a, atol=0.5 / 255 + 1e-7)
    np.testing.assert_allclose(pm2, pm, atol=ROUNDTRIP_TOL)
    assert np.all(back[a == 0] == 0)


def test_parse_background():
    np.testing.assert_allclose(parse_colour("white"), [1, 1, 1])
    np.testing.assert_allclose(parse_colour("235,235,235"), srgb_to_linear(np.full(3, 235 / 255)), rtol=1e-6)
    np.testing.assert_allclose(parse_colour("0.5,0.5,0.5"), srgb_to_linear(np.full(3, 0.5)), rtol=1e-6)
    np.testing.assert_allclose(parse_colour("#ff0000"), [1, 0, 0])
    assert parse_colour("studio") is None
    assert parse_background("studio").env is not None
    with pytest.raises(ValueError, match="nowhere"):
        parse_background("nowhere")
    with pytest.raises(ValueError, match="0-255"):
        parse_colour("300,0,0")


@pytest.mark.parametrize("bg", [(1.0, 1.0, 1.0), (0.02, 0.03, 0.05), (0.2, 0.8, 0.4)])
def test_flatten_over_a_colour_has_no_fringe(bg):
    """premult + (1 - alpha) B equals the analytic composite alpha c + (1 - alpha) B everywhere;
    the binary-mask composite (straight colour where alpha > 0) differs by a visible fringe."""
    pm, a, c = _soft_disc()
    B = np.asarray(bg)
    want = a[..., None] * c + (1 - a[..., None]) * B
    fr = Frame(pm, a, np.where(a > 0, 1.0, 0.0), FrameStats(0, 0, supersample=1))
    got = fr.over(B)
    np.testing.assert_allclose(got, want, atol=FLATTEN_TOL)
    np.testing.assert_allclose(flatten(pm, a, np.broadcast_to(B, pm.shape)), want, atol=FLATTEN_TOL)
    np.testing.assert_allclose(fr.straight()[a > 0], np.broadcast_to(c, ((a > 0).sum(), 3)), atol=1e-6)
    binary = np.where((a > 0)[..., None], c, B)  # a binary mask: the object's colour replaces B
    if np.abs(B - c).max() > 0.3:
        assert np.abs(binary - want).max() > BINARY_FRINGE_MIN


def test_background_image_of_a_map_is_the_compositors_background():
    """A map background is the environment in the pixels' world directions (the compositor's lookup)."""
    from render.composite.reference import composite_reference

    data = np.random.default_rng(0).uniform(0.1, 2.0, (16, 32, 3)).astype(np.float32)
    env = EnvMap(data, "noise")
    K = make_K(60.0, 60.0, 31.5, 23.5)
    from capture.camera import Camera

    cam = Camera(K, look_at((0.5, 0.3, 0.2), (0, 0, 0)), 64, 48)
    bg = parse_background("studio")._replace(env=env)
    got = background_image(bg, cam)
    ref = composite_reference(np.zeros((48, 64, 3)), np.zeros((48, 64)), cam, env)
    np.testing.assert_allclose(got, ref, rtol=1e-5)


@pytest.mark.gl
def test_gl_compositor_with_soft_matte_matches_analytic(gl_ctx):
    """The compositor (--env) with a frame's matte over a constant map: exactly the analytic
    composite (no fringe); and its GL matches the numpy twin with a soft matte and a real map."""
    from capture.camera import Camera
    from render.composite.gl import Compositor
    from render.composite.reference import composite_reference
    from render.shading.envmap import bundled_envmap

    pm, a, c = _soft_disc()
    H, W = a.shape
    cam = Camera(make_K(60.0, 60.0, (W - 1) / 2, (H - 1) / 2), look_at((0.5, 0.3, 0.2), (0, 0, 0)), W, H)
    B = np.array([0.9, 0.85, 0.8])
    flat = EnvMap(np.broadcast_to(B, (8, 16, 3)).astype(np.float32).copy(), "flat")
    depth = np.where(a > 0, 0.5, 0.0)
    with Compositor(gl_ctx) as comp:
        got = comp.composite(pm, depth, cam, flat, 1.0, alpha=a)
        studio = bundled_envmap("studio")
        got2 = comp.composite(pm, depth, cam, studio, 1.5, alpha=a)
    want = a[..., None] * c + (1 - a[..., None]) * B
    np.testing.assert_allclose(got, want, atol=GL_COMPOSITE_TOL)
    ref = composite_reference(pm, depth, cam, studio, 1.5, alpha=a)
    assert np.abs(got2 - ref).max() / (1 + np.abs(ref).max()) < 1e-3

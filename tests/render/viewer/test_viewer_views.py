"""The viewer's pictures (render.viewer.views): debug colourings and the method-agnostic dispatch."""

from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
import pytest

from capture.camera import Camera, look_at, make_K
from render.frame import Frame, FrameStats
from render.methods import METHODS, MethodSpec, method_spec, option
from render.viewer import views
from render.viewer.settings import ViewSettings


@dataclass(frozen=True)
class CodesOptions:
    """The options of a fake method that draws the debug outputs "camera" and "rejections"."""

    #: Debug output instead of the colour.
    debug: str | None = option(None, "debug output", type=str)


#: Two fake methods (registered by the fixture ``fakes``): one draws nothing but colour, the other
#: the debug outputs too.
PLAIN = MethodSpec("fake", "tests.render.viewer.test_viewer_views:FakeRenderer", "colour only")
CODES = MethodSpec("fake-codes", "tests.render.viewer.test_viewer_views:FakeRenderer", "colour and codes",
                   options=CodesOptions, supersample=True, debug_outputs=("camera", "rejections"))


@pytest.fixture
def fakes(monkeypatch):
    for spec, attr in ((PLAIN, "PLAIN"), (CODES, "CODES")):
        monkeypatch.setitem(METHODS, spec.name, f"tests.render.viewer.test_viewer_views:{attr}")


def test_depth_image_near_is_bright_and_empty_is_black():
    d = np.zeros((4, 5), np.float32)
    d[1, 1], d[2, 3] = 0.5, 1.5
    img = views.depth_image(d)
    assert img[0, 0].tolist() == list(views.EMPTY_RGB)
    lum = img.astype(float).sum(-1)
    assert lum[1, 1] > lum[2, 3] > 0


def test_code_image_and_frame_codes():
    pal = np.array([[10, 0, 0], [0, 20, 0]], np.uint8)
    codes = np.array([[0, 1], [2, 3]])
    img = views.code_image(codes, pal)
    assert img[0, 0].tolist() == [0, 0, 0] and img[0, 1].tolist() == [10, 0, 0]
    assert img[1, 0].tolist() == [0, 20, 0] and img[1, 1].tolist() == [10, 0, 0]   # palette cycles
    rgb = np.zeros((1, 3, 3), np.float32)
    rgb[0, :, 0] = [3.0000002, 7.0, 9.0]
    f = Frame(rgb, np.array([[1.0, 1.0, 0.0]], np.float32), np.ones((1, 3), np.float32),
              FrameStats(1.0, 1.0, supersample=1, facets=1))
    assert views.frame_codes(f).tolist() == [[3, 7, 0]]


class FakeRenderer:
    """Returns a fixed frame; records the options it was asked for."""

    def __init__(self, stats, name="fake"):
        self.stats, self.asked, self.name = stats, [], name
        self.spec = method_spec(name)

    def render(self, camera, options):
        self.asked.append(options)
        H, W = camera.height, camera.width
        cov = np.zeros((H, W), np.float32)
        cov[1:3, 1:3] = 1.0
        return Frame(np.full((H, W, 3), 0.5, np.float32) * cov[..., None], cov, cov * 2.0, self.stats)


@pytest.fixture
def cam():
    return Camera(make_K(5.0, 5.0, 1.5, 1.5), look_at([0, -1, 0], [0, 0, 0]), 4, 4)


def test_views_a_method_cannot_give_fall_back_with_a_note(cam, fakes):
    r = FakeRenderer(FrameStats(1.0, 1.0, supersample=1, facets=1))
    scene = SimpleNamespace(renderer=lambda name: r)
    for view in ("camera", "rejections", "level"):
        drawn = views.draw(scene, cam, ViewSettings(method="fake", view=view), 1)
        assert "fake" in drawn.note and view.split()[0][:5] in drawn.note
        assert drawn.image[2, 2].tolist() == drawn.image[1, 1].tolist() != [0, 0, 0]   # the colour picture
    assert all(o.methods == () for o in r.asked)  # no method's own option was set


def test_level_and_debug_views_of_a_method_that_gives_them(cam, fakes):
    @dataclass(frozen=True, kw_only=True)
    class LevelStats(FrameStats):
        level: int = 0

    r = FakeRenderer(LevelStats(1.0, 1.0, supersample=1, facets=1, level=3), "fake-codes")
    scene = SimpleNamespace(renderer=lambda name: r)
    lev = views.draw(scene, cam, ViewSettings(method="fake-codes", view="level"), 2)
    assert lev.note == "" and lev.image[1, 1].tolist() == views.palette(16)[3].tolist()
    assert lev.image[0, 0].tolist() == list(views.EMPTY_RGB)
    views.draw(scene, cam, ViewSettings(method="fake-codes", view="camera"), 2)
    assert r.asked[-1].of("fake-codes").debug == "camera" and r.asked[-1].supersample == 1


@pytest.mark.gl
def test_composite_env_uses_the_frames_matte(gl_ctx):
    """The viewer composites with the frame's soft alpha: a half-transparent red square over a flat
    map equals the analytic composite 0.5 red + 0.5 map drawn as an opaque object through the same
    compositor and tone map (no glare)."""
    from render.composite.pipeline import composite_frame
    from render.shading.envmap import EnvMap
    from render.viewer.settings import EnvSettings

    cam = Camera(make_K(20.0, 20.0, 7.5, 7.5), look_at([0, -1, 0], [0, 0, 0]), 16, 16)
    a = np.zeros((16, 16), np.float32)
    a[4:12, 4:12] = 0.5
    rgb = a[..., None] * np.array([1.0, 0.0, 0.0], np.float32)
    fr = Frame(rgb, a, np.where(a > 0, 1.0, 0.0).astype(np.float32), FrameStats(0, 0, supersample=1))
    B = np.array([0.2, 0.4, 0.6], np.float32)
    env = EnvMap(np.broadcast_to(B, (8, 16, 3)).copy(), "flat")
    with views.make_compositor(gl_ctx) as comp:
        got = views.composite_env(gl_ctx, fr, cam, env, EnvSettings(map="flat", glare=False), None, (0, 0, 1), comp)
        want = composite_frame(gl_ctx, rgb + (1 - a[..., None]) * B, np.ones((16, 16)), cam, env, glare=False,
                               ground=False)  # the analytic composite, drawn as an opaque object
    np.testing.assert_allclose(got, want, atol=1e-5)
    assert abs(got[8, 8, 0] - got[0, 0, 0]) > 0.05  # the square shows


@pytest.mark.gl
def test_ground_shadow_is_fitted_and_gridded_once_per_map(gl_ctx, monkeypatch, fakes):
    """With the ground shadow on, the viewer fits the map's spherical Gaussians once (seconds of
    work composite_frame used to redo every frame: 1.2 s a 533x400 frame measured) and the
    compositor reuses its shadow grid while only the camera changes, also when the rig's up is
    not the map's +z (the spheres are turned into a new object every frame)."""
    from render.shading import sg_fit
    from render.viewer.gl_worker import GLScene
    from render.viewer.settings import EnvSettings
    from tests import scenes

    fits = []
    real_fit = sg_fit.fit_env_sg
    monkeypatch.setattr(sg_fit, "fit_env_sg", lambda *a, **k: fits.append(1) or real_fit(*a, **k))
    scene = GLScene(gl_ctx, scenes.build_model(scenes.ring_cameras(6, 32, 24), resolutions=(4, 8)))
    try:
        r = FakeRenderer(FrameStats(1.0, 1.0, supersample=1, facets=1))
        monkeypatch.setattr(scene, "renderer", lambda name: r)
        scene.up = np.array([0.0, 0.6, 0.8])                   # a tilted rig: spheres turned per frame
        settings = ViewSettings(env=EnvSettings(map="sunset", ground=True, glare=False))
        cams = [Camera(make_K(8.0, 8.0, 3.5, 2.5), look_at([0.1 * i, -0.5, 0.2], [0, 0, 0]), 8, 6) for i in range(3)]
        views.draw(scene, cams[0], settings, 1)
        grid = scene.compositor()._grid
        for cam in cams[1:]:
            views.draw(scene, cam, settings, 1)
        assert len(fits) == 1
        assert grid is not None and scene.compositor()._grid is grid   # not recomputed
        views.draw(scene, cams[0], settings.changed(env={"map": "forest"}), 1)
        assert len(fits) == 2 and scene.compositor()._grid is not grid  # another map: refitted
    finally:
        scene.release()

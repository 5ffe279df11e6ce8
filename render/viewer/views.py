"""The pictures a viewer client can ask for, drawn on the GL thread from one rendered Frame.

* "colour": the frame as 8-bit sRGB over black (premultiplied colour), or composited with its matte into an
  environment map (:func:`composite_env`, docs/methods.md §3-§4) with exposure, ground shadow, glare, rotation;
  the 8-bit conversion through render.viewer.present.srgb8 (a lookup table; reference
  capture.scan.to_uint8_srgb);
* "depth": the z-depth, near = bright (inferno colour map over the drawn pixels' range);
* "level": the pyramid level the frame drew (Eq. 11 picks one level per frame, so every drawn
  pixel shows it), for methods whose FrameStats report a ``level``;
* a method's debug outputs (its spec's ``debug_outputs``, drawn by the renderer itself through its
  option ``debug``): the microfacets' "camera" (per pixel the index + 1 of the dominant input
  camera) and "rejections" (1 for a kept and 2 for an Eq. 2-rejected slice fragment,
  render.microfacet.gl); codes shown through fixed palettes.

Methods are looked up by name and never branched on: a view a method cannot give is reported
(``Drawn.note``) and the colour picture is shown instead.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from capture.camera import Camera
from render.viewer.settings import FRAME_VIEWS, EnvSettings, ViewSettings

#: Colour of pixels where nothing was drawn in the debug views (8-bit sRGB).
EMPTY_RGB = (0, 0, 0)
#: Rejection view: kept fragments grey, Eq. 2 rejections red (8-bit sRGB).
KEPT_RGB = (150, 150, 150)
REJECTED_RGB = (230, 40, 40)
#: Palette of the camera and level views (matplotlib's tab20, cycled); colour map of the depth
#: view (dark far -> bright near).
PALETTE = "tab20"
DEPTH_COLOURS = "inferno"


@dataclass(frozen=True)
class Drawn:
    """A picture ready to send: ``image`` (H, W, 3) uint8 sRGB, the frame's ``stats``
    (render.frame.FrameStats), a ``note`` when the asked view could not be drawn and the wall
    milliseconds of the stages measured here (``stages``: "convert", the frame -> the picture, and
    "convert_cpu", its process CPU milliseconds)."""

    image: np.ndarray
    stats: object
    note: str = ""
    stages: dict = field(default_factory=dict)


def make_compositor(ctx):
    """The environment compositor GL owner (render.composite.gl.Compositor)."""
    from render.composite.gl import Compositor

    return Compositor(ctx)


def composite_env(ctx, frame, camera: Camera, env, env_settings: EnvSettings, spheres, up, compositor,
                  sg_fit=None) -> np.ndarray:
    """``frame`` (render.frame.Frame) composited into ``env`` with its matte (premultiplied +
    (1 - alpha) background, linear light): (H, W, 3) float32 display-referred linear colour in
    [0, 1] (render.composite.pipeline.composite_frame); ``sg_fit``: the map's SG fit for the ground
    shadow (fitted per call when None)."""
    from render.composite.pipeline import composite_frame

    return composite_frame(ctx, frame.rgb, frame.depth, camera, env, alpha=frame.alpha,
                           spheres=spheres if env_settings.ground else None,
                           ground=None if env_settings.ground else False, exposure=env_settings.exposure,
                           glare=env_settings.glare, up=up, compositor=compositor, sg_fit=sg_fit)


def palette(n: int) -> np.ndarray:
    """(n, 3) uint8 distinct colours (PALETTE, cycled)."""
    import matplotlib

    cols = np.asarray(matplotlib.colormaps[PALETTE].colors)[:, :3]
    return np.round(cols[np.arange(n) % len(cols)] * 255).astype(np.uint8)


def depth_image(depth: np.ndarray) -> np.ndarray:
    """(H, W) z-depth (0 = nothing) -> (H, W, 3) uint8: near bright, far dark (DEPTH_COLOURS over the
    drawn range), EMPTY_RGB where nothing was drawn."""
    import matplotlib

    d = np.asarray(depth, np.float64)
    drawn = d > 0
    out = np.zeros((*d.shape, 3), np.uint8)
    out[:] = EMPTY_RGB
    if drawn.any():
        lo, hi = d[drawn].min(), d[drawn].max()
        t = 1.0 - (d[drawn] - lo) / max(hi - lo, 1e-12)
        lut = np.round(matplotlib.colormaps[DEPTH_COLOURS](np.linspace(0, 1, 256))[:, :3] * 255).astype(np.uint8)
        out[drawn] = lut[np.clip(np.round(t * 255), 0, 255).astype(int)]
    return out


def code_image(codes: np.ndarray, colours: np.ndarray) -> np.ndarray:
    """(H, W) integer codes (0 = nothing, k >= 1 -> ``colours[k - 1]``) -> (H, W, 3) uint8."""
    codes = np.asarray(codes)
    out = np.zeros((*codes.shape, 3), np.uint8)
    out[:] = EMPTY_RGB
    hit = codes > 0
    out[hit] = colours[(codes[hit] - 1) % len(colours)]
    return out


def frame_codes(frame) -> np.ndarray:
    """(H, W) int codes a renderer wrote for a debug view (red channel, one sample per pixel;
    0 where nothing was drawn)."""
    return np.where(frame.alpha > 0, np.rint(frame.rgb[..., 0]), 0).astype(np.int64)


def colour_image(scene, frame, camera: Camera, env_settings: EnvSettings) -> np.ndarray:
    """The "colour" view: sRGB over black, or composited into the environment."""
    from render.viewer.present import srgb8

    if env_settings.map is None:
        return srgb8(frame.rgb)
    env = scene.envmap(env_settings.map, env_settings.rotation_deg, env_settings.convention)
    fit = scene.shadow_fit(env) if env_settings.ground else None
    img = composite_env(scene.ctx, frame, camera, env, env_settings, scene.model.spheres, scene.rig_up(),
                        scene.compositor(), fit)
    return srgb8(img)


def draw(scene, camera: Camera, settings: ViewSettings, supersample: int, draft: bool = False) -> Drawn:
    """Render ``camera`` with ``settings`` (``supersample`` samples per pixel and axis; ``draft``: a
    moving frame, render.methods.RenderOptions.draft) and make the asked view (runs on the GL thread:
    ``scene`` is a render.viewer.gl_worker.GLScene)."""
    renderer = scene.renderer(settings.method)
    opts = settings.options.changed(supersample=supersample, draft=draft)
    view, note = settings.view, ""
    if view not in FRAME_VIEWS:
        if view in renderer.spec.debug_outputs:
            opts = opts.changed_for(renderer.name, debug=view, supersample=1)
        else:
            view, note = "colour", f"method {settings.method!r} draws no {settings.view!r} view"
    frame = renderer.render(camera, opts)
    t0, c0 = time.perf_counter(), time.process_time()
    if view == "colour":
        img = colour_image(scene, frame, camera, settings.env)
    elif view == "depth":
        img = depth_image(frame.depth)
    elif view == "level":
        level = getattr(frame.stats, "level", None)
        if level is None:
            img, note = colour_image(scene, frame, camera, settings.env), \
                f"method {settings.method!r} draws no pyramid level"
        else:
            img = code_image(np.where(frame.alpha > 0, level + 1, 0), palette(16))
    elif view == "rejections":
        img = code_image(frame_codes(frame), np.array([KEPT_RGB, REJECTED_RGB], np.uint8))
    else:  # a method's code view (the camera index + 1 per pixel, ...)
        img = code_image(frame_codes(frame), palette(20))
    return Drawn(img, frame.stats, note, {"convert": (time.perf_counter() - t0) * 1e3,
                                          "convert_cpu": (time.process_time() - c0) * 1e3})

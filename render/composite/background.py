"""What ``furrow render`` writes from a :class:`render.frame.Frame`: an RGBA PNG (straight alpha, as
PNG stores it) or the frame flattened over a background (``--background COLOUR|MAP``).

* :func:`rgba8`: 8-bit sRGB straight colour (premultiplied / alpha) + 8-bit alpha.
* :func:`parse_background`: a colour name or hex (matplotlib's names: ``white``, ``#ebebeb``), an
  sRGB triple (``235,235,235`` in 0-255, or ``0.9,0.9,0.9`` in 0-1), or an environment map
  (``render.shading.envmap.named_envmap``: a bundled name or a .exr / .hdr file).
* :func:`flatten`: the frame over that background in linear light, premult + (1 - alpha) B: a
  soft matte gives no dark or bright fringe.  A map is seen in the camera's pixel directions with
  the capture's ``up`` turned to the map's +z (as the compositor does), not tone mapped.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from capture.camera import Camera
from capture.scan import srgb_to_linear, to_uint8_srgb

#: Largest value of an sRGB triple given in 0-1 units; above it the triple is read as 0-255.
UNIT_TRIPLE_MAX = 1.0
#: 8-bit full scale.
FULL_8BIT = 255.0


class Background(NamedTuple):
    """A flattening background: a linear (3,) ``colour`` or an environment ``env`` (EnvMap)."""

    colour: np.ndarray | None
    env: object | None
    label: str


def parse_colour(text: str) -> np.ndarray | None:
    """Linear (3,) colour of a colour name, hex or sRGB triple; None when ``text`` is none of them."""
    from matplotlib.colors import to_rgb

    parts = [p.strip() for p in text.split(",")]
    if len(parts) == 3:
        try:
            v = np.array([float(p) for p in parts])
        except ValueError:
            return None
        if np.any(v < 0) or np.any(v > FULL_8BIT):
            raise ValueError(f"--background {text!r}: an sRGB triple is 0-1 or 0-255 per channel")
        srgb = v if v.max() <= UNIT_TRIPLE_MAX and any("." in p for p in parts) else v / FULL_8BIT
        return srgb_to_linear(srgb).astype(np.float32)
    try:
        return srgb_to_linear(np.asarray(to_rgb(text), np.float64)).astype(np.float32)
    except ValueError:
        return None


def parse_background(text: str) -> Background:
    """The background of ``--background TEXT`` (module doc); an unknown one is a ValueError naming it."""
    col = parse_colour(text)
    if col is not None:
        return Background(col, None, text)
    from render.shading.envmap import named_envmap

    try:
        return Background(None, named_envmap(text), text)
    except ValueError:
        raise ValueError(f"--background {text!r}: not a colour name, #hex, sRGB triple, environment map name or "
                         ".exr/.hdr file") from None


def background_image(bg: Background, camera: Camera, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """(H, W, 3) float32 linear background seen by ``camera`` (a colour fills it; a map is looked up
    in the pixels' world directions turned so that ``up`` is the map's +z)."""
    H, W = camera.height, camera.width
    if bg.colour is not None:
        return np.broadcast_to(np.asarray(bg.colour, np.float32), (H, W, 3)).copy()
    from render.composite.pipeline import rotation_to_z
    from render.composite.reference import pixel_world_dirs

    d = pixel_world_dirs(camera) @ rotation_to_z((0.0, 0.0, 1.0) if up is None else up).T
    return bg.env.sample(d).astype(np.float32)


def flatten(premult: np.ndarray, alpha: np.ndarray, background: np.ndarray) -> np.ndarray:
    """(H, W, 3) float32 linear premult + (1 - alpha) background (render.frame.composite_over)."""
    from render.frame import composite_over

    return composite_over(premult, alpha, background)


def rgba8(premult: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """(H, W, 4) uint8 RGBA as PNG stores it: straight colour (premult / alpha, 8-bit sRGB; black
    where alpha = 0) and alpha (8-bit, linear coverage as PNG defines it)."""
    from render.frame import straight_colour

    a = np.clip(np.asarray(alpha, np.float32), 0.0, 1.0)
    rgb = to_uint8_srgb(np.clip(straight_colour(premult, a), 0.0, 1.0))
    return np.concatenate([rgb, np.round(a * FULL_8BIT).astype(np.uint8)[..., None]], -1)


def unpack_rgba8(img: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`rgba8` up to 8-bit rounding: (premultiplied linear (H, W, 3) float32,
    alpha (H, W) float32)."""
    img = np.asarray(img)
    a = img[..., 3].astype(np.float32) / np.float32(FULL_8BIT)
    straight = srgb_to_linear(img[..., :3].astype(np.float64) / FULL_8BIT).astype(np.float32)
    return straight * a[..., None], a

"""The lighting a capture was taken under, as an equirect EnvMap (issue 15: what relighting divides
out), from one of: an equirect HDR map (.exr / .hdr) or a bundled name, the angular fisheye of an
upward camera (seed 004: 185 degrees), or a mirror-ball photo -- the last two through
``render.shading.projections``.

Orientation: every result has its +z up in its own frame (``render.shading.envmap``); the world's up
comes from the rig (``capture.orbit.estimate_up``) and is stored beside the map in the model
(``volume.model.CaptureLighting``).

* fisheye: the conventions of ``projections.equirect_from_fisheye`` (camera on its back looking up,
  image +x = the map's +x, image top towards +y); directions outside the field of view get 0.
* mirror ball: photographed level from the side (image up = the map's +z), the camera looking along
  the map's +x (:data:`MIRROR_BALL_CAM_TO_WORLD`), the image a square crop of the ball's silhouette;
  turn it into place with the rotation about up (``--capture-env-rotation``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from render.shading.envmap import HDR_EXTENSIONS, EnvMap, named_envmap

#: Rows of the equirect map made from a fisheye or mirror-ball photo.
PHOTO_ENV_HEIGHT = 256
#: Field of view of the capture fisheye (degrees; seed 004's lens).
FISHEYE_FOV_DEG = 185.0
#: Mirror-ball camera axes (columns: camera x right, y up, z towards the viewer) in the map's frame:
#: a level camera looking along +x, so x_cam = -y, y_cam = +z, z_cam = -x.
MIRROR_BALL_CAM_TO_WORLD = np.array([[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def read_hdr_image(path) -> np.ndarray:
    """(H, W, 3) float32 linear radiance of an .exr / .hdr image of any shape (errors name the file)."""
    from capture.imageio import read_exr_rgb
    from render.shading.rgbe import read_rgbe

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such image")
    ext = path.suffix.lower()
    if ext not in HDR_EXTENSIONS:
        raise ValueError(f"{path}: not an HDR image (use {', '.join(HDR_EXTENSIONS)}); capture lighting must be linear")
    try:
        data = read_exr_rgb(path) if ext == ".exr" else read_rgbe(path)
    except (ValueError, OSError, KeyError, RuntimeError) as e:
        raise ValueError(f"{path}: cannot read ({e})") from e
    if data.ndim != 3 or data.shape[2] != 3 or not np.all(np.isfinite(data)):
        raise ValueError(f"{path}: expected a finite RGB image, got {data.shape}")
    return np.maximum(data, 0).astype(np.float32)


def capture_envmap(env: str | None = None, fisheye=None, mirrorball=None, height: int = PHOTO_ENV_HEIGHT,
                   fov_deg: float = FISHEYE_FOV_DEG, convention: str = "furrow") -> EnvMap:
    """The capture lighting from exactly one of ``env`` (equirect file or bundled name, laid out in
    ``convention``: ``render.shading.envmap.ENV_CONVENTIONS``), ``fisheye`` (an HDR fisheye photo) or
    ``mirrorball`` (an HDR mirror-ball photo); see the module doc.  The result is in furrow's layout."""
    from render.shading.projections import equirect_from_fisheye, equirect_from_mirror_ball

    given = [x is not None for x in (env, fisheye, mirrorball)]
    if sum(given) != 1:
        raise ValueError("give exactly one capture lighting: an equirect map, a fisheye or a mirror-ball photo")
    if env is not None:
        return named_envmap(str(env), convention)
    if convention != "furrow":
        raise ValueError(f"--capture-env-convention {convention} applies to an equirect --capture-env map only")
    path = Path(fisheye if fisheye is not None else mirrorball)
    img = read_hdr_image(path)
    if img.shape[0] != img.shape[1]:
        raise ValueError(f"{path}: a fisheye / mirror-ball image must be square (crop it to the circle), "
                         f"got {img.shape[1]}x{img.shape[0]}")
    if fisheye is not None:
        return equirect_from_fisheye(img, height, fov_deg, name=path.stem)
    return equirect_from_mirror_ball(img, height, MIRROR_BALL_CAM_TO_WORLD, name=path.stem)

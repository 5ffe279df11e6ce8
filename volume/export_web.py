"""A static web page that draws a model's 3D Gaussians in the browser (issue 33, ``furrow export --web``).

Built with what furrow already ships: viser (pinned in pyproject) carries its client as one
bundled ``index.html`` (React + three.js, no network access) and serialises a scene for static
embedding (``ViserServer.get_scene_serializer().as_html()``).  :func:`write_web` starts a viser server
on a free local port for the time of the export (nothing connects to it), adds

* the splats as viser's Gaussian splat node (``scene.add_gaussian_splats``: centre, covariance,
  colour, opacity per Gaussian, sorted and drawn in the browser);
* the scene's up direction (the rig's, ``capture.orbit.estimate_up``) and the initial camera: the
  first capture camera (its centre, its optical axis to the object's distance, its image up and
  vertical field of view: ``capture.camera.viser_view``); the page orbits about that point,

and writes the serialised scene embedded in the client page as ``DIR/index.html``: any static file
server, or the file opened directly, shows it offline with nothing of furrow running.

What the page cannot show: viser's splats have one colour each, so the page draws the DC term
of the spherical harmonics (their view-independent colour, 0.5 + SH_C0 f_dc); it blends in the
browser's display values, as every splat viewer does.  viser stores the covariance as float16:
metres would underflow for millimetre Gaussians, so the node holds the scene scaled by
1 / (median Gaussian size) and the node's own scale maps it back to metres.
"""

from __future__ import annotations

import contextlib
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from capture.atomic import atomic_dir
from volume.splat_sh import COLOUR_OFFSET, SH_C0

#: Name of the page in the folder.
PAGE = "index.html"
#: Near clipping plane of the page's camera, as a share of its distance to the object.
NEAR_SHARE = 0.01


@dataclass(frozen=True)
class WebResult:
    """What :func:`write_web` wrote: the folder, its file count and total size in bytes."""

    path: Path
    files: int
    bytes: int


def scene_scale(splats) -> float:
    """Metres per unit of the page's scene: the median standard deviation of the Gaussians."""
    return float(np.median(splats.scales))


def start_camera(model, cameras=None) -> dict:
    """viser initial-camera fields (position, look_at, up_direction, fov) of the first capture camera."""
    from capture.camera import viser_view

    cam = (cameras or model.rgbz.cameras)[0]
    dist = float(np.linalg.norm(np.asarray(model.bounds, float).mean(axis=0) - cam.center))
    return viser_view(cam, max(dist, 1e-3))


def splat_node(splats) -> dict:
    """Keyword arguments of viser's ``scene.add_gaussian_splats`` for ``splats``: centres and
    covariances in units of :func:`scene_scale` (float16 covariances stay normal numbers), the DC
    colour clipped to [0, 1], opacities (N, 1), and the node scale back to metres."""
    unit = scene_scale(splats)
    colour = np.clip(COLOUR_OFFSET + SH_C0 * splats.sh[:, 0, :].astype(np.float64), 0.0, 1.0)
    cov = splats.covariances() / (unit * unit)
    return dict(centers=(splats.positions / unit).astype(np.float32), covariances=cov.astype(np.float32),
                rgbs=colour.astype(np.float32), opacities=splats.opacities.astype(np.float32)[:, None], scale=unit)


def build_scene(server, splats, model) -> None:
    """Put the splats, the up direction and the initial camera into ``server``'s scene."""
    from capture.orbit import estimate_up

    up = estimate_up(model.rgbz.cameras)
    server.scene.set_up_direction(tuple(float(x) for x in up))
    server.scene.add_gaussian_splats("/splats", **splat_node(splats))
    v = start_camera(model)
    server.initial_camera.position = tuple(float(x) for x in v["position"])
    server.initial_camera.look_at = tuple(float(x) for x in v["look_at"])
    server.initial_camera.up = tuple(float(x) for x in v["up_direction"])
    server.initial_camera.fov = float(v["fov"])
    server.initial_camera.near = NEAR_SHARE * float(np.linalg.norm(v["look_at"] - v["position"]))


def write_web(splats, model, folder) -> WebResult:
    """Write the page of ``splats`` (volume.splats.Splats) of ``model`` into ``folder`` (created
    or replaced atomically); see the module docstring."""
    import viser

    if len(splats) == 0:
        raise ValueError(f"{folder}: no Gaussian to put on the page")
    folder = Path(folder)
    if folder.exists() and not (folder / PAGE).exists() and any(folder.iterdir()):
        raise ValueError(f"{folder}: exists, is not empty and holds no {PAGE}; refusing to replace it")
    with contextlib.redirect_stdout(io.StringIO()):  # viser prints its banner even when not verbose
        server = viser.ViserServer(host="127.0.0.1", port=0, label="furrow", verbose=False)
    try:
        build_scene(server, splats, model)
        html = server.get_scene_serializer().as_html()
    finally:
        with contextlib.redirect_stdout(io.StringIO()):
            server.stop()
    with atomic_dir(folder) as tmp:
        (tmp / PAGE).write_text(html, encoding="utf-8")
    files = [p for p in folder.rglob("*") if p.is_file()]
    return WebResult(folder, len(files), sum(p.stat().st_size for p in files))

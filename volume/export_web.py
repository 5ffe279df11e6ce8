"""A static web page that draws a model's 3D Gaussians in the browser (issue 33, ``furrow export --web``).

:func:`write_web` writes ``DIR/index.html`` (the template volume/web/index.html: WebGL2, no
dependency, nothing fetched but the file beside it) and ``DIR/splats.bin`` (the Gaussians: positions and opacities
float32, covariances and the spherical harmonics float16).  Any static file server shows it
(``python -m http.server``) with nothing of furrow running, offline.  The page draws with the image
formation of furrow's ``splat`` method (its shaders are ports of render/splat/shaders/), including
the view-dependent colour, starts at the first capture camera (its centre, its optical axis to the
object's distance, its vertical field of view; the rig's up: ``capture.orbit.estimate_up``) and
orbits about that point with the mouse.

Why not viser's static embedding (``ViserServer.get_scene_serializer().as_html()``, tried first):
viser 1.1.1's splat node draws one colour per Gaussian and skips every Gaussian whose
alpha x det(2-D covariance + 0.3) is under 0.25, i.e. the faint pixel-sized Gaussians of thin
needles: on the path-traced conifer only scattered dots were left (silhouette IoU 0.01 against
furrow's render of the first capture camera), while the coarser plant came out right (0.98).
:func:`splat_node` still gives ``furrow view`` viser's node ("splats in the browser"), where the
viewer's own scene is viser's.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from capture.atomic import atomic_dir
from volume.splat_sh import COLOUR_OFFSET, SH_C0

#: The page's template (package data): WebGL2 ports of render/splat/shaders/, the sort, the orbit.
PAGE_TEMPLATE = Path(__file__).resolve().parent / "web" / "index.html"
#: Names of the page and of its data in the folder.
PAGE_NAME = "index.html"
DATA_NAME = "splats.bin"


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


def page_camera(model) -> dict:
    """The page's first camera (JSON-ready): position, target, up, vertical fov (radians)."""
    from capture.orbit import estimate_up

    v = start_camera(model)
    return {"position": [float(x) for x in v["position"]], "target": [float(x) for x in v["look_at"]],
            "up": [float(x) for x in estimate_up(model.rgbz.cameras)], "fov": float(v["fov"])}


def half_texels(k: int) -> int:
    """RGBA16F texels per Gaussian of the page: 6 covariance terms and 3 ``k`` SH coefficients."""
    return (6 + 3 * k + 3) // 4


def splats_bin(splats) -> tuple[bytes, float]:
    """(splats.bin bytes (volume/web_page.py LAYOUT), covariance unit in m^2)."""
    n, k = len(splats), splats.sh.shape[1]
    unit2 = scene_scale(splats) ** 2
    c = splats.covariances() / unit2
    half = np.zeros((n, 4 * half_texels(k)), np.float16)
    half[:, :6] = np.stack([c[:, 0, 0], c[:, 0, 1], c[:, 0, 2], c[:, 1, 1], c[:, 1, 2], c[:, 2, 2]], 1)
    half[:, 6:6 + 3 * k] = splats.sh.reshape(n, 3 * k)
    pos = np.concatenate([splats.positions, splats.opacities[:, None]], 1).astype("<f4")
    return np.uint32(n).astype("<u4").tobytes() + pos.tobytes() + half.astype("<f2").tobytes(), unit2


def write_web(splats, model, folder, title: str = "furrow splats") -> WebResult:
    """Write the page of ``splats`` (volume.splats.Splats) of ``model`` into ``folder`` (created
    or replaced atomically); see the module docstring."""
    import json

    if len(splats) == 0:
        raise ValueError(f"{folder}: no Gaussian to put on the page")
    folder = Path(folder)
    if folder.exists() and not (folder / PAGE_NAME).exists() and any(folder.iterdir()):
        raise ValueError(f"{folder}: exists, is not empty and holds no {PAGE_NAME}; refusing to replace it")
    data, unit2 = splats_bin(splats)
    k = splats.sh.shape[1]
    html = PAGE_TEMPLATE.read_text(encoding="utf-8")
    html = (html.replace("__TITLE__", title).replace("__CAMERA__", json.dumps(page_camera(model)))
            .replace("__SH_K__", str(k)).replace("__HALF_TEXELS__", str(half_texels(k)))
            .replace("__COV_UNIT2__", repr(float(unit2))))
    with atomic_dir(folder) as tmp:
        (tmp / PAGE_NAME).write_text(html, encoding="utf-8")
        (tmp / DATA_NAME).write_bytes(data)
    files = [p for p in folder.rglob("*") if p.is_file()]
    return WebResult(folder, len(files), sum(p.stat().st_size for p in files))

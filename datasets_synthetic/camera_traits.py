"""Traits of real cameras for synthetic captures: per-view auto exposure / white balance, and a
distorting lens.

* **Auto exposure** (``furrow synth --auto-exposure [SIGMA_EV]``): the linear colour of each
  *kept* view (index i % holdout == 0: the views ``furrow eval --holdout`` builds from) is
  multiplied by an exposure 2^N(0, SIGMA_EV) and per-channel white-balance gains exp(N(0, wb)),
  then written as 8-bit sRGB with clipping, as a phone does between frames.  Held-out views keep
  the camera's true exposure (what a render should match).  The true gains go to
  ``gt/exposure.json`` (per view: ``gain`` r g b, ``ev``, ``wb``) for ``furrow bench photometric``.
* **Lens** (``--lens opencv|fisheye``): each view is rendered by a pinhole camera with the same
  focal length and a margin wide enough for the distorted field, at twice the resolution, then
  resampled with the forward distortion (colour and coverage at 2 x 2 points per pixel, averaged;
  depth edge-aware, normals nearest) to the distorted camera, whose K (the rig's) and coefficients
  are written to transforms.json (``camera_model``).
"""

from __future__ import annotations

import json

import numpy as np

from capture.camera import Camera, resample_pixel_coords
from capture.lens import FISHEYE, PERSPECTIVE, Lens, remap_bilinear, remap_depth, undistort_pixels

#: The issue's OPENCV lens: up to ~10 px of displacement at the corners of a 640x480 view.
OPENCV_LENS = Lens(PERSPECTIVE, (-0.12, 0.03, 8e-4, -5e-4), "OPENCV")
#: A mild equidistant fisheye (about 30 px at the corners of a 640x480, 36 degree view).
FISHEYE_LENS = Lens(FISHEYE, (0.03, -0.01, 0.002, -0.0005), "OPENCV_FISHEYE")
LENSES = {"opencv": OPENCV_LENS, "fisheye": FISHEYE_LENS}
#: The issue's jitter: exposure sigma (EV) and white-balance sigma (natural log per channel).
EXPOSURE_SIGMA_EV = 0.35
WHITE_BALANCE_SIGMA = 0.06
#: Pixels of margin beyond the distorted field in the pinhole render.
RENDER_MARGIN_PX = 2
#: Sub-samples per axis of each distorted pixel (the pinhole render is made this much finer).
LENS_SUPERSAMPLE = 2
#: RNG stream of the exposure draw (the noise models use 1-4).
EXPOSURE_STREAM = 7
EXPOSURE_FILE = "gt/exposure.json"


def exposure_gains(n_views: int, sigma_ev: float, wb_sigma: float, seed: int, holdout: int = 2) -> np.ndarray:
    """(V, 3) linear gains of the camera per view: 2^N(0, sigma_ev) exp(N(0, wb_sigma)) for the
    views i % holdout == 0, 1 for the others (``holdout`` 1: every view)."""
    if sigma_ev < 0 or wb_sigma < 0 or holdout < 1:
        raise ValueError(f"auto exposure: sigmas must be >= 0 and holdout >= 1, got {sigma_ev}, {wb_sigma}, {holdout}")
    rng = np.random.default_rng([int(seed), EXPOSURE_STREAM])
    ev = rng.normal(0.0, sigma_ev, n_views)
    wb = rng.normal(0.0, wb_sigma, (n_views, 3))
    gains = np.exp2(ev)[:, None] * np.exp(wb)
    gains[np.arange(n_views) % holdout != 0] = 1.0
    return gains


def exposure_jump_gains(n_views: int, jump_ev: float, count: int, seed: int, holdout: int = 2) -> np.ndarray:
    """(V, 3) linear gains of a camera whose exposure jumped by ``jump_ev`` in ``count`` of the kept views (i %
    holdout == 0, chosen by ``seed``) and held still in the others (1): an auto exposure that reacts in a few
    frames only (a bright patch of the room coming into view)."""
    kept = np.flatnonzero(np.arange(n_views) % holdout == 0)
    if not 0 <= count <= len(kept):
        raise ValueError(f"exposure jump: count must be 0..{len(kept)} (the kept views), got {count}")
    rng = np.random.default_rng([int(seed), EXPOSURE_STREAM, 1])
    gains = np.ones((n_views, 3))
    gains[np.sort(rng.choice(kept, count, replace=False))] = 2.0 ** float(jump_ev)
    return gains


def apply_exposure(scanset, gains: np.ndarray):
    """The scan set with each view's linear colour multiplied by its gains (float linear kept:
    the writer encodes 8-bit sRGB and clips)."""
    from dataclasses import replace

    from capture.scan import Scan

    scans = tuple(Scan((s.linear_rgb * g.astype(np.float32)).astype(np.float32), s.depth, s.camera, s.name, s.alpha)
                  for s, g in zip(scanset.scans, np.asarray(gains), strict=True))
    return replace(scanset, scans=scans)


def exposure_record(names, gains: np.ndarray, sigma_ev: float, wb_sigma: float, holdout: int) -> bytes:
    """gt/exposure.json: the true per-view camera gains (module docstring)."""
    g = np.asarray(gains, np.float64)
    ev = np.log2(g).mean(axis=1)
    views = [{"name": n, "gain": gi.tolist(), "ev": float(e), "wb": (gi / np.exp2(e)).tolist(),
              "jittered": bool(i % holdout == 0)}
             for i, (n, gi, e) in enumerate(zip(names, g, ev, strict=True))]
    return json.dumps({"convention": "camera gain applied to linear colour before 8-bit sRGB encoding; ev = mean "
                       "log2 gain over r g b, wb = gain / 2^ev", "sigma_ev": sigma_ev, "wb_sigma": wb_sigma,
                       "holdout": holdout, "views": views}, indent=1).encode()


# --------------------------------------------------------------------------- lens
def margin_camera(cam: Camera, lens: Lens) -> Camera:
    """The pinhole camera (same focal length and pose) whose image covers every ray of the
    distorted camera (``cam``'s K and size, ``lens``) plus :data:`RENDER_MARGIN_PX`."""
    W, H = cam.width, cam.height
    t = np.arange(max(W, H), dtype=np.float64)
    edge = np.concatenate([np.stack([t[:W], np.zeros(W)], 1), np.stack([t[:W], np.full(W, H - 1)], 1),
                           np.stack([np.zeros(H), t[:H]], 1), np.stack([np.full(H, W - 1), t[:H]], 1)])
    und = undistort_pixels(edge, cam.K, lens)
    left = max(0, int(np.ceil(-und[:, 0].min()))) + RENDER_MARGIN_PX
    top = max(0, int(np.ceil(-und[:, 1].min()))) + RENDER_MARGIN_PX
    right = max(0, int(np.ceil(und[:, 0].max() - (W - 1)))) + RENDER_MARGIN_PX
    bottom = max(0, int(np.ceil(und[:, 1].max() - (H - 1)))) + RENDER_MARGIN_PX
    K = cam.K.copy()
    K[0, 2] += left
    K[1, 2] += top
    return Camera(K, cam.cam_from_world, W + left + right, H + top + bottom, name=cam.name)


def render_through_lens(rast, cam: Camera, lens: Lens, supersample: int = LENS_SUPERSAMPLE):
    """``rast.render`` (render.mesh.raster.gl.MeshRasterizer) of the distorted camera (``cam``, ``lens``):
    a pinhole render with a margin (:func:`margin_camera`) at ``supersample`` times the resolution,
    sampled bilinearly at ``supersample`` x ``supersample`` points of every distorted pixel and
    box-averaged (colour, coverage: the area sampling of the pinhole capture, not a blur); depth
    edge-aware and normals nearest at the pixel centres."""
    import cv2

    from render.mesh.raster.gl import RasterResult

    S = int(supersample)
    wide = margin_camera(cam, lens)
    res = rast.render(wide.scaled(S))
    H, W = cam.height, cam.width

    def source(uv_cam):
        src = undistort_pixels(uv_cam.reshape(-1, 2), cam.K, lens, wide.K)
        src = resample_pixel_coords(src, S).astype(np.float32)
        return src[:, 0].reshape(uv_cam.shape[:2]), src[:, 1].reshape(uv_cam.shape[:2])

    mx, my = source(resample_pixel_coords(cam.scaled(S).pixel_grid(), 1.0 / S))
    colour = remap_bilinear(res.color, mx, my).reshape(H, S, W, S, 3).mean(axis=(1, 3))
    alpha = remap_bilinear(res.alpha, mx, my).reshape(H, S, W, S).mean(axis=(1, 3))
    cx, cy = source(cam.pixel_grid())
    depth = remap_depth(res.depth, cx, cy)
    normal = cv2.remap(np.ascontiguousarray(res.normal, np.float32), cx, cy, cv2.INTER_NEAREST,
                       borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    alpha = np.clip(alpha, 0.0, 1.0).astype(np.float32)
    return RasterResult(colour.astype(np.float32), depth, normal, depth > 0, alpha)

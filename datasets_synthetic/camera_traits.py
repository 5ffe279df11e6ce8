"""Traits of real cameras for synthetic captures: per-view auto exposure / white balance, and a
distorting lens.

* **Auto exposure** (``furrow synth --auto-exposure [SIGMA_EV]``): the linear colour of each
  *kept* view (index i % holdout == 0: the views ``furrow eval --holdout`` builds from) is
  multiplied by an exposure 2^N(0, SIGMA_EV) and per-channel white-balance gains exp(N(0, wb)),
  then written as 8-bit sRGB with clipping, as a phone does between frames.  Held-out views keep
  the camera's true exposure (what a render should match).  The true gains go to
  ``gt/exposure.json`` (per view: ``gain`` r g b, ``ev``, ``wb``) for ``furrow bench photometric``.
* **Lens** (``--lens opencv|fisheye``): each view is rendered by a pinhole camera with the same
  focal length and a margin wide enough for the distorted field, then resampled with the forward
  distortion (colour and coverage bilinear, depth edge-aware, normals nearest) to the distorted
  camera, whose K (the rig's) and coefficients are written to transforms.json (``camera_model``).
"""

from __future__ import annotations

import json

import numpy as np

from capture.camera import Camera
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


def render_through_lens(rast, cam: Camera, lens: Lens):
    """``rast.render`` (render.raster.MeshRasterizer) of the distorted camera (``cam``, ``lens``):
    a pinhole render with a margin (:func:`margin_camera`) resampled with the forward distortion."""
    import cv2

    from render.raster import RasterResult

    big = margin_camera(cam, lens)
    res = rast.render(big)
    grid = cam.pixel_grid().reshape(-1, 2).astype(np.float64)
    src = undistort_pixels(grid, cam.K, lens, big.K).astype(np.float32)
    mx = src[:, 0].reshape(cam.height, cam.width)
    my = src[:, 1].reshape(cam.height, cam.width)
    depth = remap_depth(res.depth, mx, my)
    normal = cv2.remap(np.ascontiguousarray(res.normal, np.float32), mx, my, cv2.INTER_NEAREST,
                       borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    return RasterResult(remap_bilinear(res.color, mx, my), depth, normal, depth > 0,
                        np.clip(remap_bilinear(res.alpha, mx, my), 0.0, 1.0))

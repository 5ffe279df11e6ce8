"""Brute-force ray caster of microfacet frames (slow, float64; small scenes only): the GPU
frame's twin, built from the per-step twins in ``render/microfacet/geometry.py``."""

from __future__ import annotations

import numpy as np

from capture.camera import Camera, image_axes
from render.microfacet import geometry as mg
from render.owner import near_far


def reference_render(eye: Camera, centers: np.ndarray, w: float, spacing: float, cameras,
                     rgb: np.ndarray, depth: np.ndarray, bounds: np.ndarray, rule: str = "vote",
                     n_fallback: int | None = None, refine: int | None = None, debug: str | None = None):
    """Brute-force ray caster of the microfacet slices (slow, float64): the GPU frame's twin.

    For every pixel centre of ``eye``, intersect the ray with every slice quad, shade each hit
    (microfacet_geometry.shade_fragments) and keep the nearest surviving one.

    With ``debug`` (microfacet_geometry.DEBUG_OUTPUTS) the image holds the fragment shader's debug
    codes in its red channel instead (microfacet_geometry.debug_codes); for "rejections" every
    pixel a slice covers is alive, rejected fragments behind all kept ones.

    ``rgb`` (N, H, W, C): C = 4 with a matte (premultiplied colour + alpha,
    render.microfacet.rgbz_textures.twin_colours): the image then holds the premultiplied colour
    and the fragment's alpha in its channel 3.

    Returns (image (H, W, C) linear, alive (H, W) bool, slices (voxel, n)).
    """
    near, _ = near_far(eye, bounds)
    eye_pos = eye.center
    right, up = image_axes(eye)
    vox, n = mg.slice_distances(centers, w, eye_pos, spacing, near)
    v, a, b = mg.slice_frame(centers, eye_pos, right, up)
    idx, wts = mg.select_cameras(centers, mg.footprint_radius(w), eye_pos, cameras)
    H, W = eye.height, eye.width
    rays = eye.pixel_rays(eye.pixel_grid().reshape(-1, 2))
    rays = rays @ eye.world_from_cam[:3, :3].T  # world directions with eye-z = 1
    ha_all, hb_all = mg.slice_half_extents(centers[vox], w, eye_pos, v[vox], a[vox], b[vox], n * spacing)
    best_z = np.full(H * W, np.inf)
    C = np.shape(rgb)[-1]
    img = np.zeros((H * W, C))
    rejected = np.zeros(H * W, bool)
    for j, nn, ha, hb in zip(vox, n, ha_all, hb_all):
        s = nn * spacing
        denom = rays @ v[j]
        t = np.where(denom > 1e-12, s / np.where(denom > 1e-12, denom, 1.0), -1.0)
        hit = (t > 0) & (t < best_z)
        if not hit.any():
            continue
        pix = np.flatnonzero(hit)
        x = eye_pos + t[pix, None] * rays[pix]
        q = eye_pos + s * v[j]
        ca = (x - q) @ a[j]
        cb = (x - q) @ b[j]
        inq = (np.abs(ca) <= ha) & (np.abs(cb) <= hb) & (t[pix] >= near)
        pix, x = pix[inq], x[inq]
        if not len(pix):
            continue
        col, alive, src = mg.shade_fragments(x, np.repeat(idx[j:j + 1], len(pix), 0),
                                             np.repeat(wts[j:j + 1], len(pix), 0), spacing, cameras, rgb, depth,
                                             rule, n_fallback, eye_pos, refine, with_source=True)
        if debug is not None:
            col = np.zeros_like(col)
            col[:, 0] = mg.debug_codes(alive, src, debug)
            rejected[pix[~alive]] = True
        pix = pix[alive]
        best_z[pix] = t[pix]
        img[pix] = col[alive]
    alive = np.isfinite(best_z)
    if debug == "rejections":
        img[rejected & ~alive, 0] = mg.DEBUG_REJECTED
        alive |= rejected
    return img.reshape(H, W, C), alive.reshape(H, W), (vox, n)

"""Numpy twin of the fixed-mesh VDTM baseline's fragment shader (``render/mesh/shaders/vdtm_frag.glsl``,
the GL owner ``render.mesh.gl.VdtmRenderer``): the same camera selection and blend weights as the
microfacets (``render.microfacet.geometry``), per pixel of a rasterised mesh."""

from __future__ import annotations

import numpy as np

from capture.camera import Camera
from render.microfacet import geometry as mg


def vdtm_reference(eye: Camera, depth: np.ndarray, vertex_colour: np.ndarray, cameras, rgb: np.ndarray,
                   rgbz_depth: np.ndarray, vis_tol: float) -> np.ndarray:
    """Numpy twin of vdtm_frag.glsl for the pixels where ``depth`` (H, W, z-depth of the mesh
    in ``eye``, e.g. from render.mesh.raster.gl.rasterize_reference) is > 0; ``vertex_colour`` (H, W, 3)
    is the interpolated vertex colour there.  ``rgb`` (N, H, W, C): C = 4 with a matte
    (premultiplied colour + alpha; the vertex colour is opaque).  Returns (H, W, C) linear colour."""
    mask = depth > 0
    pts = eye.unproject(eye.pixel_grid()[mask], depth[mask])
    idx, w = mg.select_cameras(pts, 0.0, eye.center, cameras)
    N = len(pts)
    vis = np.zeros((N, mg.K_CAND), bool)
    C = np.shape(rgb)[-1]
    cols = np.zeros((N, mg.K_CAND, C))
    for k in range(mg.K_CAND):
        for c in np.unique(idx[:, k][idx[:, k] >= 0]):
            m = idx[:, k] == c
            col, d, D, inside = mg.sample_rgbz(cameras[c], rgb[c], rgbz_depth[c], pts[m])
            vis[m, k] = inside & (d > 0) & (np.abs(d - D) < vis_tol)
            cols[m, k] = col
    wb = w * vis[:, : mg.K_BLEND]
    wsum = wb.sum(1)
    blend = (wb[:, :, None] * cols[:, : mg.K_BLEND]).sum(1) / np.where(wsum > 0, wsum, 1)[:, None]
    first = np.argmax(vis, axis=1)
    fcol = cols[np.arange(N), first]
    vcol = vertex_colour[mask]
    if C == 4:
        vcol = np.concatenate([vcol, np.ones((len(vcol), 1))], 1)
    out = np.where((wsum > mg.WEIGHT_EPS)[:, None], blend, np.where(vis.any(1)[:, None], fcol, vcol))
    img = np.zeros(depth.shape + (C,))
    img[mask] = out
    return img

"""Slow references of the glossy mesh renderer (render/mesh/glossy/gl.py; docs/methods.md §2).

* :func:`glossy_pixels` -- the numpy rasteriser (``render.mesh.raster.reference.interpolate_reference``)
  at the pixel centres: per-pixel eye-facing normal, view vector, reflection vector and
  smoothness (per vertex interpolated perspective-correctly, or the bilinear per-texel map).
* :func:`glossy_msem_reference` -- the GL shader's twin: ``render.shading.msem.msem_lookup`` of
  the same MSEM at those pixels.
* :func:`phong_reference` -- the thesis' Table 5 reference: per pixel, the normalised Phong
  integral over every environment pixel, exponent Lambda = g(lambda) (Eq. 13,
  ``render.shading.msem.msem_lambda``)::

      L = sum_w L(w) max(0, r.w)^Lambda [n.w >= 0] Omega(w) / sum_w max(0, r.w)^Lambda Omega(w)

  with the horizon gate [n.w >= 0] (``gate=True``, the Phong model of Eq. 1-2) or without it
  (the quantity the MSEM tabulates, Eq. 3-4), so that the table/interpolation error and the
  dropped-gate error can be told apart.
"""

from __future__ import annotations

import numpy as np

from capture.camera import Camera
from capture.sampling import from_texcoord, sample_image
from render.mesh.glossy.gl import GlossyMesh
from render.mesh.raster.gl import MIN_NEAR, RasterMesh
from render.mesh.raster.reference import _facing_normals, interpolate_reference
from render.shading.msem import msem_lambda, msem_lookup

#: Pixels per chunk of the brute-force sum (memory: chunk x env pixels float64).
PHONG_CHUNK = 48
#: Relative weight below which environment pixels are skipped in the brute-force sum.
PHONG_PRUNE = 1e-15


def sample_smoothness_map(m: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """(N,) bilinear lookup of an (h, w) map at ``uv`` (N, 2) like the GL texture: texel (i, j)
    centred at (u, v) = ((j + 0.5) / w, (i + 0.5) / h), wrap in u, clamp to edge in v."""
    m = np.asarray(m, np.float64)
    h, w = m.shape
    return sample_image(m, from_texcoord(uv[:, 0], w), from_texcoord(uv[:, 1], h), "linear", ("clamp", "wrap"))


def glossy_pixels(mesh: GlossyMesh, camera: Camera, near: float = MIN_NEAR) -> dict:
    """Per covered pixel: mask (H, W) bool, normal n, view v (towards the eye), reflection r
    (M, 3), smoothness (M,), depth (H, W) (0 = background)."""
    V = len(mesh.vertices)
    uv = mesh.uv if mesh.uv is not None else np.zeros((V, 2), np.float32)
    rm = RasterMesh(mesh.vertices, mesh.faces, np.zeros((V, 3), np.float32), normals=mesh.normals)
    att = np.concatenate([mesh.normals, mesh.smoothness[:, None], uv], 1)
    depth, face, img = interpolate_reference(rm, camera, att, near)
    mask = face >= 0
    a = img[mask]
    pts = camera.unproject(camera.pixel_grid()[mask], depth[mask])
    n = _facing_normals(rm, camera, face[mask], a[:, :3], pts)
    v = camera.center - pts
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    r = 2 * np.sum(n * v, 1, keepdims=True) * n - v
    if mesh.smoothness_map is not None:
        sm = sample_smoothness_map(mesh.smoothness_map, a[:, 4:6])
    else:
        sm = a[:, 3]
    return {"mask": mask, "n": n, "v": v, "r": r, "smoothness": np.clip(sm, 0, 1),
            "depth": np.where(mask, depth, 0.0)}


def glossy_msem_reference(volume: np.ndarray, px: dict, kr=1.0) -> np.ndarray:
    """(H, W, 3) the GL shader's numpy twin: k_r * msem_lookup(volume, r, smoothness)."""
    out = np.zeros(px["mask"].shape + (3,))
    out[px["mask"]] = np.asarray(kr, float) * msem_lookup(volume, px["r"], px["smoothness"])
    return out


def phong_reference_pair(env, r: np.ndarray, n: np.ndarray, smoothness: np.ndarray, s: int,
                         prune: float = PHONG_PRUNE):
    """(ungated, gated) (N, 3) float64 brute-force normalised Phong integrals (module doc) over
    every pixel of ``env`` for reflection vectors ``r`` (N, 3), normals ``n`` (N, 3) and
    smoothness (N,), with Lambda = msem_lambda(smoothness, s) for an s^3 MSEM, in one pass.
    Weights are computed in log space with the per-pixel maximum removed (no underflow for
    Lambda in the tens of thousands).  Pixels whose weight is below ``prune`` times the peak for
    every pixel of a chunk are skipped (their total share is below prune x the pixel count,
    ~1e-10 at the default; ``prune=0`` sums every pixel)."""
    d = env.pixel_directions().reshape(-1, 3)
    om = env.pixel_solid_angles().reshape(-1)
    L = env.data.reshape(-1, 3).astype(np.float64)
    lam = msem_lambda(np.asarray(smoothness, np.float64), s)
    r, n = np.asarray(r, np.float64), np.asarray(n, np.float64)
    out = np.empty((len(r), 3))
    out_g = np.empty((len(r), 3))
    order = np.argsort(lam)  # chunks of similar Lambda share a small set of contributing pixels
    with np.errstate(divide="ignore", invalid="ignore", under="ignore"):
        for a in range(0, len(r), PHONG_CHUNK):
            sl = order[a:a + PHONG_CHUNK]
            c = r[sl] @ d.T
            cols = slice(None)
            if prune > 0:
                # pixels whose weight is below prune x the pixel's peak weight for every pixel of
                # the chunk are skipped: (c / c_max)^Lambda < prune <=> c < c_max prune^(1/Lambda)
                cmax = c.max(1)
                cut = np.where(lam[sl] > 0, cmax * prune ** (1.0 / np.maximum(lam[sl], 1e-300)), 0.0)
                keep = (c > cut[:, None]).any(0)
                cols = np.nonzero(keep)[0]
                c = c[:, cols]
            lg = np.where(c > 0, np.log(np.where(c > 0, c, 1.0)), -np.inf) * lam[sl, None]
            lg = np.where(c > 0, lg, -np.inf)  # Lambda = 0: the hemisphere around r
            lg -= lg.max(1, keepdims=True)
            w = np.exp(lg) * om[cols]
            norm = w.sum(1, keepdims=True)
            out[sl] = (w @ L[cols]) / norm
            out_g[sl] = ((w * ((n[sl] @ d[cols].T) >= 0)) @ L[cols]) / norm
    return out, out_g


def phong_reference(env, r: np.ndarray, n: np.ndarray, smoothness: np.ndarray, s: int,
                    gate: bool = True) -> np.ndarray:
    """(N, 3) float64 one of :func:`phong_reference_pair`: gated (the Phong model) or not."""
    return phong_reference_pair(env, r, n, smoothness, s)[1 if gate else 0]


def glossy_phong_reference(env, px: dict, s: int, kr=1.0, gate: bool = True) -> np.ndarray:
    """(H, W, 3) :func:`phong_reference` at every covered pixel of :func:`glossy_pixels`."""
    return glossy_phong_reference_pair(env, px, s, kr)[1 if gate else 0]


def glossy_phong_reference_pair(env, px: dict, s: int, kr=1.0):
    """(ungated, gated) (H, W, 3) images of :func:`phong_reference_pair` at the covered pixels."""
    u, g = phong_reference_pair(env, px["r"], px["n"], px["smoothness"], s)
    out = []
    for x in (u, g):
        img = np.zeros(px["mask"].shape + (3,))
        img[px["mask"]] = np.asarray(kr, float) * x
        out.append(img)
    return tuple(out)

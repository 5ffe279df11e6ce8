"""Numpy twin of the relighting passes (``render.relight.gl.Relighter``; shaders
``render/relight/shaders/relight_volume_frag.glsl`` and ``relight_apply_frag.glsl``).

1. **Share volume** (once per capture / new lighting): at every voxel centre x of a cube over the
   model within VISIBILITY_BAND_VOXELS of the surface, the visible shares S_A, S_B
   (``render.shading.transfer.visible_share``: the sphere set's SSDF) at the voxel's nearest surface
   point x - d(x) n, lifted by VISIBILITY_LIFT_VOXELS; n = the gradient of the model's signed
   distance smoothed at the scale of the lighting (:data:`ORIENTATION_SMOOTH` of the cube).
2. **Apply** (per frame, deferred over any method's Frame): the world point of each pixel's depth,
   its orientation (the smoothed SDF's gradient there), the direction to the camera, the shares
   sampled from the volume, the gain of ``render.shading.transfer.relight_gain``, times the colour.

Volumes are sampled as GL samples a 3-D texture (texel centres at origin + (i + 0.5) w, trilinear,
clamped to the edge texels); the gradient is the central difference over one voxel on each axis.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from capture.camera import Camera

#: Central-difference step of the SDF gradient, in voxels of the volume.
GRADIENT_STEP_VOXELS = 1.0
#: Finest resolution of the signed distance level the orientation (and the gain volume) comes from.
ORIENTATION_MAX_RES = 32
#: Gaussian smoothing of that signed distance before its gradient, as a fraction of the cube's side:
#: the orientation of a fur shell or a leafy crown, not of single strands or clumps (at 0 the 32^3
#: level's fur-ball normals are blotchy; measured in docs/relight.md).
ORIENTATION_SMOOTH = 0.1
#: The visibility of a voxel is taken this many voxels above its nearest surface point.
VISIBILITY_LIFT_VOXELS = 0.5
#: Only voxels within this many voxels of the surface (|signed distance|) get the sphere set's
#: visibility (the pixels lie near the surface; the trilinear lookup reaches one voxel out);
#: the others are treated as unoccluded.
VISIBILITY_BAND_VOXELS = 2.0


@dataclass(frozen=True)
class SdfGrid:
    """A signed distance volume on a cube of voxels.

    values: (L, L, L) float32 metres, positive outside, indexed [i, j, k] (x, y, z).
    origin: (3,) world position (metres) of the cube's minimum corner; voxel: edge length (metres).
    """

    values: np.ndarray
    origin: np.ndarray
    voxel: float

    def __post_init__(self) -> None:
        v = np.asarray(self.values, np.float32)
        if v.ndim != 3 or len(set(v.shape)) != 1 or not np.all(np.isfinite(v)):
            raise ValueError(f"SdfGrid: values must be a finite (L, L, L) cube, got {v.shape}")
        o = np.asarray(self.origin, np.float64)
        if o.shape != (3,) or not float(self.voxel) > 0:
            raise ValueError("SdfGrid: origin must be (3,) and voxel > 0")
        object.__setattr__(self, "values", v)
        object.__setattr__(self, "origin", o)
        object.__setattr__(self, "voxel", float(self.voxel))

    @property
    def resolution(self) -> int:
        return int(self.values.shape[0])


def orientation_grid(model, max_res: int = ORIENTATION_MAX_RES) -> SdfGrid:
    """The finest level of the model's pyramid with stored values and resolution <= ``max_res``
    (else the coarsest with values); without any, the signed distance of the sphere set sampled on
    a ``max_res`` cube over the model's bounds."""
    levels = [lv for lv in model.pyramid.levels if lv.values is not None]
    if levels:
        fit = [lv for lv in levels if lv.resolution <= max_res]
        lv = fit[-1] if fit else levels[0]
        return SdfGrid(lv.values, lv.origin, lv.voxel_size)
    b = np.asarray(model.bounds, np.float64)
    ext = float((b[1] - b[0]).max()) * 1.1
    origin = 0.5 * (b[0] + b[1]) - ext / 2
    w = ext / max_res
    g = origin[None] + (np.arange(max_res)[:, None] + 0.5) * w
    X, Y, Z = np.meshgrid(g[:, 0], g[:, 1], g[:, 2], indexing="ij")
    pts = np.stack([X, Y, Z], -1).reshape(-1, 3)
    return SdfGrid(sphere_set_sdf(model.spheres, pts).reshape(max_res, max_res, max_res).astype(np.float32), origin, w)


def sphere_set_sdf(spheres, points) -> np.ndarray:
    """(P,) signed distance of the union of the spheres at points (P, 3)."""
    x = np.asarray(points, np.float64)
    out = np.full(len(x), np.inf)
    for c, r in zip(np.asarray(spheres.centers), np.asarray(spheres.radii)):
        out = np.minimum(out, np.linalg.norm(x - c, axis=1) - r)
    return out


def sdf_sample(grid: SdfGrid, points) -> np.ndarray:
    """(P,) trilinear sample of the volume at world points (P, 3), clamped to the edge texels."""
    L = grid.resolution
    f = (np.asarray(points, np.float64) - grid.origin) / grid.voxel - 0.5
    f = np.clip(f, 0.0, L - 1.0)
    i0 = np.minimum(np.floor(f).astype(np.int64), L - 2) if L > 1 else np.zeros_like(f, np.int64)
    t = f - i0
    v = grid.values.astype(np.float64)
    out = np.zeros(len(f))
    for dx in (0, 1):
        for dy in (0, 1):
            for dz in (0, 1):
                w = ((t[:, 0] if dx else 1 - t[:, 0]) * (t[:, 1] if dy else 1 - t[:, 1])
                     * (t[:, 2] if dz else 1 - t[:, 2]))
                out += w * v[np.minimum(i0[:, 0] + dx, L - 1), np.minimum(i0[:, 1] + dy, L - 1),
                             np.minimum(i0[:, 2] + dz, L - 1)]
    return out


def sdf_gradient(grid: SdfGrid, points) -> np.ndarray:
    """(P, 3) central-difference gradient of the sampled volume (per metre; not normalised)."""
    x = np.asarray(points, np.float64)
    h = GRADIENT_STEP_VOXELS * grid.voxel
    g = np.empty_like(x)
    for a in range(3):
        e = np.zeros(3)
        e[a] = h
        g[:, a] = (sdf_sample(grid, x + e) - sdf_sample(grid, x - e)) / (2 * h)
    return g


def frame_points(depth, camera: Camera) -> np.ndarray:
    """(H, W, 3) world points of a z-depth map (pixel centres, OpenCV)."""
    return camera.unproject(camera.pixel_grid(), np.asarray(depth, np.float64))


def smoothed(grid: SdfGrid, sigma_voxels: float) -> SdfGrid:
    """The grid's values Gaussian-smoothed (``sigma_voxels``; edges repeated), same placement."""
    from scipy import ndimage

    if sigma_voxels <= 0:
        return grid
    return SdfGrid(ndimage.gaussian_filter(grid.values.astype(np.float64), float(sigma_voxels), mode="nearest")
                   .astype(np.float32), grid.origin, grid.voxel)


def voxel_centres(grid: SdfGrid) -> np.ndarray:
    """(L^3, 3) world voxel centres in [i, j, k] order (k fastest)."""
    L = grid.resolution
    g = (np.arange(L) + 0.5) * grid.voxel
    X, Y, Z = np.meshgrid(g, g, g, indexing="ij")
    return grid.origin + np.stack([X, Y, Z], -1).reshape(-1, 3)


def share_volume_reference(raw: SdfGrid, smooth: SdfGrid, a, b, spheres=None) -> np.ndarray:
    """(L, L, L, 6) float32 visible shares (S_A rgb, S_B rgb) at the voxel centres (module doc,
    step 1): orientation from ``smooth``, the surface point from ``raw`` (same placement), 1
    outside the band or without spheres; ``a``, ``b``: ``render.shading.transfer.RelightLighting``."""
    from render.shading.transfer import visible_share

    L = raw.resolution
    out = np.ones((L ** 3, 6))
    if spheres is None or not len(spheres):
        return out.reshape(L, L, L, 6).astype(np.float32)
    x = voxel_centres(raw)
    g = sdf_gradient(smooth, x)
    gl = np.linalg.norm(g, axis=1, keepdims=True)
    ok = gl[:, 0] > 0
    n = g / np.where(gl > 0, gl, 1.0)
    d = raw.values.reshape(-1).astype(np.float64)
    xs = x - (d - VISIBILITY_LIFT_VOXELS * raw.voxel)[:, None] * n
    band = (np.abs(d) <= VISIBILITY_BAND_VOXELS * raw.voxel) & ok
    if band.any():
        out[band, :3] = visible_share(xs[band], n[band], a, spheres)
        out[band, 3:] = visible_share(xs[band], n[band], b, spheres)
    return out.reshape(L, L, L, 6).astype(np.float32)


def volume_sample(volume, origin, voxel: float, points) -> np.ndarray:
    """(P, C) trilinear sample of an (L, L, L, C) volume at world points (clamped to the edge texels)."""
    v = np.asarray(volume, np.float64)
    return np.stack([sdf_sample(SdfGrid(v[..., c].astype(np.float32), origin, voxel), points)
                     for c in range(v.shape[-1])], -1)


def apply_reference(rgb, depth, camera: Camera, smooth: SdfGrid, shares, a, b, strands=None, hair=None,
                    strand_weight: float = 1.0, **gain_kw) -> np.ndarray:
    """(H, W, 3) float32 (module doc, step 2): ``rgb`` times the gain at each pixel's world point
    where depth > 0 (the other pixels unchanged: black stays black): orientation = gradient of
    ``smooth`` there, the visible shares sampled from ``shares`` (same placement), the view from the
    point to the camera; ``gain_kw`` to ``render.shading.transfer.relight_gain``.  With ``strands``
    (``render.relight.strands.StrandColour``) and ``hair`` (the lightings (A, B) of the strand transfer): the
    gain blended towards ``render.shading.hair_transfer.hair_gain`` by the strand score there."""
    from render.shading.transfer import global_gain, relight_gain

    out = np.asarray(rgb, np.float64).copy()
    dep = np.asarray(depth, np.float64)
    m = dep > 0
    if m.any():
        x = frame_points(dep, camera)[m]
        v = camera.center - x
        v /= np.linalg.norm(v, axis=1, keepdims=True)
        sh = volume_sample(shares, smooth.origin, smooth.voxel, x)
        grad = sdf_gradient(smooth, x)
        g = relight_gain(x, grad, a, b, views=v, shares=(sh[:, :3], sh[:, 3:]), **gain_kw)
        if strands is not None:
            g = _strand_blend(g, x, unit_normals(grad), v, strands, hair, global_gain(a, b), gain_kw, strand_weight)
        out[m] *= g
    return out.astype(np.float32)


def unit_normals(grad) -> np.ndarray:
    """(P, 3) unit SDF gradients, 0 where shorter than ``render.shading.transfer.MIN_GRADIENT``."""
    from render.shading.transfer import MIN_GRADIENT

    g = np.asarray(grad, np.float64)
    n = np.linalg.norm(g, axis=1, keepdims=True)
    return np.where(n > MIN_GRADIENT, g / np.where(n > MIN_GRADIENT, n, 1.0), 0.0)


def _strand_blend(g, x, n, v, strands, hair, g_global, gain_kw, weight: float = 1.0) -> np.ndarray:
    """(P, 3) the surface gain ``g`` mixed towards the strand gain by ``weight`` x the strand score (apply
    pass); ``n``: unit shell normals (or 0)."""
    from render.relight.strands import field_sample
    from render.shading.hair_transfer import hair_gain
    from render.shading.transfer import FORWARD_G, MAX_GAIN, REGULARISE

    f = strands.field
    t, w = field_sample(f, x)
    on = weight * w > 0
    if not on.any():
        return g
    fit = volume_sample(strands.fit, f.origin, f.voxel, x[on])
    gh = hair_gain(t[on], n[on], v[on], fit[:, :3], fit[:, 3], hair[0], hair[1], g_global,
                   regularise=gain_kw.get("regularise", REGULARISE), max_gain=gain_kw.get("max_gain", MAX_GAIN),
                   forward_g=gain_kw.get("forward_g", FORWARD_G))
    w = np.clip(weight * w[on], 0.0, 1.0)[:, None]
    out = np.array(g, np.float64)
    out[on] = (1 - w) * out[on] + w * gh
    return out

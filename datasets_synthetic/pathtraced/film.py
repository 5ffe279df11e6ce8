"""Rays of a furrow camera through a Mitsuba scene: colour, the object's true matte, and z-depth.

**Colour and matte** (:func:`render_view`): every pixel (i, j) (OpenCV centre at (i, j)) draws its
samples uniformly over its square, [i - 0.5, i + 0.5] x [j - 0.5, j + 0.5]; a sample's ray leaves the
camera centre through that point of the image (through the inverse of the OpenCV lens when there is
one, :func:`undistort_normalized`), Mitsuba's ``path`` integrator returns its radiance, and a
primary intersection says whether the first surface it meets is the object (not the table, not the
room).  Samples are splatted with the film's reconstruction filter (Mitsuba's ``gaussian``, stddev 0.5
px, by default; ``box`` = plain pixel area) into one image block of

* ``room``: the radiance of every sample (the object, the table, the visible map);
* ``black``: the radiance of the samples whose first hit is the object, 0 for the others: the object
  premultiplied over black, as a held-out view of the evaluation captures;
* ``alpha``: the filtered fraction of samples whose first hit is the object: the true coverage matte
  (C_room = alpha F + (1 - alpha) B holds with F = black / alpha, sample for sample).

**Depth** (:func:`z_depth`): rays through an S x S grid inside each pixel (S = 1: the pixel centre
alone), z-depth = distance along the optical axis, not along the ray; a pixel's depth is the
nearest hit among its sub-rays (0 when none hits), so a needle a fifth of a pixel wide has depth where
it covers a sub-ray.  Pixel centres follow ``capture.camera`` (OpenCV: centre of pixel i at i;
Mitsuba's image block: pixel i spans [i, i + 1), so its positions are ``capture.camera.corner_from_cv``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from capture.camera import Camera, corner_from_cv, resample_pixel_coords
from capture.lens import Lens, undistort_pixels
from datasets_synthetic.pathtraced.runtime import load_mitsuba

#: Reconstruction filters of the film (Mitsuba plugin names).
FILTERS = ("gaussian", "box")
#: Samples traced per kernel launch (about 4 spp of a 640x480 view; bounds the JIT's memory).
WAVEFRONT = 1_228_800
#: Fixed-point iterations of the lens inversion (the OPENCV lens of the cases converges in < 10).
UNDISTORT_ITERATIONS = 20
#: Sub-rays per pixel side of the depth.
DEPTH_SUBSAMPLES = 3
#: Channels of the image block: room rgb, black rgb, coverage, filter weight.
_CHANNELS = 8


@dataclass(frozen=True)
class ViewImages:
    """One view's film.

    room: (H, W, 3) float32 linear radiance, everything the camera sees;
    black: (H, W, 3) float32 the object alone over black (premultiplied);
    alpha: (H, W) float32 true coverage of the object in [0, 1].
    """

    room: np.ndarray
    black: np.ndarray
    alpha: np.ndarray


def undistort_normalized(xd, yd, coeffs, iterations: int = UNDISTORT_ITERATIONS):
    """Distorted normalised image coordinates -> ideal ones under OpenCV's model (k1 k2 p1 p2 k3),
    by the fixed-point iteration of ``cv2.undistortPoints``.  Plain arithmetic: works on numpy and on
    Dr.Jit arrays alike (its numpy twin is ``capture.lens.undistort_pixels``, tests compare them)."""
    k1, k2, p1, p2, k3 = (float(c) for c in coeffs[:5])
    x, y = xd, yd
    for _ in range(iterations):
        r2 = x * x + y * y
        icdist = 1.0 / (1.0 + r2 * (k1 + r2 * (k2 + r2 * k3)))
        dx = 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
        dy = p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
        x, y = (xd - dx) * icdist, (yd - dy) * icdist
    return x, y


def _check_lens(lens: Lens | None) -> None:
    if lens is not None and (lens.fisheye or any(lens.coeffs[5:])):
        raise ValueError(f"path-traced captures take an OPENCV lens (k1 k2 p1 p2 k3), got {lens.source or lens.model}")


def _camera_rays(mi, dr, cam: Camera, lens: Lens | None, px, py):
    """Dr.Jit rays through corner-convention image positions (px, py) of ``cam`` (+ ``lens``)."""
    fx, fy = (dr.opaque(mi.Float, float(cam.K[i, i])) for i in (0, 1))
    cx, cy = (dr.opaque(mi.Float, float(v)) for v in corner_from_cv(cam.K[:2, 2]))
    skew = float(cam.K[0, 1])
    y = (py - cy) / fy
    x = (px - cx - skew * y) / fx
    if lens is not None:
        x, y = undistort_normalized(x, y, lens.coeffs)
    R = cam.world_from_cam[:3, :3]
    r = [[dr.opaque(mi.Float, float(R[a, b])) for b in range(3)] for a in range(3)]
    d = dr.normalize(mi.Vector3f(r[0][0] * x + r[0][1] * y + r[0][2], r[1][0] * x + r[1][1] * y + r[1][2],
                                 r[2][0] * x + r[2][1] * y + r[2][2]))
    o = mi.Point3f(*(dr.opaque(mi.Float, float(c)) for c in cam.center))
    return mi.RayDifferential3f(o, d)


def _object_hit(dr, scene, ray, table):
    """Bool: the first surface the ray meets is the object (any shape but the table)."""
    si = scene.ray_intersect(ray)
    hit = si.is_valid()
    if table is not None:
        mi = load_mitsuba()
        hit &= si.shape != mi.ShapePtr(table)
    return hit


def render_view(pscene, cam: Camera, spp: int, seed: int, lens: Lens | None = None, max_depth: int = 10,
                rfilter: str = "gaussian", progress=None) -> ViewImages:
    """The film of one view (module docstring) of ``pscene`` (``datasets_synthetic.pathtraced.scene.PathScene``)
    at ``spp`` samples per pixel, seeded by ``seed`` (an int < 2^32)."""
    mi = load_mitsuba()
    import drjit as dr

    _check_lens(lens)
    if rfilter not in FILTERS:
        raise ValueError(f"filter must be one of {', '.join(FILTERS)}, got {rfilter!r}")
    if spp < 1:
        raise ValueError(f"spp must be >= 1, got {spp}")
    W, H = cam.width, cam.height
    per_pass = int(max(1, min(spp, WAVEFRONT // (W * H))))
    integrator = mi.load_dict({"type": "path", "max_depth": int(max_depth)})
    block = mi.ImageBlock([W, H], [0, 0], _CHANNELS, mi.load_dict({"type": rfilter}), border=False)
    block.clear()
    sampler = mi.load_dict({"type": "independent"})
    done, k = 0, 0
    while done < spp:
        n_pass = min(per_pass, spp - done)
        n = W * H * n_pass
        sampler.seed(dr.opaque(mi.UInt32, (int(seed) * 7919 + k) & 0xFFFFFFFF), n)
        pix = dr.arange(mi.UInt32, n) // n_pass
        off = sampler.next_2d()
        px, py = mi.Float(pix % W) + off.x, mi.Float(pix // W) + off.y
        ray = _camera_rays(mi, dr, cam, lens, px, py)
        obj = _object_hit(dr, pscene.scene, ray, pscene.table)
        L, _, _ = integrator.sample(pscene.scene, sampler, ray, None, True)
        Lo = dr.select(obj, L, 0.0)
        block.put(mi.Point2f(px, py), [L.x, L.y, L.z, Lo.x, Lo.y, Lo.z, dr.select(obj, 1.0, 0.0), mi.Float(1.0)])
        sampler.schedule_state()
        dr.eval(block.tensor())
        del L, Lo, obj, ray, off, px, py, pix
        done += n_pass
        k += 1
        if progress is not None:
            progress(n_pass)
    t = np.array(block.tensor(), np.float64)
    w = np.maximum(t[..., 7:8], 1e-12)
    return ViewImages((t[..., 0:3] / w).astype(np.float32), (t[..., 3:6] / w).astype(np.float32),
                      np.clip(t[..., 6] / w[..., 0], 0.0, 1.0).astype(np.float32))


def subpixel_positions(cam: Camera, samples: int) -> np.ndarray:
    """(H, W, S*S, 2) OpenCV image positions of an S x S grid inside every pixel (S = 1: the centres)."""
    S = int(samples)
    fine = resample_pixel_coords(cam.scaled(S).pixel_grid(), 1.0 / S)  # (H S, W S, 2)
    H, W = cam.height, cam.width
    return fine.reshape(H, S, W, S, 2).transpose(0, 2, 1, 3, 4).reshape(H, W, S * S, 2)


def z_depth(pscene, cam: Camera, lens: Lens | None = None, samples: int = DEPTH_SUBSAMPLES,
            with_table: bool = True) -> np.ndarray:
    """(H, W) float32 z-depth (metres, 0 = no hit) of the nearest surface among each pixel's sub-rays
    (module docstring); ``with_table`` False counts the object only (the held-out views)."""
    mi = load_mitsuba()
    import drjit as dr

    _check_lens(lens)
    uv = subpixel_positions(cam, samples).reshape(-1, 2)
    if lens is not None:
        uv = undistort_pixels(uv, cam.K, lens)
    rays = cam.pixel_rays(uv) @ cam.world_from_cam[:3, :3].T  # z = 1 in the camera: |d| = 1 / cos
    norm = np.linalg.norm(rays, axis=1)
    d = (rays / norm[:, None]).astype(np.float32)
    o = mi.Point3f(*(float(c) for c in cam.center))
    si = pscene.scene.ray_intersect(mi.Ray3f(o, mi.Vector3f(d[:, 0], d[:, 1], d[:, 2])))
    hit = si.is_valid()
    if not with_table and pscene.table is not None:
        hit &= si.shape != mi.ShapePtr(pscene.table)
    t = dr.select(hit, si.t, 0.0)
    dr.eval(t)
    z = np.array(t, np.float64) / norm  # t along the unit ray -> distance along the optical axis
    z = np.where(np.isfinite(z) & (z > 0), z, np.inf).reshape(cam.height, cam.width, -1).min(axis=2)
    return np.where(np.isfinite(z), z, 0.0).astype(np.float32)

"""A moving camera's plate samples (capture.plate_reproject.gather_samples) as one compiled loop (numba).

``gather_samples`` looks up, for every background hypothesis point of a view's pixels, what one
other view saw there: it projects the points, keeps those whose four bilinear taps are all
confidently background and whose depth agrees with the hypothesis, and reads the colour there.
In numpy that is some twenty temporaries of the points per source (projection, four taps, their
masks, the depth lookup, the bilinear weights), and a view consults eight sources for up to three
hypotheses: 0.9 s a 1280x960 view, the whole of the panorama plate stage (docs/speed.md, round 17).
:func:`gather_kernel` does each point in one pass, without temporaries.

The arithmetic is the numpy path's, operation for operation:

* the rotation ``p @ R.T + t`` as this machine's OpenBLAS sums it (capture.extent_kernel._rotate:
  the same world points bit for bit here; another BLAS may round the last bit otherwise);
* the projection ``K[0,0] x/z + K[0,1] y/z + K[0,2]`` and ``K[1,1] y/z + K[1,2]`` (capture.camera.Camera.project);
* the taps ``floor`` of the row and column and their weights ``(1 - t, t)``, multiplied row first
  (capture.sampling.linear_taps), the colour summed over the corners in row-major order in float64
  (capture.sampling._weighted), then times the gain ratio and stored in float32;
* the depth at the nearest pixel ``floor(x + 0.5)``; the far test compares in float32, as numpy 2
  compares a float32 array with a Python float.

tests/capture/test_plate_reproject_kernel.py compares it with the numpy reference on random points
over real-sized views (every kind), sample for sample.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, types
from numba.extending import overload

from capture.extent_kernel import _rotate
from capture.plate_mode_kernel import sorted_insert, sorted_median

#: Hypothesis kinds (capture.plate_reproject.background_points).
KINDS = {"plane": 0, "room": 1, "far": 2}


#: float16 -> float32 for every bit pattern (exact): numba reads no float16, so a half-float image is
#: read as its uint16 bits through this table.
F16_TABLE = np.arange(65536, dtype=np.uint16).view(np.float16).astype(np.float32)


def texel(img, lut, r, c, ch):
    """A texel of ``img`` as float64: a uint16 image holds a float16 image's bits, read through ``lut``
    (F16_TABLE); a float32 / float64 image is read as it is.  Chosen by the image's type when the
    kernel is compiled (:func:`_texel`), not by a reader function passed in: numba keys a function
    argument by its type, which differs in every process, so the kernel that took one was compiled
    again on every run (0.8-0.95 s of each `furrow model`) and its on-disk cache grew an entry each time."""
    if img.dtype == np.uint16:
        return np.float64(lut[img[r, c, ch]])
    return np.float64(img[r, c, ch])


@overload(texel, jit_options={"cache": True, "nogil": True})
def _texel(img, lut, r, c, ch):
    if img.dtype == types.uint16:
        return lambda img, lut, r, c, ch: np.float64(lut[img[r, c, ch]])
    return lambda img, lut, r, c, ch: np.float64(img[r, c, ch])


@njit(cache=True, nogil=True)
def _blown(linear, lut, r0, c0, clip):
    """Whether a channel of one of the four taps at (r0, c0) reaches ``clip``."""
    for r in range(r0, r0 + 2):
        for c in range(c0, c0 + 2):
            for ch in range(3):
                if texel(linear, lut, r, c, ch) >= clip:
                    return True
    return False


@njit(cache=True, nogil=True, error_model="numpy")
def gather_kernel(points, kind, R, t, K, background, depth, linear, lut, ratio, far_z, depth_tol, clip, out):
    """Fill ``out`` (N, 3) float32 (NaN on entry) with the colour view j saw at world ``points`` (N, 3)
    float64 where the sample counts (module docstring).  ``kind``: KINDS; ``R`` (3, 3), ``t`` (3,):
    j's cam_from_world; ``K`` (3, 3); ``background`` (H, W) bool, ``depth`` (H, W) float32, ``linear``
    (H, W, 3) read by :func:`texel` (a float16 image as its uint16 bits, through ``lut``);
    ``ratio`` (3,) g_j / g_i; ``far_z`` float32 (FAR_MARGIN x focus_far); ``clip``: a sample with a tap
    at or above it in a channel does not count (inf: every sample counts; capture.plate_reproject.drops_clipped)."""
    H, W = background.shape
    for n in range(points.shape[0]):
        p0, p1, p2 = points[n, 0], points[n, 1], points[n, 2]
        x = _rotate(p0, p1, p2, R, t, 0)
        y = _rotate(p0, p1, p2, R, t, 1)
        z = _rotate(p0, p1, p2, R, t, 2)
        if not z > 0:
            continue
        xn = x / z
        yn = y / z
        u = K[0, 0] * xn + K[0, 1] * yn + K[0, 2]
        v = K[1, 1] * yn + K[1, 2]
        if not (math.isfinite(u) and math.isfinite(v)):
            continue
        fr = math.floor(v)
        fc = math.floor(u)
        if fr < 0.0 or fr + 1.0 > H - 1 or fc < 0.0 or fc + 1.0 > W - 1:
            continue
        r0 = int(fr)
        c0 = int(fc)
        if not (background[r0, c0] and background[r0, c0 + 1] and background[r0 + 1, c0]
                and background[r0 + 1, c0 + 1]):
            continue
        rn = min(max(int(math.floor(v + 0.5)), 0), H - 1)
        cn = min(max(int(math.floor(u + 0.5)), 0), W - 1)
        d32 = depth[rn, cn]
        d = np.float64(d32)
        if kind == 2:
            if not (d32 <= 0 or d32 > far_z):
                continue
        elif kind == 0:
            if not (d > 0 and abs(d - z) <= depth_tol * z):
                continue
        elif not (d <= 0 or abs(d - z) <= depth_tol * z):
            continue
        if clip < math.inf and _blown(linear, lut, r0, c0, clip):
            continue
        ty = v - fr
        tx = u - fc
        w00 = (1.0 - ty) * (1.0 - tx)
        w01 = (1.0 - ty) * tx
        w10 = ty * (1.0 - tx)
        w11 = ty * tx
        for c in range(3):
            s = 0.0 + texel(linear, lut, r0, c0, c) * w00
            s = s + texel(linear, lut, r0, c0 + 1, c) * w01
            s = s + texel(linear, lut, r0 + 1, c0, c) * w10
            s = s + texel(linear, lut, r0 + 1, c0 + 1, c) * w11
            out[n, c] = np.float32(s * ratio[c])


@njit(cache=True, nogil=True)
def median_count(s, med, count):
    """Per pixel n of the samples ``s`` (K, N, 3) float32 (NaN: none): ``count[n]`` the sources with a
    sample (channel 0 finite) and ``med[n]`` (3,) float32 the median of each channel's finite samples,
    0.5 x (lo + hi) of the sorted values in float32 as capture.plate_reproject.nan_median (NaN without
    any).  One pass a pixel with an insertion sort of at most K values, instead of numpy's sort of the
    whole (K, N, 3) block and its masks (capture.plate_reproject.MEDIAN_COMPILED)."""
    K, N = s.shape[0], s.shape[1]
    buf = np.empty(K, np.float32)
    for p in range(N):
        n_have = 0
        for k in range(K):
            if np.isfinite(s[k, p, 0]):
                n_have += 1
        count[p] = n_have
        for c in range(3):
            m = 0
            for k in range(K):
                v = s[k, p, c]
                if np.isfinite(v):
                    m = sorted_insert(buf, m, v)
            med[p, c] = np.nan if m == 0 else sorted_median(buf, m)

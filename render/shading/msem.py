"""Multi-scale environment map (MSEM) for non-uniform roughness (docs/methods.md §2, seed 000).

A cube of s^3 RGB voxels. Voxel t (centre in (-1, 1)^3, index (i, j, k) = (x, y, z)) holds the
normalised Phong convolution of the environment around the direction t^ = t / |t| with the
exponent Lambda = g(|t|) (Eq. 8-9, 13)::

    F(t) = sum_w L(w) max(0, t^.w)^Lambda Omega(w) / sum_w max(0, t^.w)^Lambda Omega(w)

(the thesis sums over the pixels of a uniform dome; we weight equirect pixels by their solid
angle Omega, which is the same integral). Rendering looks up t = r * lambda (r the reflection
vector, lambda in (0, 1] the smoothness) with trilinear filtering: ``msem_lookup`` (numpy) and
``msem_radiance`` in ``render/shaders/shading_msem.glsl`` (3-D texture).

g(|t|) (Eq. 11-13) with I intensity levels and s voxels across::

    Lambda = -ln(I) / ln(cos(atan(2 / (|t| s)))) = 2 ln(I) / ln(1 + (2 / (|t| s))^2)

written in the second form (no cos/atan round trip); it tends to 0 as |t| -> 0 (the lobe
becomes the whole hemisphere) and g(0) is defined as 0: that is the |t| -> 0 clamp.

Builds:
* :func:`msem_brute` — the reference: the sum above over every pixel of the full map, for any
  set of voxels (used on samples of voxels; float64).
* :func:`msem_build` — fast: the voxel radius is quantised into ``levels`` shells; for each shell
  the convolved map is computed on an equirect grid whose resolution follows the lobe width
  (a pyramid of area-resampled maps), with weights below ``th`` (relative to the lobe peak)
  dropped (the paper's threshold, Eq. 14); every voxel then interpolates bilinearly in
  direction and linearly between its two shells. Rotation about +z is a cyclic column shift,
  so each output row is a sum of circular cross-correlations of a narrow band of source rows,
  done with real FFTs.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from capture.sampling import cell_centres, from_texcoord, sample_grid, to_texcoord
from render.shading.envmap import (
    EnvMap,
    dir_to_uv,
    equirect_nearest,
    pixel_centre_azimuth,
    pixel_centre_polar,
    pixel_solid_angles,
    sample_equirect,
)
from render.shading.lights import LUMA

#: Intensity resolution I of Eq. 11-13 (8-bit display: 256 levels).
MSEM_INTENSITY_LEVELS = 256
#: The per-shell grid has about this many pixels per lobe width 1/sqrt(Lambda).
MSEM_OVERSAMPLE = 2.0
#: Smallest per-shell grid height.
MSEM_MIN_HEIGHT = 16
#: Default cap of the per-shell grid height (256 rows: 128^3 from a 1024x512 map in ~6 s with
#: mean error 0.3/256 vs the full-resolution brute force; 512 rows is 5x slower, 5x more exact).
MSEM_MAX_HEIGHT = 256
#: Output rows processed together (memory bound: rows x band x W complex).
MSEM_ROW_BLOCK = 64


def msem_lambda(radius, s: int, levels: int = MSEM_INTENSITY_LEVELS) -> np.ndarray:
    """g(|t|) of Eq. 13 (stable form), elementwise; g(0) = 0 (the |t| -> 0 limit)."""
    r = np.abs(np.asarray(radius, np.float64))
    # ln(1 + x^2), x = 2 / (|t| s), without overflow for tiny |t| (it grows like 2 ln x)
    lx = np.log(2.0 / (np.where(r > 0, r, 1.0) * s))
    ln1px2 = np.where(lx > 0, 2 * lx + np.log1p(np.exp(-2 * np.abs(lx))), np.log1p(np.exp(2 * np.minimum(lx, 0))))
    return np.where(r > 0, 2.0 * np.log(levels) / ln1px2, 0.0)


def voxel_centres(s: int) -> np.ndarray:
    """(s, s, s, 3) float64 voxel centres t in (-1, 1)^3, indexed [i, j, k] = (x, y, z)."""
    c = cell_centres(s, -1.0, 1.0)
    return np.stack(np.meshgrid(c, c, c, indexing="ij"), -1)


def phong_weights(cosang, lam):
    """max(0, c)^Lambda, elementwise, no underflow warnings; Lambda = 0 gives the gate."""
    with np.errstate(divide="ignore", under="ignore", invalid="ignore"):
        return np.where(cosang > 0, np.exp(lam * np.log(np.where(cosang > 0, cosang, 1.0))), 0.0)


def msem_brute(env: EnvMap, s: int, index) -> np.ndarray:
    """Reference F for voxels ``index`` ((N, 3) int, i j k): the full pixel sum. (N, 3) float64."""
    idx = np.atleast_2d(np.asarray(index, np.int64))
    t = to_texcoord(idx, s) * 2.0 - 1.0
    rad = np.linalg.norm(t, axis=1)
    lam = msem_lambda(rad, s)
    tn = t / rad[:, None]
    d = env.pixel_directions().reshape(-1, 3)
    om = env.pixel_solid_angles().reshape(-1)
    L = env.data.reshape(-1, 3).astype(np.float64)
    out = np.empty((len(idx), 3))
    for a in range(0, len(idx), 64):
        c = tn[a:a + 64] @ d.T  # (n, P)
        lg = np.where(c > 0, np.log(np.where(c > 0, c, 1.0)), -np.inf) * lam[a:a + 64, None]
        lg -= lg.max(1, keepdims=True)  # the largest weight is 1: no underflow of the sum
        w = np.exp(lg) * om
        out[a:a + 64] = (w @ L) / w.sum(1, keepdims=True)
    return out


def _shell_height(lam: float, src_h: int) -> int:
    sigma = 1.0 / np.sqrt(max(lam, 1.0))
    h = int(np.ceil(MSEM_OVERSAMPLE * np.pi / sigma))
    h = 1 << int(np.ceil(np.log2(max(h, 1))))  # powers of two: a small pyramid, shared levels
    return int(min(src_h, max(MSEM_MIN_HEIGHT, h)))


def convolve_phong(src: EnvMap, lam: float, th: float = 0.0) -> np.ndarray:
    """(h, 2h, 3) the normalised cos^lam convolution of ``src`` at its own pixel centres, weights
    below ``th`` of the peak dropped (FFT over azimuth, band of source rows)."""
    # angular reach of the lobe: cos^lam(alpha) = th; the hemisphere gate caps it at pi/2
    if th > 0 and lam > 0:
        alpha = min(float(np.arccos(np.clip(th ** (1.0 / lam), -1.0, 1.0))), np.pi / 2)
        cos_min = np.cos(alpha)
    else:
        alpha, cos_min = np.pi / 2, 0.0

    def kernel(c):
        k = phong_weights(c, lam)
        return np.where(c >= cos_min, k, 0.0) if cos_min > 0 else k

    return convolve_zonal(src, kernel, alpha, normalise=True)


def convolve_zonal(src: EnvMap, kernel, reach: float, normalise: bool) -> np.ndarray:
    """(H, W, 3) sum_w L(w) kernel(x.w) Omega(w) at every pixel centre x of ``src`` (divided by
    sum_w kernel Omega when ``normalise``). ``kernel`` maps cosines to weights and must vanish
    beyond the angle ``reach``. Rotation about +z is a column shift, so each output row is a sum
    over a band of source rows of circular cross-correlations (real FFTs)."""
    H, W = src.height, src.width
    th_c = pixel_centre_polar(H)
    om = pixel_solid_angles(H)[:, 0]
    band = int(min(H - 1, np.ceil(min(reach, np.pi) / (np.pi / H)) + 1))
    cos_d = np.cos(np.arange(W) * (2 * np.pi / W))
    FL = np.fft.rfft(src.data.astype(np.float64), axis=1)  # (H, W/2+1, 3)
    out = np.empty((H, W, 3))
    offs = np.arange(-band, band + 1)
    for r0 in range(0, H, MSEM_ROW_BLOCK):
        rows = np.arange(r0, min(H, r0 + MSEM_ROW_BLOCK))
        srows = rows[:, None] + offs[None, :]  # (R, B)
        valid = (srows >= 0) & (srows < H)
        sr = np.clip(srows, 0, H - 1)
        a = np.cos(th_c[rows])[:, None] * np.cos(th_c[sr])
        b = np.sin(th_c[rows])[:, None] * np.sin(th_c[sr])
        k = kernel(a[..., None] + b[..., None] * cos_d)  # (R, B, W)
        k = k * (om[sr] * valid)[..., None]
        FK = np.fft.rfft(k, axis=-1)  # (R, B, W/2+1)
        num = np.fft.irfft(np.einsum("rbf,rbfc->rfc", np.conj(FK), FL[sr]), n=W, axis=1)
        if normalise:
            num /= FK[..., 0].real.sum(1)[:, None, None]  # sum of weights per output row
        out[rows] = num
    return out


@dataclass(frozen=True)
class MsemBuild:
    """volume: (s, s, s, 3) float32 F indexed [i, j, k]; seconds: build time; shells: number of
    radius shells tabulated; heights: per-shell grid heights; direct: voxels summed directly."""

    volume: np.ndarray
    seconds: float
    shells: int
    heights: tuple
    direct: int


def _reach(lam, th) -> np.ndarray:
    """Angle at which cos^lam falls to th (the hemisphere gate caps it at pi/2)."""
    lam = np.asarray(lam, np.float64)
    with np.errstate(divide="ignore"):
        c = np.where(lam > 0, th ** (1.0 / np.where(lam > 0, lam, 1.0)), 0.0)
    return np.minimum(np.arccos(np.clip(c, -1.0, 1.0)), np.pi / 2)


def msem_direct(env: EnvMap, dirs, lam, th: float) -> np.ndarray:
    """F at unit ``dirs`` (N,3) with exponents ``lam`` (N,), summing only the source pixels within
    the reach of weight ``th`` (a window of rows and columns around each direction; whole rows
    when the window reaches a pole). (N, 3) float64. Exactly the brute-force quadrature with
    weights below th dropped (the paper's Eq. 14)."""
    dirs = np.asarray(dirs, np.float64)
    lam = np.asarray(lam, np.float64)
    H, W = env.height, env.width
    OM = env.pixel_solid_angles()[:, 0]
    L = env.data.astype(np.float64)
    dth, dph = np.pi / H, 2 * np.pi / W
    alpha = _reach(lam, th)
    cos_a = np.cos(alpha)
    uv = dir_to_uv(dirs)
    i0, j0 = equirect_nearest(uv, H)
    R = np.ceil(alpha / dth).astype(np.int64) + 1
    lo, hi = i0 - R, i0 + R
    polar = (lo < 0) | (hi > H - 1)
    smin = np.sin(np.minimum(np.clip(lo, 0, H - 1) + 0.5, H - 0.5 - np.clip(hi, 0, H - 1)) * dth)
    smin = np.maximum(smin, 1e-12)
    C = np.ceil(np.arcsin(np.minimum(1.0, np.sin(alpha) / smin)) / dph).astype(np.int64) + 1
    polar |= 2 * C + 1 >= W
    out = np.empty((len(dirs), 3))
    # 1 - t.w = 2 sin^2(dtheta / 2) + sin(theta_t) sin(theta_s) 2 sin^2(dphi / 2): separable in
    # the window's rows and columns, and free of the cancellation of 1 - dot near the peak
    th_t = np.arctan2(np.hypot(dirs[:, 0], dirs[:, 1]), dirs[:, 2])
    ph_t = np.arctan2(dirs[:, 1], dirs[:, 0])
    th_s = pixel_centre_polar(H)
    ph_s = pixel_centre_azimuth(W)
    Lf = L.reshape(-1, 3)
    # windows near a pole: the band of rows (clipped) times every column
    C = np.where(polar, -1, C)
    key = R * 100000 + C
    for k in np.unique(key):
        grp = np.nonzero(key == k)[0]
        r_, c_ = int(R[grp[0]]), int(C[grp[0]])
        dr = np.arange(-r_, r_ + 1)
        full = c_ < 0
        dc = np.arange(W) if full else np.arange(-c_, c_ + 1)
        step = max(1, 2_000_000 // (dr.size * dc.size))
        for a in range(0, grp.size, step):
            g = grp[a:a + step]
            rows = i0[g, None] + dr[None]  # (n, R')
            valid = (rows >= 0) & (rows < H)
            rows = np.clip(rows, 0, H - 1)
            cols = np.broadcast_to(dc[None], (len(g), dc.size)) if full else (j0[g, None] + dc[None]) % W
            A = 2 * np.sin((th_t[g, None] - th_s[rows]) / 2) ** 2
            B = np.sin(th_t[g, None]) * np.sin(th_s[rows])
            E = 2 * np.sin((ph_t[g, None] - ph_s[cols]) / 2) ** 2
            x = A[:, :, None] + B[:, :, None] * E[:, None, :]  # 1 - cos, (n, R', C')
            keep = (x <= (1 - cos_a[g])[:, None, None]) & (x < 1) & valid[:, :, None]
            with np.errstate(divide="ignore", invalid="ignore", under="ignore"):
                w = np.where(keep, np.exp(lam[g, None, None] * np.log1p(-np.minimum(x, 1.0))), 0.0)
            w *= OM[rows][:, :, None]
            Lg = Lf[rows[:, :, None] * W + cols[:, None, :]]  # (n, R', C', 3)
            out[g] = np.einsum("nrc,nrcj->nj", w, Lg) / w.sum((1, 2))[:, None]
    return out


#: Voxels whose lobe reaches at most this many source rows (weight th) are "sharp": the shell
#: table would interpolate between pixels there, so they are summed directly at their own
#: direction on the full-resolution map (no tabulation error) -- unless the source is nearly
#: flat around them: when the radiance range (max - min, any channel) within the reach plus
#: MSEM_RANGE_MARGIN pixels is below MSEM_RANGE_TOL / 256 of the white level, the table value
#: (a weighted mean of the same pixels) is within that bound of the direct sum and is kept.
MSEM_DIRECT_MAX_ROWS = 8
MSEM_RANGE_MARGIN = 3
MSEM_RANGE_TOL = 64.0


def _local_range(env: EnvMap, half_rows: int) -> np.ndarray:
    """(H, W) max over channels of (max - min) radiance over every pixel within about
    ``half_rows`` rows of angular distance: a window of 2 half_rows + 1 rows and, in row i,
    2 c_i + 1 columns with c_i = half_rows / sin(theta) (wrap in u; whole rows near the poles)."""
    from scipy.ndimage import maximum_filter1d, minimum_filter1d

    H, W = env.height, env.width
    d = env.data
    hi = maximum_filter1d(d, 2 * half_rows + 1, axis=0, mode="nearest")
    lo = minimum_filter1d(d, 2 * half_rows + 1, axis=0, mode="nearest")
    out = np.empty((H, W))
    th = pixel_centre_polar(H)
    # the window's rows reach theta +- half_rows rows: use the smallest sin(theta) in it
    smin = np.sin(np.clip(np.minimum(th, np.pi - th) - half_rows * np.pi / H, 0, None))
    for i in range(H):
        c = W if smin[i] <= 0 else int(np.ceil(half_rows / smin[i])) + 1
        if 2 * c + 1 >= W:
            out[i] = (hi[i].max(0) - lo[i].min(0)).max()
        else:
            out[i] = (maximum_filter1d(hi[i], 2 * c + 1, axis=0, mode="wrap")
                      - minimum_filter1d(lo[i], 2 * c + 1, axis=0, mode="wrap")).max(-1)
    return out


def msem_build(env: EnvMap, s: int, th: float = 0.001, levels: int | None = None,
               max_height: int | None = None, range_tol: float | None = MSEM_RANGE_TOL) -> MsemBuild:
    """Fast MSEM (see module doc). All voxels up to rho_max = 1 + 2 sqrt(3) / s interpolate
    ``levels`` radius shells (default max(9, s // 8 + 1)), each tabulated on a grid of at most
    ``max_height`` rows (default MSEM_MAX_HEIGHT); sharp voxels near radiance edges are then
    replaced by the direct sum (see MSEM_DIRECT_MAX_ROWS; ``range_tol=None``: every sharp voxel
    direct; ``range_tol=inf``: none, table only). Corner voxels beyond rho_max, which no lookup with |t| <= 1
    reaches, hold the bilinear source radiance."""
    t0 = time.perf_counter()
    s = int(s)
    M = max(2, int(levels) if levels else max(9, s // 8 + 1))
    cap = min(env.height, int(max_height) if max_height else MSEM_MAX_HEIGHT)
    rho_max = 1.0 + np.sqrt(3.0) * 2.0 / s
    t = voxel_centres(s).reshape(-1, 3)
    rad = np.linalg.norm(t, axis=1)
    lam_v = msem_lambda(rad, s)
    tn = t / rad[:, None]
    corner = rad > rho_max
    inside = np.nonzero(~corner)[0]
    vol = np.empty((len(t), 3))
    if corner.any():
        vol[corner] = env.sample(tn[corner])
    rho = np.linspace(0.0, rho_max, M)
    lam = msem_lambda(rho, s)
    pyramid: dict[int, EnvMap] = {}
    heights = []
    uv = dir_to_uv(tn[inside])
    x = np.clip(rad[inside] / rho_max * (M - 1), 0, M - 1)
    m0 = np.minimum(np.floor(x).astype(np.int64), M - 2)
    w = np.clip(x - m0, 0.0, 1.0)[:, None]
    prev = None
    for m in range(M - 1):
        k = m0 == m
        if not k.any():
            prev = None
            continue
        pair = []
        for mm in (m, m + 1):
            if prev is not None and prev[0] == mm:
                pair.append(prev[1])
                continue
            h = _shell_height(lam[mm], cap)
            if h not in pyramid:
                pyramid[h] = env if h == env.height else env.resized(h)
            pair.append(convolve_phong(pyramid[h], lam[mm], th))
            heights.append(h)
        prev = (m + 1, pair[1])
        vol[inside[k]] = sample_equirect(pair[0], uv[k]) * (1 - w[k]) + sample_equirect(pair[1], uv[k]) * w[k]
    # sharp voxels near edges: direct sums
    dth = np.pi / env.height
    sharp = ~corner & (_reach(lam_v, th) / dth <= MSEM_DIRECT_MAX_ROWS)
    if range_tol is not None and np.isinf(range_tol):
        sel = np.zeros(0, np.int64)
    elif range_tol is not None and sharp.any():
        rng_map = _local_range(env, MSEM_DIRECT_MAX_ROWS + 1 + MSEM_RANGE_MARGIN)
        uvs = dir_to_uv(tn[sharp])
        i0 = np.clip((uvs[:, 1] * env.height).astype(np.int64), 0, env.height - 1)
        j0 = np.clip((uvs[:, 0] * env.width).astype(np.int64), 0, env.width - 1)
        flat = rng_map[i0, j0] * 256.0 / white_level(env) <= range_tol
        sel = np.nonzero(sharp)[0][~flat]
    else:
        sel = np.nonzero(sharp)[0]
    if sel.size:
        vol[sel] = msem_direct(env, tn[sel], lam_v[sel], th)
    return MsemBuild(vol.reshape(s, s, s, 3).astype(np.float32), time.perf_counter() - t0,
                     len(heights), tuple(heights), int(sel.size))


def msem_lookup(volume: np.ndarray, r, smoothness) -> np.ndarray:
    """Trilinear lookup of an MSEM at t = r * smoothness (r unit (N,3), smoothness (N,) in
    [0, 1]); clamp-to-edge like the GL texture. (N, 3) float64."""
    vol = np.asarray(volume, np.float64)
    s = vol.shape[0]
    t = np.asarray(r, np.float64) * np.asarray(smoothness, np.float64)[..., None]
    return sample_grid(vol, from_texcoord((t + 1.0) / 2.0, s), "linear", "clamp")


def msem_texture(ctx, volume: np.ndarray):
    """moderngl RGB32F 3-D texture (LINEAR, clamp) of ``volume`` [i, j, k] for shading_msem.glsl.
    The caller releases it."""
    import moderngl

    v = np.ascontiguousarray(np.transpose(np.asarray(volume, np.float32), (2, 1, 0, 3)))  # z, y, x
    s = volume.shape[0]
    tex = ctx.texture3d((s, s, s), 3, v.tobytes(), dtype="f4")
    tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
    tex.repeat_x = tex.repeat_y = tex.repeat_z = False
    return tex


def white_level(env: EnvMap, percentile: float = 99.0) -> float:
    """The map's 'white' for error units: the given percentile of the pixel luminance. Errors
    are reported in 1/256 of it (the thesis used 8-bit maps, 256 levels)."""
    lum = env.data.astype(np.float64) @ LUMA
    return float(np.percentile(lum, percentile))

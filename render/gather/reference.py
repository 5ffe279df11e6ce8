"""Numpy reference (float64) of the ``gather`` method: a z-buffer of splatted RGB-D points gives
every pixel of the new view a depth, and its colour is gathered from the two nearest kept
views with soft visibility (the GLSL is ``render/shaders/gather_*.glsl``).

Per frame, for an eye E (docs/methods.md §1.9; measured in docs/novel_views.md):

1. **Depth** (:func:`front_depth`): the points of the ``k_depth`` kept cameras nearest to E in
   viewing angle (``render.points.reference.nearest_views``) are splatted into E in
   ``splat_px`` x ``splat_px``-pixel splats; a pixel's depth is the nearest splatted z, and a
   pixel no splat covers stays empty (this is the frame's coverage).  With a model that kept
   which depth the capture measured (volume.rgbz.measured_depth) and ``measured_first``, the
   measured points win: a pixel takes the nearest splatted z of the geometry's fill (the fused
   surface written into the pixels nothing was measured at, volume.rgbz) only where no measured
   point lands (:func:`measured_first_depth`).  The fill lies on the fused surface, which wraps a
   conifer's crown in front of its trunk: drawn in one z-buffer it hid the trunk the photos see
   through the needles (docs/novel_views.md, "Measured depth first").  Last
   (:func:`fill_pinholes`), a pixel no splat covers whose four edge neighbours all have a depth
   within ``pinhole_spread_m`` of each other takes their mean: the 2 x 2 splats of a surface seen
   from 10-20 degrees away leave single-pixel gaps, which a composite over white shows as specks.
2. **Colour** (:func:`gather`): the pixel's point X (its centre at that depth) is projected
   into the ``k_blend`` nearest cameras; each gives its colour image resampled at the
   projection (bilinear by default, capture.sampling.sample_image; Catmull-Rom bicubic,
   :func:`cubic`, as an option: the photos' own anti-aliasing and strand fringes are kept, where
   a 2 x 2 splat repeats one texel), with weight (1 / angle) x visibility.  Visibility is soft
   (Soft 3D, Penner & Zhang 2017): exp(-(d - z)^2 / 2 sigma^2) for the camera's depth d at the
   nearest texel and X's depth z in that camera, never below ``vis_floor`` -- an occluded or
   unmeasured camera still adds a little of what it saw there, so the pixels no camera sees
   (23-60 % of fur at 20-degree spacing, issue 11) get the consensus of the two views instead
   of the one view's occluder.  A pixel that no blend camera's image contains is left empty.

3. **Second layer** (a model with a matte and ``back_gap_m`` > 0; :func:`back_depth`,
   :func:`under_back`): per pixel with a splatted front depth, the farthest splatted point of the same
   cameras, where it lies more than ``back_gap_m`` behind it, gets its colour and alpha gathered like the front's and is
   composited under a drawn front (alpha > 0), as far as the kept views see it solid and the front
   not (both measured from ``back_solid`` up; :func:`under_back`).  A conifer's needle
   in front of its trunk gathers the kept views' partial alpha at the needle's point, where parallax
   has put the trunk elsewhere; the second layer puts the trunk back behind it (docs/novel_views.md,
   "The trunk through the needles").  The frame's depth stays the front's.

**Alpha** (a model with a matte, ``volume.model.RgbzImages.alpha``): the views' colours are
premultiplied by their alpha (:func:`premultiply`) and the alpha is resampled with the same
filter, both blended with the same weights and divided by the weight sum: a fringe pixel gets a
partial alpha and the strand's colour, not the background.  A pixel whose blended alpha is 0 is
left empty.  Without a matte every drawn pixel is opaque and the colour is exactly the blend of
the straight colours.

Eye on a kept camera: that camera takes (almost) all the weight (1 / angle) and its resampled
colour at its own pixel centres is the photo.  One camera: it is the only blend camera.  An
empty model (no depth anywhere): an empty frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from capture.camera import Camera
from capture.sampling import sample_image
from render.gather import alpha_mass as am
from render.gather.fine_depth import use_fine
from render.points import reference as pr

#: Colour resampling filters (GatherConfig.resample).
RESAMPLERS = ("cubic", "linear")
#: GatherConfig.alpha_mass's modes.
ALPHA_MASS_MODES = ("auto", "on", "off")
#: Catmull-Rom: the Keys cubic convolution kernel with a = -0.5 (interpolating, exact on
#: quadratics).
CUBIC_A = -0.5


@dataclass(frozen=True)
class GatherConfig:
    """Constants of the gather method (shared with its GLSL as #defines)."""

    k_depth: int = 2
    """Kept cameras (nearest in viewing angle) whose points are splatted for the depth (4 adds
    the outer views' fringes to the silhouette: -0.1 dB, lower SSIM and sharpness)."""
    splat_px: int = 2
    """Side of the depth splats in output pixels (1 leaves pin holes between the points of a
    view seen from 10 degrees away; 3 fattens thin strands: measured in docs/novel_views.md)."""
    k_blend: int = 2
    """Kept cameras whose colours are blended per pixel (the nearest; a third at 20-degree
    spacing is 30 degrees away and costs 1 dB)."""
    vis_sigma_m: float = 0.003
    """Soft visibility width (metres of z-depth): a few 1-mm depth units of an RGB-D sensor."""
    vis_floor: float = 0.2
    """Smallest visibility weight of a camera whose image contains the point."""
    measured_first: bool = True
    """The measured points win the depth over the geometry's fill (module docstring, step 1);
    False: one z-buffer of all points (the rule before)."""
    pinhole_spread_m: float = 0.01
    """Step 1's single-pixel holes (:func:`fill_pinholes`): the largest spread (metres) of the four
    neighbours' depths that fills the hole with their mean; 0 = none filled (the rule before)."""
    back_gap_m: float = 0.02
    """The second depth layer (:func:`back_depth`, a model with a matte only): the farthest splatted
    point where it lies more than this (metres of z-depth) behind the pixel's front depth; 0 = no
    second layer (the rule before).  0.015-0.03 scored alike on the conifers it was set on
    (docs/novel_views.md)."""
    back_solid: float = 0.6
    """Where a layer starts to count as solid (:func:`solid`, :func:`under_back`): the second layer
    shows through as far as the kept views see it solid and see the front not."""
    resample: str = "linear"
    """Colour resampling: "linear" (bilinear, 2 x 2 texels) or "cubic" (Catmull-Rom, 4 x 4; keeps
    more contrast, sharpness +0.1, but -0.15 to -0.2 dB on every scene and size measured)."""
    alpha_mass: str = "auto"
    """Hold the frame's coverage to the mass of the kept views' mattes (render.gather.alpha_mass, a model with a
    matte only): the splats, the visibility floor and the second layer add 5-7 % of coverage to a conifer's partial
    pixels, in alpha and colour alike (docs/novel_views.md "Gather's alpha mass").  "auto": where every kept view
    was matted against a backdrop (their premultiplied colour exact: render.gather.alpha_mass.backdrop_matted; met
    its rule on six fresh black captures: over black +0.13 dB on average, conifers +0.30, bunnies +0.08, fur
    untouched); "on": every model with a matte (failed its rule: a room matte's colour error is pulled with the
    coverage, SSIM -0.008 on a conifer before a sunset); "off": the frame as drawn."""

    fine_depth: str = "auto"
    """1-pixel splats first (render.gather.fine_depth): a pixel a kept view's point lands in takes the nearest z of
    those points, the ``splat_px`` splats only where none lands, so a needle in front no longer lends its z to the
    pixels beside it.  "auto" (the default): on for a model whose kept mattes are mostly partial pixels (a
    conifer's crown), off for a body under fur, where the wide splats fill the coat; it met its third rule on six
    fresh captures (conifers over white +0.36..+0.57 dB, alpha MSE down, PSNR +0.03..+0.33, SSIM up; fur and a bunny
    untouched; docs/novel_views.md "Fine depth"); "on"; "off": the 2 x 2 splats alone (the rule before)."""

    def __post_init__(self) -> None:
        for k in ("k_depth", "splat_px", "k_blend"):
            if int(getattr(self, k)) != getattr(self, k) or getattr(self, k) < 1:
                raise ValueError(f"gather: {k} must be an integer >= 1, got {getattr(self, k)}")
        if not self.vis_sigma_m > 0:
            raise ValueError(f"gather: vis_sigma_m must be > 0, got {self.vis_sigma_m}")
        if not self.pinhole_spread_m >= 0:
            raise ValueError(f"gather: pinhole_spread_m must be >= 0, got {self.pinhole_spread_m}")
        if not self.back_gap_m >= 0:
            raise ValueError(f"gather: back_gap_m must be >= 0, got {self.back_gap_m}")
        if not 0 <= self.back_solid < 1:
            raise ValueError(f"gather: back_solid must be in [0, 1), got {self.back_solid}")
        if not 0 <= self.vis_floor <= 1:
            raise ValueError(f"gather: vis_floor must be in [0, 1], got {self.vis_floor}")
        if self.resample not in RESAMPLERS:
            raise ValueError(f"gather: resample must be one of {RESAMPLERS}, got {self.resample!r}")
        for k in ("alpha_mass", "fine_depth"):
            if getattr(self, k) not in ALPHA_MASS_MODES:
                raise ValueError(f"gather: {k} must be one of {ALPHA_MASS_MODES}, got {getattr(self, k)!r}")


def front_depth(eye: Camera, clouds, side: int, fine: bool = False) -> tuple[np.ndarray, int]:
    """(H, W) float64 nearest z-depth of the points of ``clouds`` splatted into ``eye`` in
    ``side`` x ``side``-pixel splats (0 where none lands), and the number of points in front
    of the eye.  ``fine``: the 1-pixel splats' nearest z wherever one lands, the ``side`` splats' elsewhere
    (GatherConfig.fine_depth)."""
    if fine and side > 1:
        z1, _ = front_depth(eye, clouds, 1)
        z, n = front_depth(eye, clouds, side)
        return np.where(z1 > 0, z1, z), n
    W, H = eye.width, eye.height
    front = np.full(H * W, np.inf)
    n = 0
    for cl in clouds:
        if len(cl.points) == 0:
            continue
        uv, z = eye.project(cl.points)
        ok = np.nonzero(z > 0)[0]
        n += len(ok)
        for i, pix in pr.splat_pixels(uv[ok], W, H, side):
            np.minimum.at(front, pix, z[ok[i]])
    front = front.reshape(H, W)
    return np.where(np.isfinite(front), front, 0.0), n


def measured_first_depth(eye: Camera, measured_clouds, fill_clouds, side: int,
                         fine: bool = False) -> tuple[np.ndarray, int]:
    """:func:`front_depth` of ``measured_clouds``, and where none of their splats lands, of
    ``fill_clouds`` (module docstring, step 1); the points in front of the eye of both."""
    zm, n = front_depth(eye, measured_clouds, side, fine)
    zf, nf = front_depth(eye, fill_clouds, side, fine)
    return np.where(zm > 0, zm, zf), n + nf


def back_depth(eye: Camera, clouds, side: int, front: np.ndarray, gap: float) -> np.ndarray:
    """(H, W) float64 z-depth of the second layer: per pixel with a ``front`` depth (> 0; the
    splatted front before :func:`fill_pinholes`), the farthest z of the points of ``clouds``
    splatted as in :func:`front_depth` where it lies more than ``gap`` metres behind the front; 0
    elsewhere.  (The farthest, not the nearest beyond the gap: the GPU gets it in the front's own
    pass, and the held-out scores were the same, docs/novel_views.md.)"""
    W, H = eye.width, eye.height
    far = np.zeros(H * W)
    for cl in clouds:
        if len(cl.points) == 0:
            continue
        uv, z = eye.project(cl.points)
        ok = np.nonzero(z > 0)[0]
        for i, pix in pr.splat_pixels(uv[ok], W, H, side):
            np.maximum.at(far, pix, z[ok[i]])
    far = far.reshape(H, W)
    front = np.asarray(front, np.float64)
    return np.where((front > 0) & (far > front + gap), far, 0.0)


def solid(alpha: np.ndarray, threshold: float) -> np.ndarray:
    """How solid the kept views see a layer of gathered ``alpha``: clip((alpha - threshold) / (1 - threshold), 0, 1)."""
    return np.clip((alpha - threshold) / (1.0 - threshold), 0.0, 1.0)


def under_back(col: np.ndarray, alpha: np.ndarray, col_b: np.ndarray, alpha_b: np.ndarray, threshold: float):
    """The front layer (premultiplied ``col`` (..., 3), ``alpha`` (...)) over the second layer's
    (``col_b``, ``alpha_b``), which shows through as far as it is solid and the front is not:
    g = :func:`solid` (alpha_b) (1 - :func:`solid` (alpha)); (col + (1 - alpha) (g / alpha_b) col_b,
    alpha + (1 - alpha) g).  A front the kept views see (nearly) solid already holds what lies behind
    it in their direction; the second layer would count it twice."""
    g = solid(alpha_b, threshold) * (1.0 - solid(alpha, threshold))
    scale = np.where(alpha_b > 0, g / np.where(alpha_b > 0, alpha_b, 1.0), 0.0)
    return col + ((1.0 - alpha) * scale)[..., None] * col_b, alpha + (1.0 - alpha) * g


def fill_pinholes(z: np.ndarray, spread: float) -> np.ndarray:
    """(H, W) ``z`` (0 = empty) with each empty pixel whose four edge neighbours all have a depth,
    at most ``spread`` metres apart, given their mean (float32 sums, as the GPU); image border
    pixels and holes of two or more pixels stay empty.  ``spread`` 0 returns ``z`` unchanged."""
    if not spread > 0 or min(z.shape) < 3:
        return z
    c = z[1:-1, 1:-1]
    nb = np.stack([z[:-2, 1:-1], z[2:, 1:-1], z[1:-1, :-2], z[1:-1, 2:]]).astype(np.float32)
    lo, hi = nb.min(axis=0), nb.max(axis=0)
    ys, xs = np.nonzero((c <= 0) & (lo > 0) & (hi - lo <= np.float32(spread)))
    out = z.copy()
    out[ys + 1, xs + 1] = pinhole_mean(z, ys + 1, xs + 1)
    return out


def pinhole_mean(z: np.ndarray, ys: np.ndarray, xs: np.ndarray) -> np.ndarray:
    """The filled depth of pixels (ys, xs) of ``z`` (none on the border): the mean of the four edge
    neighbours, summed in float32 in the shader's order (above, below, left, right)."""
    nb = [z[ys - 1, xs], z[ys + 1, xs], z[ys, xs - 1], z[ys, xs + 1]]
    nb = [np.asarray(v, np.float32) for v in nb]
    return (((nb[0] + nb[1]) + nb[2]) + nb[3]) * np.float32(0.25)


def cubic_weights(t: np.ndarray, a: float = CUBIC_A) -> np.ndarray:
    """(N, 4) Keys cubic weights of the taps at offsets -1, 0, 1, 2 from floor(x), t = x - floor(x)."""
    t = np.asarray(t, np.float64)
    t2, t3 = t * t, t * t * t
    return np.stack([a * (t3 - 2 * t2 + t), (a + 2) * t3 - (a + 3) * t2 + 1,
                     -(a + 2) * t3 + (2 * a + 3) * t2 - a * t, a * (t2 - t3)], -1)


def cubic(img: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """(N, C) Catmull-Rom bicubic interpolation of ``img`` (H, W, C) at ``uv`` (N, 2) OpenCV pixel
    coordinates, 4 x 4 taps clamped to the border, the result clamped to >= 0 (colours are)."""
    H, W = img.shape[:2]
    x0 = np.floor(uv[:, 0])
    y0 = np.floor(uv[:, 1])
    wx = cubic_weights(uv[:, 0] - x0)
    wy = cubic_weights(uv[:, 1] - y0)
    out = 0.0
    for j in range(4):
        yy = np.clip(y0 + j - 1, 0, H - 1).astype(np.int64)
        row = 0.0
        for i in range(4):
            row = row + img[yy, np.clip(x0 + i - 1, 0, W - 1).astype(np.int64)] * wx[:, i : i + 1]
        out = out + row * wy[:, j : j + 1]
    return np.maximum(out, 0.0)


def premultiply(rgb: np.ndarray, alpha: np.ndarray | None) -> np.ndarray:
    """(..., 3) colour, or with a matte ``alpha`` (...) the (..., 4) premultiplied colour + alpha
    the views are resampled from (float32, as the GPU stores them)."""
    if alpha is None:
        return np.asarray(rgb)
    a = np.asarray(alpha, np.float32)[..., None]
    return np.concatenate([np.asarray(rgb, np.float32) * a, a], -1)


def sample_view(cam: Camera, rgb: np.ndarray, depth: np.ndarray, points: np.ndarray, resample: str = "linear"):
    """What camera ``cam`` saw at world ``points`` (N, 3): (colour (N, C) resampled from ``rgb``
    (H, W, C; 3 straight or 4 premultiplied + alpha channels) by :func:`cubic`, or bilinearly with
    the edge texels clamped (capture.sampling.sample_image: GL_LINEAR + CLAMP_TO_EDGE), depth d (N,)
    at the nearest texel, the points' own z-depth z (N,), inside (N,) bool: in front of the camera
    and within its image, [-0.5, W - 0.5] x [-0.5, H - 0.5])."""
    uv, z = cam.project(points)
    uv = np.nan_to_num(uv, nan=-1e9)
    H, W = depth.shape
    inside = (z > 0) & (uv[:, 0] >= -0.5) & (uv[:, 1] >= -0.5) & (uv[:, 0] <= W - 0.5) & (uv[:, 1] <= H - 0.5)
    uvc = np.where(inside[:, None], uv, 0.0)
    d = np.where(inside, sample_image(depth, uvc[:, 0], uvc[:, 1], "nearest", "clamp"), 0.0)
    col = cubic(rgb, uvc) if resample == "cubic" else sample_image(rgb, uvc[:, 0], uvc[:, 1], "linear", "clamp")
    return col, d, z, inside


def visibility(d: np.ndarray, z: np.ndarray, inside: np.ndarray, sigma: float, floor: float) -> np.ndarray:
    """Soft visibility weight of a camera: exp(-(d - z)^2 / 2 sigma^2) where it measured a depth
    d > 0, at least ``floor``; 0 outside its image."""
    g = np.where(d > 0, np.exp(-0.5 * ((d - z) / sigma) ** 2), 0.0)
    return np.where(inside, np.maximum(g, floor), 0.0)


def gather(eye: Camera, depth: np.ndarray, views, weights, cfg: GatherConfig) -> tuple[np.ndarray, np.ndarray]:
    """Colours of the pixels of ``eye`` with ``depth`` > 0 gathered from ``views`` ((camera,
    rgb (H, W, C), depth (H, W)) per blend camera; C = 3 straight colour, or 4 = premultiplied
    colour + alpha, :func:`premultiply`) with per-camera ``weights`` (1 / angle): (rgb (H, W, 3)
    float64 linear premultiplied, alpha (H, W) float64 in [0, 1]: 1 where some blend camera's
    image contains the point without a matte, the blended alpha with one)."""
    m = depth > 0
    X = eye.unproject(eye.pixel_grid()[m], depth[m])
    C = np.asarray(views[0][1]).shape[-1] if len(views) else 3
    acc = np.zeros((len(X), C))
    wsum = np.zeros(len(X))
    for (cam, rgb, dep), w in zip(views, weights):
        col, d, z, inside = sample_view(cam, rgb, dep, X, cfg.resample)
        v = w * visibility(d, z, inside, cfg.vis_sigma_m, cfg.vis_floor)
        acc += v[:, None] * col
        wsum += v
    drawn = wsum > 0
    blend = np.where(drawn[:, None], acc / np.where(drawn, wsum, 1.0)[:, None], 0.0)
    out = np.zeros(depth.shape + (3,))
    alpha = np.zeros(depth.shape)
    out[m] = blend[:, :3]
    alpha[m] = np.minimum(blend[:, 3], 1.0) if C == 4 else drawn
    return out, alpha


def frame_depths(eye: Camera, clouds, cameras, rgb: np.ndarray, depth: np.ndarray, centre: np.ndarray,
                 cfg: GatherConfig, measured: np.ndarray | None = None, back: bool = False, fine: bool = False):
    """Steps 1 and 3's depths of :func:`gather_frame` (its arguments; ``fine``: GatherConfig.fine_depth as
    decided for the model): (front z (H, W) after :func:`fill_pinholes`, the second layer's z (H, W) or None
    unless ``back``, the points in front of the eye, the nearest cameras' indices and angles)."""
    idx, ang = pr.nearest_views(eye, cameras, centre, max(cfg.k_depth, cfg.k_blend))
    dv = idx[: cfg.k_depth]
    if measured is not None and cfg.measured_first:
        m = np.asarray(measured, bool)[dv]
        d = np.asarray(depth)[dv]
        cams = [cameras[i] for i in dv]
        used = [pr.back_project(cams, rgb[dv], np.where(m, d, 0)), pr.back_project(cams, rgb[dv], np.where(m, 0, d))]
        z, n = measured_first_depth(eye, *used, cfg.splat_px, fine)
        used = used[0] + used[1]
    else:
        used = [clouds[i] for i in dv]
        z, n = front_depth(eye, used, cfg.splat_px, fine)
    zb = back_depth(eye, used, cfg.splat_px, z, cfg.back_gap_m) if back else None
    return fill_pinholes(z, cfg.pinhole_spread_m), zb, n, idx, ang


def gather_frame(eye: Camera, clouds, cameras, rgb: np.ndarray, depth: np.ndarray, centre: np.ndarray,
                 cfg: GatherConfig | None = None, alpha: np.ndarray | None = None,
                 measured: np.ndarray | None = None, excess: float = 1.0):
    """The gather method's frame for ``eye`` (module docstring): (rgb (H, W, 3) float32 linear
    premultiplied (over black), alpha (H, W) float32 in [0, 1] (0 / 1 without a matte), depth
    (H, W) float32 z-depth, 0 = empty, points splatted).  ``clouds``:
    ``points_reference.back_project`` of (cameras, rgb, depth); ``alpha``: the views' (N, H, W)
    straight matte or None; ``measured``: the views' (N, H, W) bool measured depth
    (volume.rgbz_store.RgbzImages.measured) or None = all; ``cfg`` default GatherConfig(); ``excess``: the model's
    alpha excess f (render.gather.alpha_mass: its :func:`~render.gather.alpha_mass.loo_excess_reference`; 1: the
    alpha as drawn)."""
    cfg = cfg or GatherConfig()
    layered = alpha is not None and cfg.back_gap_m > 0
    fine = use_fine(cfg.fine_depth, alpha)
    z, zb, n, idx, ang = frame_depths(eye, clouds, cameras, rgb, depth, centre, cfg, measured, layered, fine)
    blend = idx[: cfg.k_blend]
    w = 1.0 / np.maximum(ang[: cfg.k_blend], pr.ANGLE_EPS)
    views = [(cameras[i], premultiply(rgb[i], None if alpha is None else alpha[i]), depth[i]) for i in blend]
    col, a = gather(eye, z, views, w, cfg)
    if layered:
        col_b, a_b = gather(eye, zb, views, w, cfg)
        col, a = under_back(col, a, col_b, np.where(a > 0, a_b, 0.0), cfg.back_solid)
    col, a = col.astype(np.float32), a.astype(np.float32)
    if alpha is not None and cfg.alpha_mass != "off":  # "auto": the caller gives f only for a backdrop's mattes
        col, a, _ = am.pull(col, a, excess)
    return (col, a, np.where(a > 0, z, 0.0).astype(np.float32), n)

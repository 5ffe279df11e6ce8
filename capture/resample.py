"""Depth maps at a lower resolution than the colour camera (phone LiDAR, RGB-D apps), and confidence maps.

Polycam, Record3D and ARKit exports pair e.g. a 1920x1440 colour image with a 256x192 depth map
over the same field of view.  :func:`upsample_depth` brings such a depth map to the colour
camera's pixels without ever averaging across a depth discontinuity:

- The depth image covers the colour image's field of view, edges aligned: depth pixel j's centre
  sits at colour coordinate (j + 0.5) * s - 0.5 with s = W / w (``capture.camera.resample_pixel_coords``,
  as in ``Camera.scaled``); W / w and H / h must agree (:data:`ASPECT_TOLERANCE`).
- Each colour pixel takes the 2 x 2 depth samples around it (``capture.sampling.linear_taps``;
  beyond the outer sample centres, the edge samples twice: CLAMP_TO_EDGE).  Where all four are measured and lie
  on one surface (spread <= :data:`DISCONTINUITY_REL` of the nearest), it is their bilinear
  interpolation (exact for planes).
- Elsewhere the footprint straddles a depth edge or a hole.  Joint-bilateral choice: each of the
  four samples scores exp(-d^2 / 2 sigma_s^2) * exp(-|c - c_k|^2 / 2 sigma_r^2), d its distance in
  depth pixels and c - c_k the difference between the colour pixel and the colour image averaged
  over that depth sample's footprint.  The best-scoring sample decides the surface: a hole gives no
  depth; otherwise the bilinear mean of the samples on the winner's surface (within
  DISCONTINUITY_REL of it) -- samples of the other surface never enter.

:func:`upsample_depth_reference` is the same rule written per pixel (the test compares them).

Confidence maps (ARKit / Record3D / Polycam style): 8-bit single-channel images beside the depth.
Values 0, 1, 2 are ARKit's low / medium / high; any map whose maximum exceeds 2 is read as 0..255.
:func:`confidence_mask` keeps depth whose confidence reaches :data:`MIN_CONFIDENCE` (of high).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from capture.camera import resample_pixel_coords
from capture.sampling import _axis_taps, linear_taps, nearest_pixel

#: Largest relative difference between W / w and H / h of a colour / depth pair.
ASPECT_TOLERANCE = 0.01
#: Two depth samples lie on one surface when they differ by at most this fraction of the nearer.
DISCONTINUITY_REL = 0.03
#: Spatial sigma of the joint-bilateral choice, in depth pixels.
SIGMA_SPATIAL = 0.5
#: Colour sigma of the joint-bilateral choice (Euclidean RGB distance, sRGB values in [0, 1]).
SIGMA_COLOUR = 0.1
#: ARKit confidence levels (low, medium, high) as stored by Record3D / Polycam / ARKit exports.
ARKIT_LEVELS = 2
#: Depth is kept where confidence >= this fraction of the highest level (ARKit: medium and high).
MIN_CONFIDENCE = 0.5
#: Rows of colour pixels resampled per block (bounds the temporary arrays to ~100 MB at 1920 wide).
BLOCK_ROWS = 256


class ResampleError(ValueError):
    """The depth image cannot be mapped onto the colour camera (aspect ratio, shape)."""


@dataclass(frozen=True)
class ResampleStats:
    """What :func:`upsample_depth` did.

    Attributes:
        depth_size: (w, h) of the depth image.
        colour_size: (W, H) of the colour image (and of the resampled depth).
        scale: (sx, sy) colour pixels per depth pixel.
        edge_pixels: colour pixels whose 2 x 2 depth footprint straddled a discontinuity or a hole.
        colour_decided: edge pixels whose surface was not that of the nearest depth sample.
        holes: colour pixels left without depth (the winning sample was unmeasured).
    """

    depth_size: tuple[int, int]
    colour_size: tuple[int, int]
    scale: tuple[float, float]
    edge_pixels: int
    colour_decided: int
    holes: int


def depth_scale(depth_shape: tuple[int, int], colour_shape: tuple[int, int]) -> tuple[float, float]:
    """(sx, sy) = (W / w, H / h) for a depth (h, w) beside a colour (H, W); ResampleError if they disagree."""
    h, w = depth_shape
    H, W = colour_shape
    if min(h, w, H, W) < 1:
        raise ResampleError(f"empty image ({w}x{h} depth, {W}x{H} colour)")
    sx, sy = W / w, H / h
    if abs(sx - sy) > ASPECT_TOLERANCE * max(sx, sy):
        raise ResampleError(f"depth is {w}x{h} but the colour image is {W}x{H}: different aspect ratios "
                            f"({w / h:.4f} vs {W / H:.4f}), so the depth cannot cover the colour camera's view")
    return sx, sy


def _guide_lo(guide: np.ndarray, w: int, h: int) -> np.ndarray:
    """The colour image averaged over each depth pixel's footprint: (h, w, 3) float32."""
    import cv2

    return cv2.resize(np.ascontiguousarray(guide, np.float32), (w, h), interpolation=cv2.INTER_AREA)


def _block(depth, glo, guide, rows, sx, sy):
    """Resample colour rows ``rows`` (all columns); returns (depth block, edge, colour_decided, holes).

    Only the pixels with a measured depth sample among their four taps are computed (a phone frame's
    background, half of it, has none): every other pixel is an edge pixel whose every choice is a
    hole, so it is 0 and counted as one; the computed pixels are the same elementwise arithmetic as
    over the whole block (:func:`upsample_depth_reference` is the rule pixel by pixel)."""
    h, w = depth.shape
    W = guide.shape[1]
    y, x = resample_pixel_coords(rows, 1 / sy), resample_pixel_coords(np.arange(W), 1 / sx)
    (iy,), _, _ = zip(*_axis_taps(y[:, None], (h,), ("clamp",)))
    (ix,), _, _ = zip(*_axis_taps(x[:, None], (w,), ("clamp",)))
    measured = depth > 0
    anyv = np.zeros((len(rows), W), bool)
    for jj in iy:
        for ii in ix:
            anyv |= measured[jj[:, None], ii[None, :]]
    out = np.zeros((len(rows), W), np.float64)
    r, c = np.nonzero(anyv)
    n_none = anyv.size - len(r)
    if not len(r):
        return out, n_none, 0, n_none
    Y, X = y[r], x[c]
    taps = linear_taps(np.stack([Y, X], -1), (h, w), "clamp")  # the 2 x 2 depth samples, edge clamped
    idx = [ij for ij, _, _ in taps]
    b = np.stack([wt for _, _, wt in taps], -1)
    d = np.stack([depth[j, i] for j, i in idx], -1)
    valid = d > 0
    dmin = np.where(valid, d, np.inf).min(-1)
    edge = ~(valid.all(-1) & (d.max(-1) - dmin <= DISCONTINUITY_REL * dmin))
    vals = np.where(edge, 0.0, (b * d).sum(-1))
    # joint-bilateral choice of the surface (module docstring), on the edge pixels only
    e = np.nonzero(edge)
    idx_e = [(j[e], i[e]) for j, i in idx]
    d_e, b_e, valid_e = d[e], b[e], valid[e]
    cols = np.stack([glo[j, i] for j, i in idx_e], -2)
    dist2 = np.stack([(Y[e] - j) ** 2 + (X[e] - i) ** 2 for j, i in idx_e], -1)
    g = guide[rows[r[e]], c[e]][:, None, :]
    score = np.exp(-dist2 / (2 * SIGMA_SPATIAL**2)) * np.exp(-((g - cols) ** 2).sum(-1) / (2 * SIGMA_COLOUR**2))
    win = np.argmax(score, -1)
    dwin = np.take_along_axis(d_e, win[:, None], -1)[:, 0]
    same = valid_e & (np.abs(d_e - dwin[:, None]) <= DISCONTINUITY_REL * dwin[:, None])
    bw = np.where(same, b_e + 1e-9, 0.0)
    vals[e] = np.where(dwin > 0, (bw * d_e).sum(-1) / np.maximum(bw.sum(-1), 1e-30), 0.0)
    out[r, c] = vals
    n_colour = int(np.count_nonzero((dwin > 0) & (win != np.argmin(dist2, -1))))
    return out, n_none + len(dwin), n_colour, n_none + int(np.count_nonzero(dwin <= 0))


def upsample_depth(depth: np.ndarray, guide: np.ndarray, fast: bool = True) -> tuple[np.ndarray, ResampleStats]:
    """Edge-aware resampling of a low-resolution z-depth map to the colour camera (module docstring).

    Args:
        depth: (h, w) float z-depth in metres, 0 = no measurement.
        guide: (H, W, 3) colour of the same view, float in [0, 1] (sRGB-encoded values).
        fast: the compiled loop (capture.resample_kernel), else the vectorised numpy path
            (:func:`upsample_depth_numpy`, its twin: the same depth, tests/capture/test_resample.py).
    Returns:
        (H, W) float32 depth in metres (0 = none) and the :class:`ResampleStats`.
    """
    if not fast:
        return upsample_depth_numpy(depth, guide)
    from capture.resample_kernel import upsample_depth_kernel

    depth, guide, (h, w), (H, W), (sx, sy), glo = _inputs(depth, guide)
    out, edge, colour, holes = upsample_depth_kernel(depth, glo, guide, sx, sy, DISCONTINUITY_REL, SIGMA_SPATIAL,
                                                     SIGMA_COLOUR)
    return out, ResampleStats((w, h), (W, H), (sx, sy), edge, colour, holes)


def _inputs(depth, guide):
    """(depth float64 with 0 for none, guide float32, (h, w), (H, W), (sx, sy), the guide averaged
    over each depth pixel) of :func:`upsample_depth`'s arguments; ResampleError on bad shapes."""
    depth = np.asarray(depth, np.float64)
    guide = np.asarray(guide, np.float32)
    if depth.ndim != 2 or guide.ndim != 3 or guide.shape[2] != 3:
        raise ResampleError(f"expected (h, w) depth and (H, W, 3) colour, got {depth.shape} and {guide.shape}")
    h, w = depth.shape
    H, W = guide.shape[:2]
    sx, sy = depth_scale((h, w), (H, W))
    depth = np.where(np.isfinite(depth) & (depth > 0), depth, 0.0)
    return depth, guide, (h, w), (H, W), (sx, sy), _guide_lo(guide, w, h)


def upsample_depth_numpy(depth: np.ndarray, guide: np.ndarray) -> tuple[np.ndarray, ResampleStats]:
    """:func:`upsample_depth` vectorised in numpy blocks of BLOCK_ROWS rows (the compiled loop's twin)."""
    depth, guide, (h, w), (H, W), (sx, sy), glo = _inputs(depth, guide)
    out = np.zeros((H, W), np.float32)
    edge = colour = holes = 0
    for r0 in range(0, H, BLOCK_ROWS):
        rows = np.arange(r0, min(H, r0 + BLOCK_ROWS))
        blk, e, c, o = _block(depth, glo, guide, rows, sx, sy)
        out[rows] = blk
        edge, colour, holes = edge + e, colour + c, holes + o
    return out, ResampleStats((w, h), (W, H), (sx, sy), edge, colour, holes)


def upsample_depth_reference(depth: np.ndarray, guide: np.ndarray) -> np.ndarray:
    """:func:`upsample_depth` written pixel by pixel (slow; the obviously-correct twin for tests)."""
    depth = np.asarray(depth, np.float64)
    guide = np.asarray(guide, np.float32)
    h, w = depth.shape
    H, W = guide.shape[:2]
    sx, sy = depth_scale((h, w), (H, W))
    glo = _guide_lo(guide, w, h)
    out = np.zeros((H, W), np.float32)
    for v in range(H):
        for u in range(W):
            y, x = float(resample_pixel_coords(v, 1 / sy)), float(resample_pixel_coords(u, 1 / sx))
            corners = [(int(j), int(i), float(wt)) for (j, i), _, wt in linear_taps(np.array([y, x]), (h, w), "clamp")]
            ds = [depth[j, i] for j, i, _ in corners]
            if all(z > 0 for z in ds) and max(ds) - min(ds) <= DISCONTINUITY_REL * min(ds):
                out[v, u] = sum(bk * depth[j, i] for j, i, bk in corners)
                continue
            scores = [np.exp(-((y - j) ** 2 + (x - i) ** 2) / (2 * SIGMA_SPATIAL**2))
                      * np.exp(-float(np.sum((guide[v, u] - glo[j, i]) ** 2)) / (2 * SIGMA_COLOUR**2))
                      for j, i, _ in corners]
            dw = ds[int(np.argmax(scores))]
            if dw <= 0:
                continue
            num = den = 0.0
            for (_, _, bk), z in zip(corners, ds):
                if z > 0 and abs(z - dw) <= DISCONTINUITY_REL * dw:
                    num += (bk + 1e-9) * z
                    den += bk + 1e-9
            out[v, u] = num / den
    return out


def nearest_depth(depth: np.ndarray, W: int, H: int) -> np.ndarray:
    """(H, W) ``depth`` resampled by the nearest source pixel to each target pixel centre (a
    measured value, never a blend across an edge): the working scale's depth (volume.views) and the
    fusion maps at a phone depth's measured size (volume.stream)."""
    h, w = np.asarray(depth).shape
    xi = np.clip(nearest_pixel(resample_pixel_coords(np.arange(W), w / W)), 0, w - 1)
    yi = np.clip(nearest_pixel(resample_pixel_coords(np.arange(H), h / H)), 0, h - 1)
    return np.asarray(depth)[yi[:, None], xi[None, :]]


def confidence_levels(conf: np.ndarray) -> np.ndarray:
    """Confidence image -> float in [0, 1]: ARKit levels 0/1/2 when the maximum is <= 2, else value / 255."""
    c = np.asarray(conf)
    if c.ndim != 2:
        raise ResampleError(f"confidence must be a single-channel image, got shape {c.shape}")
    top = ARKIT_LEVELS if c.max(initial=0) <= ARKIT_LEVELS else 255.0
    return c.astype(np.float32) / top


def confidence_mask(conf: np.ndarray, min_confidence: float = MIN_CONFIDENCE) -> np.ndarray:
    """(h, w) bool: depth samples whose confidence reaches ``min_confidence`` (fraction of the highest level)."""
    return confidence_levels(conf) >= min_confidence


def guide_from_colour(rgb: np.ndarray) -> np.ndarray:
    """A scan's colour (uint8 sRGB or float32 linear) -> (H, W, 3) float32 sRGB values in [0, 1] for the guide."""
    from capture.scan import linear_to_srgb

    rgb = np.asarray(rgb)
    return rgb.astype(np.float32) / 255.0 if rgb.dtype == np.uint8 else linear_to_srgb(rgb)


def describe(stats: list[ResampleStats]) -> str:
    """One log line about the resampling of a scan set's depth maps (sizes of the first frame)."""
    edge = sum(s.edge_pixels for s in stats)
    colour = sum(s.colour_decided for s in stats)
    holes = sum(s.holes for s in stats)
    (w, h), (W, H), (sx, _) = stats[0].depth_size, stats[0].colour_size, stats[0].scale
    return (f"depth {w}x{h} resampled to the colour cameras {W}x{H} "
            f"(x{sx:.3g}) in {len(stats)} frames, edge-aware: bilinear only within one surface (spread <= "
            f"{DISCONTINUITY_REL:.0%}); {edge} pixels at depth edges or holes took one side chosen by colour "
            f"({colour} not the nearest sample's, {holes} left without depth)")

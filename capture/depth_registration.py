"""Is each view's depth registered to its colour image?  Part of the depth-agreement check (volume/agreement.py).

An RGB-D capture whose depth was not registered to the colour camera (or was registered with another
calibration) puts every depth pixel a few pixels beside the colour it belongs to.  The depths still agree
with each other and with the poses (capture.depth_agreement sees nothing), and the model is built without
a word: on the 24-view synthetic fur ball, every depth map moved 6 px to the right cost the held-out views
1.95 dB (24.48 -> 22.52, docs/capture_formats.md).

The check.  Where the depth has an edge (a measured pixel beside an unmeasured one, or a step of more than
:data:`EDGE_LOG_STEP` in log depth: the object's silhouette and its folds), the colour image has one too.  Each
view is measured at most :data:`OFFSET_WORK_PX` wide (its colour by area, depth by nearest sample): the
mean colour-gradient magnitude at the depth's edges shifted by (dx, dy), for every shift within
:data:`OFFSET_RADIUS`, over the view's mean gradient (:func:`edge_scores`).  The views' scores are summed, and
the best shift is reported when it is at least :data:`OFFSET_MIN_PX` from (0, 0) and scores :data:`OFFSET_GAIN`
times the score at (0, 0) (:func:`offset_verdict`).  Measured: right captures (the synthetic fur ball, bunny,
plant, noisy and pose-jittered copies, the 72-view phone plant, path-traced captures of fur and conifers) have
their best shift at exactly (0, 0); the fur ball with its depth moved 6 px right finds (-6, 0) at 1.13 times,
the path-traced fur before a background of its own colour likewise at 1.04 times.
The stage scores about 24 views of a capture (volume/agreement.py EDGE_VIEWS).

A depth camera with its own field of view (its focal length a times the colour's, the maps read with the colour's
intrinsics) puts the depth's edges a times as far from the principal point as the colour's: the depths then agree
with the poses with every focal length times a (capture.depth_agreement.focal_check), as they do when the focal
lengths are wrong for both images.  :func:`zoom_sums` tells the two apart (:data:`ZOOM_GAIN`), and
:func:`zoomed_depth` draws the depth back (``--depth-agreement fix``).
"""

from __future__ import annotations

import numpy as np

#: Shifts searched, in working pixels, each way.
OFFSET_RADIUS = 8
#: Views are measured at most this many pixels wide.
OFFSET_WORK_PX = 640
#: A best shift at least this far (working pixels, either axis) from (0, 0) is reported ...
OFFSET_MIN_PX = 3
#: ... when its score is at least this many times the score at (0, 0) (every right capture measured peaks at
#: (0, 0) itself; the path-traced fur before a background of its colour, its depth moved 6 px: (-6, 0) at 1.04).
OFFSET_GAIN = 1.02
#: A depth edge: a step of more than this in log depth between neighbours (or measured beside unmeasured).
EDGE_LOG_STEP = 0.05
#: A view with fewer depth-edge pixels than this inside the searched margin is not scored ...
MIN_EDGE_PIXELS = 50
#: ... and one with more is scored on this many of them (seeded by ``seed``; 4,000 found the same offsets).
EDGE_SAMPLES = 2000
#: Where the focal search (capture.depth_agreement.focal_check) finds a factor a, the colour's edges are held
#: against the depth's drawn a times closer to the principal point (:func:`zoom_sums`): a depth camera with its own
#: field of view, read with the colour's intrinsics, scores this many times the gradient there or more (1.34-1.77
#: on the fur ball with its depth maps zoomed 0.9x / 1.15x); focal lengths wrong for colour and depth alike score
#: less (0.12-0.95 on nine captures; docs/capture_formats.md).
ZOOM_GAIN = 1.1


def depth_edges(depth: np.ndarray) -> np.ndarray:
    """(H, W) bool: both pixels of every horizontal or vertical neighbour pair across a depth edge (a measured
    pixel beside an unmeasured one, or a log-depth step above EDGE_LOG_STEP): symmetric, so no half-pixel bias."""
    z = np.asarray(depth, np.float32)
    v = np.isfinite(z) & (z > 0)
    lz = np.log(np.where(v, z, 1.0))
    e = np.zeros(v.shape, bool)
    for ax in (0, 1):
        a = [slice(None), slice(None)]
        b = [slice(None), slice(None)]
        a[ax], b[ax] = slice(1, None), slice(None, -1)
        a, b = tuple(a), tuple(b)
        cut = (v[a] != v[b]) | (v[a] & v[b] & (np.abs(lz[a] - lz[b]) > EDGE_LOG_STEP))
        e[a] |= cut
        e[b] |= cut
    return e


def gradient_and_edges(rgb: np.ndarray, depth: np.ndarray, seed: int, work_px: int, radius: int,
                       samples: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """(the colour's gradient magnitude G (h, w) float32 at most ``work_px`` wide (colour by area, depth by nearest
    sample), the depth's edge pixels (ys, xs) at least ``radius`` inside it, at most ``samples`` of them drawn with
    ``seed``, the working scale) of one view (``depth`` on the colour's pixel grid, metres)."""
    import cv2

    raw = np.asarray(rgb)
    H, W = raw.shape[:2]
    f = min(1.0, work_px / W)
    if f < 1.0:  # measured at the working size: the colour by area, the depth by nearest sample
        w, h = max(1, round(W * f)), max(1, round(H * f))
        raw = cv2.resize(raw if raw.dtype in (np.uint8, np.float32) else raw.astype(np.float32), (w, h),
                         interpolation=cv2.INTER_AREA)
        depth = cv2.resize(np.asarray(depth, np.float32), (w, h), interpolation=cv2.INTER_NEAREST)
    g = raw.mean(axis=-1, dtype=np.float32) if raw.ndim == 3 else raw.astype(np.float32)
    g = g / 255.0 if raw.dtype == np.uint8 else np.sqrt(np.clip(g, 0.0, None))  # 8-bit sRGB, or linear: ~perceptual
    G = np.hypot(cv2.Sobel(g, cv2.CV_32F, 1, 0, ksize=3), cv2.Sobel(g, cv2.CV_32F, 0, 1, ksize=3))
    ys, xs = np.nonzero(depth_edges(depth))
    inside = (ys >= radius) & (ys < G.shape[0] - radius) & (xs >= radius) & (xs < G.shape[1] - radius)
    ys, xs = ys[inside], xs[inside]
    if len(ys) > samples:
        pick = np.sort(np.random.default_rng(seed).choice(len(ys), samples, replace=False))
        ys, xs = ys[pick], xs[pick]
    return G, ys, xs, f


def _gradient_and_edges(rgb: np.ndarray, depth: np.ndarray, seed: int):
    """:func:`gradient_and_edges` at OFFSET_WORK_PX, OFFSET_RADIUS and EDGE_SAMPLES, None for G with too few edges
    (MIN_EDGE_PIXELS) or no gradient."""
    G, ys, xs, f = gradient_and_edges(rgb, depth, seed, OFFSET_WORK_PX, OFFSET_RADIUS, EDGE_SAMPLES)
    if len(ys) < MIN_EDGE_PIXELS or not G.mean() > 0:
        return None, ys, xs, f
    return G, ys, xs, f


def edge_scores(rgb: np.ndarray, depth: np.ndarray, seed: int = 0) -> tuple[np.ndarray | None, float]:
    """((2R+1, 2R+1) mean colour-gradient magnitude at the depth's edges shifted by (dy, dx) = index - R, over
    the image's mean gradient, or None with too few edges; the working scale (working / full pixels)) of one
    view (module docstring).  ``rgb``: (H, W, 3) colour (8-bit sRGB or linear), ``depth``: (H, W) metres; at most
    EDGE_SAMPLES edge pixels, drawn with ``seed``."""
    G, ys, xs, f = _gradient_and_edges(rgb, depth, seed)
    if G is None:
        return None, f
    return _around(G, ys, xs).mean(axis=-1) / G.mean(), f


def _around(G: np.ndarray, ys: np.ndarray, xs: np.ndarray) -> np.ndarray:
    """(2R+1, 2R+1, m) ``G`` at each pixel (ys, xs) shifted by (dy, dx) = index - R, R = OFFSET_RADIUS (the pixels
    at least R inside ``G``)."""
    d = np.arange(-OFFSET_RADIUS, OFFSET_RADIUS + 1)
    return G[(ys[None, :] + d[:, None])[:, None, :], (xs[None, :] + d[:, None])[None, :, :]]


def offset_verdict(total: np.ndarray, views: int, scale: float) -> dict:
    """The registration part of the depth-agreement record from the views' summed :func:`edge_scores` (``views``
    of them, measured at ``scale`` working / full pixels): the best shift of the colour's edges from the
    depth's (full pixels, x right, y down), its score against (0, 0)'s, and ``offset`` True when it is reported
    (module docstring)."""
    R = OFFSET_RADIUS
    by, bx = np.unravel_index(int(np.argmax(total)), total.shape)
    dx, dy = int(bx) - R, int(by) - R
    gain = float(total[by, bx] / max(total[R, R], 1e-12))
    off = max(abs(dx), abs(dy)) >= OFFSET_MIN_PX and gain >= OFFSET_GAIN
    rec = {"colour_offset_px": [round(dx / scale, 1), round(dy / scale, 1)], "colour_offset_gain": round(gain, 4),
           "colour_offset_views": int(views), "colour_offset": bool(off)}
    if off:
        rec["colour_offset_message"] = (
            f"the colour images' edges sit ({dx / scale:+.0f}, {dy / scale:+.0f}) px from the depth's in {views} views "
            f"({gain:.2f} times as many as at (0, 0)): is the depth registered to the colour camera (the depth "
            "pixels over the colour pixels they measured)?")
    return rec


def shifted_depth(depth: np.ndarray, dx: int, dy: int) -> np.ndarray:
    """``depth`` moved by (dx, dy) whole pixels (x right, y down), 0 where nothing moved in: what ``--depth-agreement
    fix`` does with the opposite of the reported offset."""
    z = np.asarray(depth, np.float32)
    out = np.zeros_like(z)
    H, W = z.shape
    if abs(dx) >= W or abs(dy) >= H:
        return out
    to = (slice(max(dy, 0), H + min(dy, 0)), slice(max(dx, 0), W + min(dx, 0)))
    out[to] = z[max(-dy, 0):H + min(-dy, 0), max(-dx, 0):W + min(-dx, 0)]
    return out


def zoom_sums(rgb: np.ndarray, depth: np.ndarray, centre: np.ndarray, zoom: float, seed: int = 0) -> np.ndarray:
    """(1 + (2R+1)^2,) the colour's gradient magnitude summed at the depth's edges as they are, then at the same
    edges drawn ``zoom`` times closer to ``centre`` (full-size pixels (cx, cy): the principal point) and shifted by
    (dy, dx) = index - R working pixels (row by row), of one view; zeros with too few edges.  A depth map from a
    camera whose focal length is ``zoom`` times the colour's, read with the colour's intrinsics, has its edges
    ``zoom`` times further from the centre than the colour's (and beside them where the two cameras stand apart):
    the zoomed sums are the larger (:func:`zoom_verdict`)."""
    R = OFFSET_RADIUS
    G, ys, xs, f = _gradient_and_edges(rgb, depth, seed)
    if G is None:
        return np.zeros(1 + (2 * R + 1) ** 2)
    c = np.asarray(centre, np.float64) * f
    my = np.rint(c[1] + (ys - c[1]) / zoom).astype(np.int64)
    mx = np.rint(c[0] + (xs - c[0]) / zoom).astype(np.int64)
    ok = (my >= R) & (my < G.shape[0] - R) & (mx >= R) & (mx < G.shape[1] - R)
    return np.concatenate([[G[ys[ok], xs[ok]].sum()], _around(G, my[ok], mx[ok]).sum(axis=-1).ravel()])


def zoom_verdict(total: np.ndarray, zoom: float, width: int) -> dict:
    """From the views' summed :func:`zoom_sums` at ``zoom`` (views ``width`` pixels wide): ``depth_zoom_gain`` (the
    best zoomed sum over the sum as they are), ``depth_zoom_shift_px`` (the best one's shift, full pixels, x right,
    y down: the colour's edges from the depth's drawn back; (0, 0) when under OFFSET_MIN_PX working pixels) and
    ``depth_zoom`` (the gain at least ZOOM_GAIN)."""
    R = OFFSET_RADIUS
    grid = np.asarray(total[1:], np.float64).reshape(2 * R + 1, 2 * R + 1)
    by, bx = np.unravel_index(int(np.argmax(grid)), grid.shape)
    if max(abs(int(bx) - R), abs(int(by) - R)) < OFFSET_MIN_PX:  # a shift too small to report is none
        by, bx = R, R
    gain = float(grid[by, bx] / total[0]) if total[0] > 0 else 0.0
    f = min(1.0, OFFSET_WORK_PX / float(width))
    return {"depth_zoom_gain": round(gain, 4), "depth_zoom_shift_px": [round((int(bx) - R) / f, 1),
                                                                       round((int(by) - R) / f, 1)],
            "depth_zoom": bool(gain >= ZOOM_GAIN)}


def zoomed_depth(depth: np.ndarray, centre: np.ndarray, width: int, zoom: float) -> np.ndarray:
    """``depth`` drawn ``zoom`` times closer to ``centre`` (the principal point (cx, cy) in pixels of an image
    ``width`` wide; the depth map may be smaller): each pixel p takes the depth at centre + zoom (p - centre)
    (nearest; 0 outside): what ``--depth-agreement fix`` does with a depth camera's own field of view
    (volume/agreement.py)."""
    z = np.asarray(depth, np.float32)
    H, W = z.shape
    c = np.asarray(centre, np.float64) * (W / float(width))
    ys, xs = np.mgrid[0:H, 0:W]
    sy = np.rint(c[1] + zoom * (ys - c[1])).astype(np.int64)
    sx = np.rint(c[0] + zoom * (xs - c[0])).astype(np.int64)
    ok = (sy >= 0) & (sy < H) & (sx >= 0) & (sx < W)
    out = np.zeros_like(z)
    out[ok] = z[sy[ok], sx[ok]]
    return out

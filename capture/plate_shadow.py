"""The object's own shadow on its support, put into a fixed camera's plate before the matte (issue 30).

A fixed camera's plate is the frames' median background (capture.plate_fixed).  The object turns on its table and
its shadow turns with it, so the plate does not hold the shadow a frame casts, and the known-background matte reads
the darkened table beside the object as coverage: a furry bunny on a table grew a band of alpha along the side its
shadow falls, and its held-out alpha sat 1-2 px off the truth (docs/matting.md, "The bunny on the table").

:func:`shadow_relit` lights the plate as the frame is lit there: on the *ring* -- the trimap's background within
RING_PX of its band, where the plate is known, on the support plane near the object (:func:`support_pixels`), and
neither colour clipped or black -- the ratio of the frame's mean colour to the plate's is measured; when at least
SHADOW_SHARE of those ratios are below SHADOW_RATIO (a shadow, not noise: a conifer's ring had 1 % of them, the fur's
23-42 %), the ratios, clipped to [MIN_SCALE, 1] (a shadow only darkens), are filled inward by the push-pull pyramid
(capture.fill.push_pull) and scale the plate within RING_PX of the band on the support plane.  Elsewhere, and
without a shadow, the plate is as it was.
"""

from __future__ import annotations

import numpy as np

#: Width (pixels) of the ring around the trimap's band, and of the region the scale reaches into.
RING_PX = 30
#: A ring pixel darker than this ratio of its plate counts as shadowed ...
SHADOW_RATIO = 0.85
#: ... and the view is relit when at least this share of its ring is.
SHADOW_SHARE = 0.1
#: The darkest scale taken (a shadow darker than this is left to the matte).
MIN_SCALE = 0.3
#: Fewest ring pixels for a verdict.
MIN_RING = 100
#: The support plane counts within this many focus radii of the object's centre (the table, not the room beyond).
SUPPORT_REACH = 1.5
#: Darkest and brightest linear values a ring pixel may have in the plate (mean) and the frame (any channel).
DARK, CLIP = 0.02, 0.98
#: Where a view's ring shows the shadow, the plate's pixels on the support that the frames' lines estimated
#: (capture.plate_lines: one background per pixel across the frames) count as unknown (:func:`lines_off_shadow`);
#: False: kept.  The shadow turns with the object, so the lines there mix lit and shadowed table and cross at neither:
#: on a furry bunny on a table (path-traced, auto exposure, a lens) those pixels held 62 % of the kept views' squared
#: alpha error (6,878 of 11,105; on the support 6,281 -> 2,734 of 6,871 after).  Held out (docs/matting.md "The
#: lines under the shadow"): the bunny 24.155 -> 24.197 dB, alpha MSE 0.0111 -> 0.0094; the fur ball on the table
#: 23.817 -> 23.847, 0.0111 -> 0.0105; dropped everywhere in such a view instead of on the support, the fur ball lost
#: 1.0 dB.
SHADOW_DROPS_LINES = True


def support_pixels(camera, plane, centre, radius: float, shape, box=None) -> np.ndarray:
    """(H, W) bool: pixels of ``camera`` (capture.camera.Camera, OpenCV) whose ray meets ``plane`` ((4,): n . x + d
    = 0, world) in front of the camera within SUPPORT_REACH x ``radius`` of ``centre`` (3,); ``box`` (y0, y1, x0,
    x1): only those pixels (the rest False)."""
    H, W = shape
    y0, y1, x0, x1 = (0, H, 0, W) if box is None else box
    v, u = np.mgrid[y0:y1, x0:x1]
    rays = np.stack([u, v, np.ones_like(u)], -1).reshape(-1, 3).astype(np.float64) @ np.linalg.inv(camera.K).T
    R, t = camera.cam_from_world[:3, :3], camera.cam_from_world[:3, 3]
    dirs, origin = rays @ R, -R.T @ t  # R^T d for each ray; the camera centre
    n, d = np.asarray(plane[:3], np.float64), float(plane[3])
    den = dirs @ n
    with np.errstate(divide="ignore", invalid="ignore"):
        hit = -(n @ origin + d) / np.where(np.abs(den) > 1e-12, den, np.nan)
    pts = origin + hit[:, None] * dirs
    near = np.linalg.norm(pts - np.asarray(centre, np.float64), axis=1) < SUPPORT_REACH * float(radius)
    out = np.zeros((H, W), bool)
    out[y0:y1, x0:x1] = ((hit > 0) & near).reshape(y1 - y0, x1 - x0)
    return out


def reach_box(trimap: np.ndarray):
    """(y0, y1, x0, x1): the box around the trimap's band and object widened by RING_PX + 1 (where the ring and
    the scale can be), or None without one."""
    ys, xs = np.nonzero(np.asarray(trimap) > 0.0)
    if not len(ys):
        return None
    H, W = np.shape(trimap)
    m = RING_PX + 1
    return (max(int(ys.min()) - m, 0), min(int(ys.max()) + m + 1, H),
            max(int(xs.min()) - m, 0), min(int(xs.max()) + m + 1, W))


def shadow_relit(image: np.ndarray, background: np.ndarray, known: np.ndarray, trimap: np.ndarray,
                 support: np.ndarray) -> tuple[np.ndarray, dict | None]:
    """(the plate ``background`` (H, W, 3) lit as the frame ``image`` is on the support beside the object, the
    record; or the plate itself and None without a shadow) (module docstring).  ``known``, ``support``: (H, W)
    bool; ``trimap``: (H, W), background <= 0, band and object above."""
    from capture.fill import push_pull
    from capture.matting_fast import dilate

    box = reach_box(trimap)
    if box is None:
        return background, None
    sl = (slice(box[0], box[1]), slice(box[2], box[3]))  # the ring and the scale lie in it: the same values
    C = np.asarray(image)[sl].astype(np.float64)
    B = np.asarray(background)[sl].astype(np.float64)
    tri = np.asarray(trimap)[sl]
    known, support = np.asarray(known, bool)[sl], np.asarray(support, bool)[sl]
    reach = dilate(tri > 0.0, RING_PX) & np.asarray(known, bool) & np.asarray(support, bool)
    lc, lb = C.mean(-1), B.mean(-1)
    ring = reach & (tri <= 0.0) & (lb > DARK) & (lc > DARK / 4) & (C.max(-1) < CLIP) & (B.max(-1) < CLIP)
    if int(ring.sum()) < MIN_RING:
        return background, None
    ratio = lc[ring] / lb[ring]
    share = float(np.mean(ratio < SHADOW_RATIO))
    if share < SHADOW_SHARE:
        return background, None
    r = np.zeros(tri.shape)
    r[ring] = np.clip(ratio, MIN_SCALE, 1.0)
    filled = np.where(ring, r, push_pull(r[..., None], ring.astype(np.float64))[..., 0])
    scale = np.where(reach, np.clip(filled, MIN_SCALE, 1.0), 1.0)
    lit = np.array(background, copy=True)
    lit[sl] = (B * scale[..., None]).astype(lit.dtype)
    return lit, {"ring": int(ring.sum()), "dark_share": round(share, 4), "scale_min": round(float(scale.min()), 4)}


def lines_off_shadow(known: np.ndarray, estimated: np.ndarray | None, support: np.ndarray,
                     record: dict | None) -> tuple[np.ndarray, np.ndarray | None]:
    """(known, estimated) of a view's plate with the lines' estimates on the ``support`` (H, W) bool taken out of both
    when :func:`shadow_relit` found a shadow (``record`` not None; SHADOW_DROPS_LINES); the record gets
    ``lines_dropped``, the pixels taken out.  Otherwise the masks as they were."""
    if record is None or estimated is None or not SHADOW_DROPS_LINES:
        return known, estimated
    drop = np.asarray(estimated, bool) & np.asarray(support, bool)
    record["lines_dropped"] = int(drop.sum())
    return np.asarray(known, bool) & ~drop, np.asarray(estimated, bool) & ~drop

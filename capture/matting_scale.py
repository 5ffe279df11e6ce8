"""Matting at the resolution it needs (issue 32): solve on a smaller copy, bring alpha and colour back
guided by the full-resolution image.

A phone frame is 1920x1440 while the depth that draws its trimap (capture.matting.depth_trimap) was
measured at 256x192: a closed-form solve over the frame's 2.8 million pixels (11.7 s a view, 231 s
the worst) mostly re-derives, pixel by pixel, what a coarser solve already knows.  Here the solve
(any ``solve(image, trimap, background, known) -> Matte`` of capture.matting: the closed-form
estimate, the known-background matte) runs on the crop around the trimap's unknown and opaque
pixels scaled by :func:`working_scale`, and its alpha and foreground colour come back to full
resolution by the **fast guided filter** (He & Sun 2015, "Fast Guided Filter"): the guided filter's
local linear model q = a . I + b (I the colour image, a (3,) and b per window) is fitted at the
working resolution against the downscaled image, its coefficients upsampled bilinearly and applied
to the full-resolution image, so that every edge of the full-resolution colour is an edge of the
alpha.  The full-resolution trimap still rules where it is sure (opaque 1, background 0), and an
opaque pixel's colour is the pixel's own (C = F where alpha = 1).

The working scale (:func:`working_scale`) keeps the object's box at least ``OBJECT_WORK_PX``
pixels on its longer side and the image at least ``DEPTH_OVERSAMPLE`` times the width the depth
was measured at (when known): never finer than the frame, never coarser than what drew the
trimap or what shows the object's shape.  A scale above ``FULL_SIZE_ABOVE`` solves at full size
(the saving would not pay for the resampling).

:func:`matte_at_scale` at scale 1 is the solve itself (the full-size reference).

:func:`known_matte_at_scale` is the same for the known-background matte (capture.matting_known; the
plate and backdrop paths): alpha is solved on the working copy (image, trimap, background and where
it is known, all downscaled) and brought back by the fast guided filter, and the trimap it is held
to at full resolution is the known-background path's own (widened where the background cannot
explain a pixel, opaque pixels open where the background is known), with alpha kept above the
full-resolution bound of the compositing equation (and, where the plate is blown out and the photo
is not, the bound against the plate: capture.matting_known.blown_bound).  Before that each pixel's
own alpha is pulled in by step 2 of capture.matting_known at full resolution, with the full-size
path's candidates and rule (its colour_sources and fit_candidates, shared).  The colour is then made **at full
resolution** where the background is known: F = B + (C - B) / alpha exactly, so the premultiplied
colour alpha F = C - (1 - alpha) B reproduces the photo (capture.matting_known.foreground_colour,
step 4); only where the background is not known does the upsampled working colour stand in for
pymatting's foreground.
"""

from __future__ import annotations

import numpy as np

#: The object's box (trimap's unknown and opaque pixels) keeps at least this many pixels along its
#: longer side at the working resolution.
OBJECT_WORK_PX = 640
#: ... and the working image is at least this many times the width the depth was measured at.
DEPTH_OVERSAMPLE = 2.0
#: Scales above this solve at full size.
FULL_SIZE_ABOVE = 0.8
#: A **solid** object (leaves, a pot: its depth's trimap leaves at most SOLID_BAND_SHARE of the
#: object's pixels, unknown and opaque, unknown) keeps only SOLID_WORK_PX pixels along its longer side
#: (the depth's floor still holds).  A needle conifer's trimap is nearly all band (its opaque core
#: eroded away).  Measured (docs/speed.md round 8, the plate path against the full-size solve, alpha
#: MSE over the frame): 8 views of the 72-view 1280x960 phone plant, band share 0.34-0.48, at 0.4 /
#: 0.5 / 0.6 / 0.7 worst 0.0019 / 0.0013 / 0.0014 / 0.0014; the path-traced conifer turntable (36
#: views, band share 0.973-0.978) at 0.5 / 0.7 worst 0.028 / 0.017 (issue 32's bar 0.002): it keeps
#: OBJECT_WORK_PX.  Only these two kinds of object were measured; a conifer whose depth is coarse
#: enough to leave an opaque core (a phone's) was not.
SOLID_BAND_SHARE = 0.6
SOLID_WORK_PX = 400
#: Fast guided filter: window radius at the working resolution (pixels) and regularisation epsilon
#: (linear colour squared).
GUIDE_RADIUS = 2
GUIDE_EPS = 1e-4
#: Known-background matte at the working scale: weight of each full-resolution pixel's own alpha
#: (the compositing equation solved with the upsampled colour, capture.matting_known.candidate_alpha,
#: times its confidence) against the upsampled alpha; 0 = the upsampled alpha alone.
REFINE_WEIGHT = 16
#: Margin (full-resolution pixels) around the trimap's unknown and opaque pixels that is solved.
CROP_PAD = 8
#: Trimap values (pymatting's convention, as capture.matting).
BG, UNKNOWN, FG = 0.0, 0.5, 1.0
#: A working pixel is sure (opaque or background) when this share of its footprint is (area average).
SURE_SHARE = 1.0 - 1e-6
#: Alpha from which a pixel is opaque: its colour is the image's.
OPAQUE_ALPHA = 1.0 - 1e-3


def object_box(trimap: np.ndarray, pad: int = CROP_PAD) -> tuple[slice, slice] | None:
    """(rows, cols) of the box around the trimap's unknown and opaque pixels (or a bool mask's True)
    grown by ``pad`` and clipped to the frame; None without any."""
    import cv2

    t = np.asarray(trimap)
    m = t if t.dtype == bool and t.flags.c_contiguous else t > BG  # a bool mask is its own ``> BG`` (round 14)
    x, y, w, h = cv2.boundingRect(m.view(np.uint8))
    if w == 0 or h == 0:
        return None
    H, W = np.shape(trimap)
    return (slice(max(0, y - pad), min(H, y + h + pad)), slice(max(0, x - pad), min(W, x + w + pad)))


def band_share(trimap: np.ndarray) -> float:
    """The share of the object's pixels (the trimap's unknown and opaque) that are unknown; 0 without any."""
    t = np.asarray(trimap)
    unk = np.count_nonzero(t == UNKNOWN)
    obj = unk + np.count_nonzero(t >= FG)
    return unk / obj if obj else 0.0


def working_scale(trimap: np.ndarray, depth_width: int | None = None, object_px: int = OBJECT_WORK_PX,
                  depth_oversample: float = DEPTH_OVERSAMPLE, solid_px: int = SOLID_WORK_PX) -> float:
    """The scale (<= 1) a view's matte is solved at (module docstring): the larger of ``object_px``
    (``solid_px`` for a solid object: :func:`band_share` at most SOLID_BAND_SHARE; 0: no such rule)
    over the object box's longer side and ``depth_oversample`` x ``depth_width`` over the image width;
    1 above FULL_SIZE_ABOVE, for no object, or ``object_px`` 0 (the full-size reference)."""
    box = object_box(trimap, 0)
    if box is None or object_px <= 0:
        return 1.0
    side = max(box[0].stop - box[0].start, box[1].stop - box[1].start)
    if 0 < solid_px < object_px and band_share(trimap) <= SOLID_BAND_SHARE:
        object_px = solid_px
    s = object_px / side
    if depth_width:
        s = max(s, depth_oversample * depth_width / np.shape(trimap)[1])
    return 1.0 if s > FULL_SIZE_ABOVE else float(s)


def _resize(a: np.ndarray, w: int, h: int, interpolation) -> np.ndarray:
    import cv2

    out = cv2.resize(np.ascontiguousarray(a, np.float32), (w, h), interpolation=interpolation)
    return out if out.ndim == np.ndim(a) else out[..., None]


def downscale_trimap(trimap: np.ndarray, w: int, h: int) -> np.ndarray:
    """(h, w) trimap of a (H, W) one: a working pixel is opaque (background) when its whole footprint
    is, otherwise unknown."""
    import cv2

    t = np.asarray(trimap)
    fg = _resize((t >= FG).astype(np.float32), w, h, cv2.INTER_AREA)
    bg = _resize((t <= BG).astype(np.float32), w, h, cv2.INTER_AREA)
    out = np.full((h, w), UNKNOWN)
    out[bg >= SURE_SHARE] = BG
    out[fg >= SURE_SHARE] = FG
    return out


def _box(a: np.ndarray, r: int) -> np.ndarray:
    import cv2

    out = cv2.boxFilter(a, -1, (2 * r + 1, 2 * r + 1), normalize=True, borderType=cv2.BORDER_REFLECT)
    return out if out.ndim == a.ndim else out[..., None]  # OpenCV drops a single channel


def guided_coefficients(guide: np.ndarray, target: np.ndarray, r: int = GUIDE_RADIUS,
                        eps: float = GUIDE_EPS, fast: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """The colour guided filter's mean coefficients (a (h, w, C, 3), b (h, w, C)) of ``target``
    (h, w, C) guided by ``guide`` (h, w, 3): q = a . I + b (He, Sun, Tang 2013, eq. 14-16, with the
    3x3 covariance of the guide in each window).  ``fast``: the 3x3 solves by
    capture.guided_kernel.solve_spd3 (within its SOLVE_RTOL of ``fast=False``, LAPACK's, the reference)."""
    I = np.asarray(guide, np.float64)
    p = np.asarray(target, np.float64)
    mI = _box(I, r)
    mp = _box(p, r)
    II = np.einsum("hwi,hwj->hwij", I, I).reshape(*I.shape[:2], 9)
    cov = _box(II, r).reshape(*I.shape[:2], 3, 3) - np.einsum("hwi,hwj->hwij", mI, mI)
    cov += eps * np.eye(3)
    Ip = np.einsum("hwi,hwc->hwci", I, p).reshape(*I.shape[:2], -1)
    cIp = _box(Ip, r).reshape(*p.shape, 3) - np.einsum("hwc,hwi->hwci", mp, mI)
    if fast:
        from capture.guided_kernel import solve_spd3

        a = solve_spd3(cov, cIp)                                           # (h, w, C, 3)
    else:
        a = np.linalg.solve(cov[:, :, None], cIp[..., None])[..., 0]
    b = mp - np.einsum("hwci,hwi->hwc", a, mI)
    C = p.shape[2]
    ma = _box(a.reshape(*I.shape[:2], C * 3), r).reshape(a.shape)
    return ma, _box(b, r)


def guided_upsample(guide_lo: np.ndarray, target_lo: np.ndarray, guide: np.ndarray, r: int = GUIDE_RADIUS,
                    eps: float = GUIDE_EPS) -> np.ndarray:
    """``target_lo`` (h, w, C) brought to the size of ``guide`` (H, W, 3) by the fast guided filter
    (module docstring): coefficients at (h, w), upsampled bilinearly, applied to ``guide``; (H, W, C)."""
    import cv2

    H, W = guide.shape[:2]
    a, b = guided_coefficients(guide_lo, target_lo, r, eps)
    C = b.shape[2]
    a_up = _resize(a.reshape(*a.shape[:2], C * 3), W, H, cv2.INTER_LINEAR).reshape(H, W, C, 3)
    b_up = _resize(b, W, H, cv2.INTER_LINEAR).reshape(H, W, C)
    return np.einsum("hwci,hwi->hwc", a_up, np.asarray(guide, np.float32)) + b_up


def _working_copy(img: np.ndarray, box, scale: float, background, known):
    """(crop in [0, 1], its working copy, (w, h), background and known at the working size or None)."""
    import cv2

    ci = np.clip(img[box], 0.0, 1.0)
    h_full, w_full = ci.shape[:2]
    w, h = max(1, round(w_full * scale)), max(1, round(h_full * scale))
    lo = _resize(ci, w, h, cv2.INTER_AREA)
    bg_lo = known_lo = None
    if background is not None:
        bg_lo = _resize(np.asarray(background, np.float32)[box], w, h, cv2.INTER_AREA)
        known_lo = _resize(np.asarray(known, np.float32)[box], w, h, cv2.INTER_AREA) >= SURE_SHARE
    return ci, lo, (w, h), bg_lo, known_lo


def guided_upsample_at(guide_lo: np.ndarray, target_lo: np.ndarray, guide: np.ndarray, where: np.ndarray,
                       r: int = GUIDE_RADIUS, eps: float = GUIDE_EPS) -> np.ndarray:
    """:func:`guided_upsample` at the ``where`` (H, W) pixels of ``guide`` only: (N, C)."""
    import cv2

    H, W = guide.shape[:2]
    a, b = guided_coefficients(guide_lo, target_lo, r, eps)
    C = b.shape[2]
    a_up = _resize(a.reshape(*a.shape[:2], C * 3), W, H, cv2.INTER_LINEAR)[where].reshape(-1, C, 3)
    b_up = _resize(b, W, H, cv2.INTER_LINEAR)[where].reshape(-1, C)
    return np.einsum("nci,ni->nc", a_up, np.asarray(guide, np.float32)[where]) + b_up


def matte_at_scale(image: np.ndarray, trimap: np.ndarray, solve, scale: float, background: np.ndarray | None = None,
                   known: np.ndarray | None = None):
    """(alpha (H, W) float32, foreground (H, W, 3) float32, the working solve's Matte) of linear
    ``image`` (H, W, 3) under ``trimap`` (H, W), solved at ``scale`` (module docstring) by
    ``solve(image, trimap, background, known) -> Matte`` (``background`` (H, W, 3) and ``known`` (H, W)
    bool: the known background, downscaled with the image; None when there is none).  Outside the
    box of the trimap's unknown and opaque pixels alpha is 0 and the colour is the image's.  A
    working trimap left without opaque pixels (an object thin all over) is solved at full size."""
    img = np.asarray(image, np.float32)
    H, W = trimap.shape
    if scale >= 1.0:
        m = solve(img, trimap, background, known)
        return np.asarray(m.alpha, np.float32), np.asarray(m.foreground, np.float32), m
    alpha = np.zeros((H, W), np.float32)
    fg = img.copy()
    box = object_box(trimap)
    if box is None:
        return alpha, fg, None
    ct = trimap[box]
    ci, lo, (w, h), bg_lo, known_lo = _working_copy(img, box, scale, background, known)
    tri_lo = downscale_trimap(ct, w, h)
    if np.any(ct >= FG) and not np.any(tri_lo >= FG):  # no footprint wholly opaque: thin all over
        return matte_at_scale(image, trimap, solve, 1.0, background, known)
    m = solve(lo, tri_lo, bg_lo, known_lo)
    target = np.concatenate([np.asarray(m.alpha, np.float32)[..., None], np.asarray(m.foreground, np.float32)], -1)
    up = guided_upsample(lo, target, ci)
    a = np.clip(up[..., 0], 0.0, 1.0)
    a[ct >= FG] = 1.0
    a[ct <= BG] = 0.0
    f = np.clip(up[..., 1:], 0.0, None)
    opaque = a >= OPAQUE_ALPHA
    f[opaque] = ci[opaque]
    alpha[box] = a
    fg[box] = np.where((a > 0)[..., None], f, img[box])
    return alpha, fg, m


def known_matte_at_scale(image: np.ndarray, trimap: np.ndarray, background: np.ndarray, known: np.ndarray,
                         noise: float, scale: float, box, mask: np.ndarray | None = None,
                         record: dict | None = None, chroma: bool = False,
                         coverage: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool] | None:
    """(alpha (h, w), straight colour F (h, w, 3), the full-resolution trimap solved, converged) of the
    known-background matte (capture.matting_known.known_background_matte's result on the crop ``box``
    of linear ``image`` (H, W, 3), ``trimap``, ``background`` (H, W, 3) known where ``known`` (H, W),
    ``noise``) solved at ``scale`` < 1 (module docstring); None when the working trimap keeps no
    opaque pixel (an object thin all over: solve it at full size).  ``mask`` (H, W): the object's
    depth, downscaled (area, half covered) for the prior where the photo is blown out
    (capture.matting_blind), whose record goes into ``record``; ``chroma``: the frame's chroma was subsampled
    (capture.matting_known.alpha_lower_bound); ``coverage``: the depth-opaque sources' measured coverage
    (capture.matting_sources.capture_coverage; None: opaque)."""
    import cv2

    from capture.matting_channels import colour_bound
    from capture.matting_known import (
        CLIP_LEVEL,
        alpha_lower_bound,
        blown_bound,
        clipped,
        known_background_matte,
        solve_trimap,
    )

    img = np.asarray(image, np.float32)
    ct = np.asarray(trimap)[box]
    ci, lo, (w, h), bg_lo, known_lo = _working_copy(img, box, scale, background, known)
    tri_lo = downscale_trimap(ct, w, h)
    if np.any(ct >= FG) and not np.any(tri_lo >= FG):
        return None
    mask_lo = None if mask is None else \
        _resize(np.asarray(mask, np.float32)[box], w, h, cv2.INTER_AREA) >= 0.5
    a_lo, f_lo, _, ok = known_background_matte(lo, tri_lo, bg_lo, known_lo, noise, mask_lo, record, chroma=chroma,
                                               coverage=coverage)
    B = np.clip(np.asarray(background, np.float32)[box], 0.0, 1.0)
    given = np.asarray(known, bool)[box]
    sure = given & ~clipped(ci, B)
    tri, _ = solve_trimap(ct, ci, B, sure, noise, chroma)  # the full-resolution trimap the fast path is held to
    # the guided filter where alpha is open (the band); elsewhere alpha is the trimap's and the colour
    # (alpha 0: the object's colour extended; opaque: the pixel's own) the working one, bilinear
    band = tri == UNKNOWN
    target = np.concatenate([np.asarray(a_lo, np.float32)[..., None], np.asarray(f_lo, np.float32)], -1)
    up = guided_upsample_at(lo, target, ci, band)
    f_up = np.clip(_resize(np.asarray(f_lo, np.float32), *ci.shape[1::-1], cv2.INTER_LINEAR), 0.0, 1.0)
    f_up[band] = np.clip(up[:, 1:], 0.0, 1.0)
    a = np.zeros(ct.shape, np.float32)
    a[band] = np.clip(up[:, 0], 0.0, 1.0)
    open_ = band & sure
    lower = np.zeros(ct.shape, np.float32)
    lower[open_] = alpha_lower_bound(ci, B, noise, True)[open_] if chroma else \
        alpha_lower_bound(ci[open_], B[open_], noise)
    if REFINE_WEIGHT > 0:
        a = _refine_known(a, ci, B, f_up, lower, open_, ct >= FG, sure, scale, coverage)
    # the full-size path's alpha floor where the plate is blown out and the photo is not
    a = np.maximum(np.maximum(a, lower), blown_bound(ci, B, band & given & ~sure, noise, chroma))
    a = np.maximum(a, colour_bound(ci, B, f_up, band & given & ~sure, CLIP_LEVEL, noise))  # capture.matting_channels
    a[tri <= BG] = 0.0
    a[tri >= FG] = 1.0
    F = _full_colour(ci, a, B, given, f_up, record)
    return a.astype(np.float32), F, tri, ok


def _refine_known(a: np.ndarray, image: np.ndarray, background: np.ndarray, f_up: np.ndarray, lower: np.ndarray,
                  where: np.ndarray, opaque: np.ndarray, known: np.ndarray, scale: float,
                  coverage: float | None = None) -> np.ndarray:
    """The upsampled alpha ``a`` (h, w) pulled, at the ``where`` pixels (known background, unknown),
    towards each pixel's own alpha from the compositing equation by REFINE_WEIGHT x its confidence.
    The candidates and the rule that picks one are the full-size path's (step 2 of
    capture.matting_known: :func:`~capture.matting_known.colour_sources`, the depth's ``opaque``
    pixels and those whose bound is above SOURCE_ALPHA, only where the background is ``known``;
    :func:`~capture.matting_known.fit_candidates`, the nearest sure colour, filled outwards by a
    push-pull pyramid from ``scale``, before the palette of the sure colours, which wins only by
    PALETTE_MARGIN), with the upsampled colour ``f_up`` one more candidate behind the same margin; the sources
    unmixed at their measured ``coverage`` (capture.matting_sources.capture_coverage; None: opaque)."""
    import cv2

    from capture.fill import push_pull
    from capture.matting_known import candidate_alpha, colour_sources, fit_candidates
    from capture.matting_sources import source_colours

    if not where.any():
        return a
    src = colour_sources(opaque, known, lower)
    image_src = source_colours(image, background, lower, src, known, coverage)  # the image itself at coverage 1
    C, B, lo = image[where][:, None], background[where][:, None], lower[where][:, None]
    if src.any():
        h, w = a.shape
        lo_w, lo_h = max(1, round(w * scale)), max(1, round(h * scale))
        wt = _resize(src.astype(np.float32), lo_w, lo_h, cv2.INTER_AREA)
        v = _resize(image_src * src[..., None], lo_w, lo_h, cv2.INTER_AREA) / np.maximum(wt, 1e-6)[..., None]
        near = _resize(np.asarray(push_pull(v, np.minimum(wt, 1.0)), np.float32), w, h, cv2.INTER_LINEAR)
        near = np.where(src[..., None], image_src, near)
        a_px, conf = fit_candidates(C, B, near[where][:, None], image_src[src], lo, [f_up[where][:, None]])
    else:
        a_px, conf = candidate_alpha(C, B, f_up[where][None, :, None], lo)
    wgt = REFINE_WEIGHT * conf[:, 0]
    out = a.copy()
    out[where] = (a[where] + wgt * a_px[:, 0]) / (1.0 + wgt)
    return out


def _full_colour(image: np.ndarray, a: np.ndarray, background: np.ndarray, known: np.ndarray,
                 f_up: np.ndarray, record: dict | None = None) -> np.ndarray:
    """(h, w, 3) straight colour at full resolution (capture.matting_known.foreground_colour's rules):
    F = B + (C - B) / alpha exactly where the background is ``known``, not blown out and alpha > 0;
    an opaque pixel of unknown background, or in the object's interior before a blown-out one
    (capture.matting_interior), its own colour; everywhere else (the background not known or blown
    out, alpha 0) the working solve's colour ``f_up``, brought up by the guided filter (the working
    solve made it by the same rules: pymatting's foreground, the fills of the nearest sure colours).
    ``record`` gets capture.matting_interior's count at full size."""
    from capture.matting_full_colour import full_colour
    from capture.matting_interior import interior, unseen_fill
    from capture.matting_known import CLIP_LEVEL, clipped
    from capture.matting_known import OPAQUE_ALPHA as KNOWN_OPAQUE

    inner = interior(image, a, background, known, KNOWN_OPAQUE, CLIP_LEVEL, record)  # the interior: its photo
    if (fused := full_colour(image, a, background, known, f_up, CLIP_LEVEL, KNOWN_OPAQUE)) is not None:
        out = np.where(inner[..., None], image, fused) if inner.any() else fused
        return unseen_fill(out, image, a, background, known, None, record)  # the unseen band before a window
    blown = known & clipped(image, background) & (a > 0)
    ok = known & ~blown & (a > 0)
    F = np.clip(background + (image - background) / np.maximum(a, 1e-6)[..., None], 0.0, 1.0)
    own = (a >= KNOWN_OPAQUE) & ~ok & (~blown | inner)
    return unseen_fill(np.where(ok[..., None], F, np.where(own[..., None], image, f_up)), image, a, background, known,
                       blown, record)

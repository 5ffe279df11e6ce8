"""Frames blurred where the others are sharp, found by the fixed camera's background plate (issue 30;
capture.plate.background_plates; volume/surroundings.py says so, and leaves them out with ``--blurred-views
'leave out'``).

A shaken frame's photo is its sharp self convolved with a kernel, its background too.  Every sixth frame of the
path-traced conifer (room, table, auto exposure, lens) blurred, colour and matte, along a line 2 % of the width
(``scripts/broken_captures.py CAPTURE OUT blur``: every third view ``furrow eval --holdout 2`` keeps) cost the
held-out views beside them 7.7-8.9 dB (26.41 -> 22.40 over all): the blurred matte spreads the needles over the
blown-out sky, and the colour unmixed there is the sky's.  No check said a word.  Blurring the plate to match each
photo (the kernel below applied to it) gave back 0.09 dB: the blurred views themselves are the fault; left out, the
conifer came back to 25.80, while the same blur on a fur ball before the room cost 1.06 dB more left out than kept
(its held-out views then 40 degrees from a kept one).  So the default says so and keeps them (docs/matting.md).

The test (:func:`view_kernel`): the kernel k with photo ~ k * plate (one for the three channels, (2 r + 1)^2 taps,
r = :data:`RADIUS` x the width / 640), fitted by least squares (ridge :data:`RIDGE`) over up to :data:`PATCHES`
squares of the view's sure background near its object, not blown out, the plate there the fixed camera's robust
mode of the other frames (capture.plate_fixed.fixed_prediction; leave one out, as the held-back ring is); fitted on
every other pixel, judged on the rest.  A sharp view's kernel is about one tap and gains nothing (held-back RMS
1.02-1.15 times the plate's own on the conifer's 12 sharp kept views); a blurred one's falls to 0.15-0.57 of it.  A
view is blurred where it falls to :data:`BLURRED` or less.  A background without light (a black room) is not tested,
nor the moving camera's plates (panorama: their draw is dearer; not measured).
"""

from __future__ import annotations

import numpy as np

#: Half the kernel's width at 640 pixels (scaled with the width).
RADIUS = 5
#: Views wider than this are not tested (the kernel's taps grow as the square of the width).
MAX_WIDTH = 1280
#: The plate is drawn for the fit over at most PATCHES squares of PATCH pixels (at 640 wide) of sure background,
#: each at least PATCH_SHARE of it, not blown out in the photo (their pixels, half to fit and half to judge).
PATCHES = 10
PATCH = 32
PATCH_SHARE = 0.8
#: Ridge weight of the taps (times the mean of the normal matrix's diagonal).
RIDGE = 1e-3
#: A view is blurred where the kernel's held-back RMS is at most this times the plate's own.
BLURRED = 0.8
#: Sure background pixels within this fraction of the width of the object's depth are sampled.
NEAR_FRACTION = 0.15
#: A plate whose mean square over the samples is under this (linear^2) is not fitted (a black room).
TEXTURE_FLOOR = 1e-8
#: Fewer samples than this times the taps: nothing tested.
MIN_PER_TAP = 10


def window_offsets(r: int) -> tuple[np.ndarray, np.ndarray]:
    """(dy, dx) of a (2r+1)^2 window, row by row."""
    dy, dx = np.mgrid[-r:r + 1, -r:r + 1]
    return dy.ravel(), dx.ravel()


def fit_kernel(photo: np.ndarray, plate: np.ndarray, ys: np.ndarray, xs: np.ndarray, r: int) -> dict | None:
    """The (2r+1, 2r+1) kernel k with ``photo`` ~ k * ``plate`` ((H, W, 3) each; the plate finite over every
    window) at the pixels (ys, xs), fitted on every other, judged on the rest: {kernel, rms_plate (as drawn),
    rms_blurred} over the held-back pixels and channels; None where the plate's mean square is under TEXTURE_FLOOR
    (a black room)."""
    dy, dx = window_offsets(r)
    A = np.moveaxis(plate[ys[:, None] + dy, xs[:, None] + dx], 1, 2).astype(np.float64)  # (n, 3, taps)
    c = np.asarray(photo, np.float64)[ys, xs]                                               # (n, 3)
    Af, cf = A[0::2].reshape(-1, A.shape[2]), c[0::2].reshape(-1)
    N = Af.T @ Af
    scale = float(np.mean(np.diag(N)))
    if not scale > TEXTURE_FLOOR * len(Af):  # a background without light or texture says nothing of a blur
        return None
    N[np.diag_indices_from(N)] += RIDGE * scale
    k = np.linalg.solve(N, Af.T @ cf)
    held = c[1::2]

    def rms(d):
        return float(np.sqrt(np.mean(d * d)))

    return {"kernel": k.reshape(2 * r + 1, 2 * r + 1), "rms_plate": rms(A[1::2, :, A.shape[2] // 2] - held),
            "rms_blurred": rms(A[1::2] @ k - held)}


def _patches(object_depth: np.ndarray, photo: np.ndarray, r: int, clip: float) -> tuple[list, np.ndarray]:
    """((row, column, side) of up to PATCHES squares of PATCH x the width / 640 pixels, each of them for the most
    part (PATCH_SHARE) sure background (capture.plate.source_mask) not blown out in the photo, within NEAR_FRACTION of
    the width of the object and r from the frame's edges, evenly among those that qualify; the pixels that qualify
    (H, W))."""
    import cv2

    from capture.matting_fast import dilate
    from capture.plate import px, source_mask

    H, W = np.shape(object_depth)
    use = source_mask(object_depth) & dilate(np.asarray(object_depth) > 0, px(NEAR_FRACTION, W)) & \
        (np.asarray(photo, np.float32).max(axis=-1) < clip)
    P = max(8, int(round(PATCH * W / 640)))
    share = cv2.boxFilter(use.astype(np.float32), -1, (P, P), normalize=True, anchor=(0, 0),
                          borderType=cv2.BORDER_CONSTANT)
    cand = [(y, x) for y in range(r, H - r - P + 1, P) for x in range(r, W - r - P + 1, P)
            if share[y, x] >= PATCH_SHARE]
    if len(cand) > PATCHES:
        cand = [cand[k] for k in np.linspace(0, len(cand) - 1, PATCHES).round().astype(np.int64)]
    return [(y, x, P) for y, x in cand], use


def view_kernel(ps, gains: np.ndarray, j: int) -> tuple[dict | None, dict]:
    """(:func:`fit_kernel`'s answer or None, the record: ``blurred``, the held-back RMS ``ratio``) of view ``j`` of
    the PlateSet ``ps`` (exposure ``gains``): its plate from the other frames over its patches and their windows."""
    from capture.matting_known import CLIP_LEVEL
    from capture.plate_fixed import FIXED_RING_FRAMES, fixed_prediction, in_view, mode_frames

    p = ps.views[j]
    H, W = np.shape(p.view.object_depth)
    if W > MAX_WIDTH:
        return None, {"blurred": False, "reason": f"wider than {MAX_WIDTH} pixels"}
    r = max(1, int(round(RADIUS * W / 640)))
    patches, use = _patches(p.view.object_depth, p.view.linear, r, CLIP_LEVEL)
    grid = np.zeros((H, W), bool)
    for y, x, P in patches:
        grid[y - r:y + P + r, x - r:x + P + r] = True
    gy, gx = np.nonzero(grid)
    views, weights = [q.view for q in ps.views], [q.weight for q in ps.views]
    img = np.full((H, W, 3), np.nan, np.float32)
    if len(gy):  # the plate's own robust mode of the other frames (leave one out, as its held-back ring)
        img[gy, gx] = in_view(*fixed_prediction(views, np.stack([gx, gy], axis=1), j, gains, weights,
                                                mode_frames(len(views), j, FIXED_RING_FRAMES)), gains[j])
    dy, dx = window_offsets(r)
    inner = np.zeros((H, W), bool)
    for y, x, P in patches:
        inner[y:y + P, x:x + P] = True
    ys, xs = np.nonzero(inner & use)
    win = img[ys[:, None] + dy, xs[:, None] + dx]
    with np.errstate(invalid="ignore"):  # the window seen by the other frames, nothing blown out in it
        ok = np.isfinite(win).all(axis=(1, 2)) & (np.nan_to_num(win, nan=1.0).max(axis=(1, 2)) < CLIP_LEVEL)
    ys, xs = ys[ok], xs[ok]
    if len(ys) < MIN_PER_TAP * (2 * r + 1) ** 2:
        return None, {"blurred": False, "reason": "too few background pixels, not blown out, that the other frames saw"}
    fit = fit_kernel(p.view.linear, img, ys, xs, r)
    if fit is None:
        return None, {"blurred": False, "reason": "a background without light"}
    ratio = fit["rms_blurred"] / max(fit["rms_plate"], 1e-12)
    return fit, {"blurred": bool(ratio <= BLURRED), "ratio": round(ratio, 4), "rms_plate": round(fit["rms_plate"], 5),
                 "samples": int(len(ys))}


def blurred_views(ps, gains: np.ndarray) -> list[dict]:
    """Per view of the PlateSet ``ps`` (the fixed camera's, with its ``gains``) :func:`view_kernel`'s record."""
    from capture.plate_threads import thread_map

    return list(thread_map(lambda j: view_kernel(ps, gains, j)[1], range(len(ps.views))))

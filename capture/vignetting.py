"""A lens's vignetting under a moving camera, measured on the background the views share, and taken out.

An uncorrected lens darkens its image towards the corners: the linear colour is the scene's times v(r), r the
distance from the principal point over the half-diagonal.  A fixed camera sees each point of the room at the same
pixel in every frame, so its plate carries the same v and nothing can be measured from it.  A moving camera sees a
patch of the room at one place in one frame and elsewhere in the next, and the panorama plate (capture.plate_reproject)
draws view i's background from its neighbours' pixels at other radii: with half a stop at the corners (0.7, the
``vignette`` copy of scripts/broken_captures.py) the path-traced conifer orbit lost **1.1 dB** held out (27.49 ->
26.40, SSIM 0.664 -> 0.618) and nothing was said; docs/real_cameras.md, "Vignetting".

**Measured** (:func:`vignetting_check`, the panorama path of capture.plate.background_plates): every ring pixel of
view i (the held-back background beside the object) that a neighbour j saw as background (the panorama's own
samples: capture.plate_reproject.first_samples, and the pixel of j each came from) gives, in grey (the mean of the
channels), both colours within the gain fit's range (capture.plate's ``_usable``),

    log c_j - log c_i = u_j - u_i + f(r_j) - f(r_i),    f(r) = log v(r) = b1 r^2 + b2 r^4,

u the views' log exposures (free).  Least squares with Huber weights (VIGNETTE_HUBER, VIGNETTE_PASSES).
**Judged** on held-back pixels: both models (exposures alone; exposures and f) are fitted on every other ring pixel
and scored on the rest by their Huber loss, pair of views by pair; the vignette is taken where the mean gain over the
pairs is at least VIGNETTE_Z standard errors, v changes by at least VIGNETTE_MIN somewhere on r in [0, 1], v stays
within VIGNETTE_RANGE, and the even views alone and the odd views alone find the same v (VIGNETTE_AGREE: one lens; the
200-view phone plant's 1 % fit had z 7.3).  Else the frames stay as they are and the record says why.
**Applied**: every frame's linear colour divided by v (:func:`devignette_set`: the plate's views, before their
exposures are fitted; :func:`devignette_view`: the scans the matte and every later stage read,
volume/surroundings.py).
"""

from __future__ import annotations

import numpy as np

#: Ring pixels of a view the check reads (an even subsample of capture.plate's ring).
VIGNETTE_RING_PIXELS = 1000
#: Least ring pixels seen by a neighbour for a fit.
VIGNETTE_MIN_ROWS = 500
#: Least views' pairs with held-back pixels for a verdict.
VIGNETTE_MIN_PAIRS = 8
#: Least held-back pixels of a pair for its share of the verdict.
VIGNETTE_MIN_PIXELS = 20
#: The vignette is taken from this many standard errors of the held-back pairs' mean gain.
VIGNETTE_Z = 5.0
#: ... and where v differs from 1 by at least this somewhere on r in [0, 1] (a lens within 3 % is left alone).
VIGNETTE_MIN = 0.03
#: ... and where v stays within this range on r in [0, 1] (else the fit is not a lens's).
VIGNETTE_RANGE = (0.3, 1.5)
#: ... and where the even views' fit and the odd views' agree to within this share of log v's largest size (one
#: lens in every frame: vignetted orbits 0.003, right captures' 1-3 % fits 0.36-1.3).
VIGNETTE_AGREE = 0.25
#: Huber threshold of the log residuals, and the reweighting passes.
VIGNETTE_HUBER = 0.05
VIGNETTE_PASSES = 3
#: Powers of r^2 in f (r^2, r^4).
VIGNETTE_TERMS = 2


def radius2(cam, uv: np.ndarray) -> np.ndarray:
    """(N,) r^2 of pixels ``uv`` (N, 2) of ``cam``: the squared distance from the principal point over the squared
    half-diagonal of the image (OpenCV pixel centres)."""
    uv = np.asarray(uv, np.float64)
    half2 = ((cam.width - 1) / 2) ** 2 + ((cam.height - 1) / 2) ** 2
    return ((uv[:, 0] - cam.K[0, 2]) ** 2 + (uv[:, 1] - cam.K[1, 2]) ** 2) / half2


def vignette(coef, r2: np.ndarray) -> np.ndarray:
    """v at squared radii ``r2``: exp(sum_k coef[k] r2^(k + 1))."""
    r2 = np.asarray(r2, np.float64)
    return np.exp(sum(float(c) * r2 ** (k + 1) for k, c in enumerate(coef)))


def vignette_map(cam, coef) -> np.ndarray:
    """(H, W) float32 v over ``cam``'s pixels."""
    y, x = np.mgrid[0:cam.height, 0:cam.width]
    return vignette(coef, radius2(cam, np.stack([x.ravel(), y.ravel()], 1))).reshape(cam.height, cam.width) \
        .astype(np.float32)


def devignette_linear(linear: np.ndarray, cam, coef) -> np.ndarray:
    """``linear`` (H, W, 3) divided by v, in place (returned)."""
    linear /= vignette_map(cam, coef)[..., None].astype(linear.dtype)
    return linear


def devignette_view(scan, k, coef):
    """Per view (capture.view_map): the scan with its linear colour divided by v (8-bit sRGB stays 8-bit, re-encoded
    and clipped; float stays float)."""
    from capture.scan import Scan, to_uint8_srgb

    lin = devignette_linear(np.array(scan.linear_rgb, np.float32), scan.camera, coef)
    rgb = to_uint8_srgb(lin) if scan.rgb.dtype == np.uint8 else lin
    return Scan(rgb, scan.depth, scan.camera, scan.name, scan.alpha), None


def ring_rows(ps) -> dict:
    """The equations' rows of a capture.plate.PlateSet (module docstring): y, r2 in i and in j, views i and j,
    pair index and held back (every other ring pixel) as arrays."""
    from capture.plate import _usable
    from capture.plate_reproject import background_points, first_samples, neighbour_order, panorama_sources

    src = panorama_sources(ps, np.ones((len(ps.views), 3)))
    rows = {k: [] for k in ("y", "ri", "rj", "i", "j", "pair", "held")}
    for i, p in enumerate(ps.views):
        cam, nb = p.view.camera, neighbour_order(ps.cameras, i, ps.neighbours)
        sub = np.unique(np.linspace(0, len(p.ring) - 1, min(len(p.ring), VIGNETTE_RING_PIXELS)).round().astype(int))
        ring, obs, kinds = p.ring[sub], np.asarray(p.observed, np.float64)[sub], np.full(len(sub), -1)
        s = first_samples(cam, ring, np.ones(3), [src[j] for j in nb], ps.plane, p.room, kinds=kinds)
        pts = np.zeros((len(ring), 3))
        for h, (_, hp, _) in enumerate(background_points(cam, ring, ps.plane, p.room)):
            pts[kinds == h] = hp[kinds == h]
        ok_i = _usable(obs) & (kinds >= 0)
        ri, held = radius2(cam, ring), np.arange(len(ring)) % 2 == 1
        for k, j in enumerate(nb):
            ok = ok_i & np.isfinite(s[k]).all(axis=1) & _usable(np.nan_to_num(s[k]))
            if not ok.any():
                continue
            uv, _ = src[j].camera.project(pts[ok])
            n = int(ok.sum())
            for key, val in (("y", np.log(s[k][ok].astype(np.float64).mean(1)) - np.log(obs[ok].mean(1))),
                             ("ri", ri[ok]), ("rj", radius2(src[j].camera, uv)), ("i", np.full(n, i)),
                             ("j", np.full(n, j)), ("pair", np.full(n, len(rows["pair"]))), ("held", held[ok])):
                rows[key].append(val)
    return {k: np.concatenate(v) if v else np.zeros(0) for k, v in rows.items()}


def fit(rows: dict, V: int, terms: int, use: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(coef (terms,), u (V,)) of the rows ``use`` (default all) by Huber-reweighted least squares, sum u = 0: the
    normal equations summed per view by ``np.bincount`` (each row has +1 at u_j, -1 at u_i, and the terms)."""
    use = np.ones(len(rows["y"]), bool) if use is None else use
    y, i, j = rows["y"][use], rows["i"][use].astype(np.int64), rows["j"][use].astype(np.int64)
    R = np.stack([rows["rj"][use] ** (k + 1) - rows["ri"][use] ** (k + 1) for k in range(terms)], 1) \
        if terms else np.zeros((len(y), 0))
    w, x = np.ones(len(y)), np.zeros(V + terms)
    for _ in range(1 + VIGNETTE_PASSES):
        x = np.linalg.lstsq(*_normal(i, j, R, w, y, V), rcond=None)[0]
        r = np.abs(x[j] - x[i] + R @ x[V:] - y)
        w = np.where(r <= VIGNETTE_HUBER, 1.0, VIGNETTE_HUBER / np.maximum(r, 1e-12))
    return x[V:], x[:V]


def _normal(i, j, R, w, y, V: int) -> tuple[np.ndarray, np.ndarray]:
    """(A^T W A + the gauge's row of ones, A^T W y) of the rows (views ``i``, ``j``, terms ``R``, weights ``w``)."""
    P = R.shape[1]
    M, b = np.zeros((V + P, V + P)), np.zeros(V + P)
    M[:V, :V] = -np.bincount(i * V + j, w, V * V).reshape(V, V)
    M[:V, :V] += M[:V, :V].T
    M[:V, :V] += np.diag(np.bincount(i, w, V) + np.bincount(j, w, V)) + 1.0  # + 1: the gauge sum u = 0
    for k in range(P):
        M[:V, V + k] = M[V + k, :V] = np.bincount(j, w * R[:, k], V) - np.bincount(i, w * R[:, k], V)
    M[V:, V:] = R.T @ (w[:, None] * R)
    b[:V] = np.bincount(j, w * y, V) - np.bincount(i, w * y, V)
    b[V:] = R.T @ (w * y)
    return M, b


def _loss(rows: dict, coef: np.ndarray, u: np.ndarray, use: np.ndarray) -> np.ndarray:
    """Huber loss of each row ``use`` under (coef, u)."""
    f = vignette(coef, rows["rj"][use]) / vignette(coef, rows["ri"][use]) if len(coef) else 1.0
    r = np.abs(u[rows["j"][use].astype(np.int64)] - u[rows["i"][use].astype(np.int64)] + np.log(f) - rows["y"][use])
    return np.where(r <= VIGNETTE_HUBER, 0.5 * r * r, VIGNETTE_HUBER * (r - 0.5 * VIGNETTE_HUBER))


def held_back_z(rows: dict, V: int) -> tuple[float, int]:
    """(z of the held-back pairs' mean gain in Huber loss, vignette against exposures alone; pairs judged)."""
    train, test = ~rows["held"].astype(bool), rows["held"].astype(bool)
    losses = [_loss(rows, *fit(rows, V, t, train), test) for t in (0, VIGNETTE_TERMS)]
    pair = rows["pair"][test].astype(np.int64)
    cnt = np.bincount(pair)
    keep = cnt >= VIGNETTE_MIN_PIXELS
    gain = np.bincount(pair, losses[0] - losses[1])[keep] / cnt[keep]
    if len(gain) < VIGNETTE_MIN_PAIRS or not np.std(gain) > 0:
        return float("nan"), len(gain)
    return float(gain.mean() / (gain.std(ddof=1) / np.sqrt(len(gain)))), len(gain)


def vignetting_check(ps) -> tuple[np.ndarray | None, dict]:
    """(coef to divide the frames by, or None; record) of a moving camera's PlateSet (module docstring)."""
    V = len(ps.views)
    rows = ring_rows(ps)
    if len(rows["y"]) < VIGNETTE_MIN_ROWS:
        return None, {"applied": False, "pixels": int(len(rows["y"])),
                      "reason": f"{len(rows['y'])} ring pixels seen by a neighbour (under {VIGNETTE_MIN_ROWS})"}
    z, pairs = held_back_z(rows, V)
    if not np.isfinite(z):
        return None, {"applied": False, "pixels": int(len(rows["y"])), "pairs": pairs,
                      "reason": f"{pairs} pairs of views with {VIGNETTE_MIN_PIXELS} held-back pixels (under "
                                f"{VIGNETTE_MIN_PAIRS})"}
    coef, _ = fit(rows, V, VIGNETTE_TERMS)
    r2 = np.linspace(0.0, 1.0, 11)
    v = vignette(coef, r2)
    half = [vignette(fit(rows, V, VIGNETTE_TERMS, rows["i"] % 2 == k)[0], r2) for k in (0, 1)]  # even, odd views
    apart = float(np.abs(np.log(half[0] / half[1])).max()) if np.isfinite(half).all() else np.inf
    rec = {"coefficients": [round(float(c), 6) for c in coef], "z": round(z, 2), "pairs": pairs,
           "pixels": int(len(rows["y"])), "corner": round(float(v[-1]), 4) if np.isfinite(v[-1]) else None,
           "halves": [round(float(h[-1]), 4) if np.isfinite(h[-1]) else None for h in half]}
    if z < VIGNETTE_Z:
        return None, {**rec, "applied": False, "reason": f"no better than none on held-back pixels (z {z:.1f})"}
    if np.abs(v - 1.0).max() < VIGNETTE_MIN:
        return None, {**rec, "applied": False, "reason": f"within {VIGNETTE_MIN:.0%} of flat"}
    if not np.isfinite(v).all() or v.min() < VIGNETTE_RANGE[0] or v.max() > VIGNETTE_RANGE[1]:
        return None, {**rec, "applied": False, "reason": f"v from {v.min():.2f} to {v.max():.2f}: not a lens's"}
    if apart > VIGNETTE_AGREE * np.abs(np.log(v)).max():  # one lens: the even and the odd views must find it
        return None, {**rec, "applied": False, "reason": f"the even and the odd views disagree (corners at "
                      f"{half[0][-1]:.2f} and {half[1][-1]:.2f}): not one lens's"}
    return coef, {**rec, "applied": True,
                  "reason": f"the corners at {v[-1]:.2f} of the centre (z {z:.1f} on {pairs} pairs' held-back pixels)"}


def devignette_set(ps, coef):
    """The PlateSet ``ps`` with every view's colour and its ring's observed colours divided by v (new arrays: the
    caller's views stay as they were)."""
    from dataclasses import replace

    return replace(ps, views=tuple(
        replace(p, view=replace(p.view, linear=devignette_linear(np.array(p.view.linear), p.view.camera, coef)),
                observed=p.observed / vignette(coef, radius2(p.view.camera, p.ring))[:, None]) for p in ps.views))


def measured(ps, mode: str, cfg, trials: dict):
    """For capture.plate.background_plates: (the PlateSet, the vignetting's record) where ``mode`` is 'panorama' and
    ``cfg.vignetting`` (capture.plate.PlateConfig) 'auto', else (``ps``, None); where v is applied, the set's views
    are divided by it (:func:`devignette_set`) and ``trials[mode]`` is predicted again (the path's first trial)."""
    if mode != "panorama" or getattr(cfg, "vignetting", "off") != "auto":
        return ps, None
    from capture.plate import ring_trial

    coef, rec = vignetting_check(ps)
    if coef is not None:
        ps = devignette_set(ps, coef)
        trials[mode] = ring_trial(ps, mode)
    return ps, rec

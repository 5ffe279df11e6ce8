"""The colour across the views in bounded memory (issue 30 seventh round, issue 32's bounds).

capture.matting_lines.cell_colours crosses the lines of every view's partial pixels at once: the
matte stage's views hand back all of them (about 65 bytes a pixel) and the main process concatenates
them in float64.  On 18 views of 640 x 480 that is 40 MB; on 200 views of 1920 x 1440 (6.4 % of the
pixels partial) 2.3 GB of samples and 4 GB more of concatenation.  Here the same step runs in two
passes whose memory does not grow with views x pixels:

1. **Fit** (:func:`fit_sample`, :func:`fit_cells`): each view hands back at most :func:`fit_cap` of
   its partial pixels' lines (a seeded draw, in their pixel order; all of them when fewer), float32,
   and the bounds of all its partial pixels' 3D points.  The main process crosses the lines of each
   cube (capture.matting_lines.group_fit) and keeps the table: each cube's colour F and expected
   squared error sigma^2 (at most CELLS_PER_EXTENT^3 cubes).  The cubes tile the bounds of every
   partial pixel of every view (:func:`cell_grid`), what both passes know whatever was drawn.
2. **Apply** (:func:`apply_cells`): each view recomputes its own partial pixels' samples
   (capture.matting_lines.line_samples, in the matte stage's per-view map) and applies the same
   gate and assignment as cell_colours.

Where nothing is drawn (every view under its cap: the 18-view 640 x 480 captures) the two passes give
the same colours as cell_colours, bit for bit (tests/capture/test_matting_cells.py).

A pixel given its cube's colour F_c gets the alpha its line implies, imp, and so the premultiplied colour imp F_c:
the photo's part across the line, r = (C - B) - imp (F_c - B), was dropped.  :func:`across_line` (KEEP_ACROSS, both
paths) puts back the share of r that the plate's uncertainty allows: all of it where a frame saw the background
(r is then the needles' own colour about their cube's), none where it is the plate's guess or unknown.
"""

from __future__ import annotations

import numpy as np

from capture.matting_global import cross_cells, filled, with_object_colour
from capture.matting_lines import CELL_LINE_ALPHA, CELLS_PER_EXTENT, MIN_LINES, _implied, line_alpha, line_weights

#: Most partial pixels a view hands back for the fit.  Above the partial pixels of the 640 x 480 views of
#: the conifer captures (35-40k a view on average; on the turntable and AE + lens runs every line was
#: fitted: docs/matting.md seventh round), so that their result is unchanged; a 1920 x 1440 phone view
#: has about 100k.
MAX_FIT_LINES_PER_VIEW = 1 << 17
#: Most partial pixels crossed at once across the views: each view's cap is at most this over the number
#: of views (:func:`fit_cap`).  The fit holds about 400 bytes a line at its peak (float64 terms of
#: capture.matting_lines.group_fit): 1.5M lines about 0.6 GB.  The 18-view captures (about 40k partial
#: pixels a view, 0.73M at most in all) are not drawn from.
MAX_FIT_LINES = 1_500_000
#: The seed of the draw (with the view's position).
FIT_SEED = 30
#: Background at least this bright (linear, Euclidean) for a line to cross (:func:`band_crossing`):
#: a partial pixel before a black background has C = a F, its line passes through 0 like every other
#: such line, and its unmixed colour's premultiplied error (a - a_true) B vanishes with B.
CROSSING_DARK = 0.03
#: ... and at least this times the object's own median brightness (the depth's sure pixels): where
#: |B| is below |F| the unmixed colour's premultiplied error (a - a_true) B is below what the cube's
#: colour errs by, a (F_cell - F) + (a - a_true) F.
CROSSING_OVER = 1.0
#: Every this-th sure object pixel for the object's brightness.
OBJECT_STRIDE = 7
#: The colour across the views runs (``--matte-across auto``) only where the views' mean
#: :func:`band_crossing` (the plate record's ``band_crossing_mean``) reaches this.  Measured (issue 32,
#: round 7; the kept views 0::2, docs/speed.md): the 24-view phone capture (black room, striped table;
#: the fixed plate, its default, sees the black and estimates the table) 0.010 (0.000-0.021 a view),
#: held out no gain; the conifer room turntable 0.366, room + table + AE + lens 0.123, orbit 0.665, the
#: fur before similar bricks 0.161.  Missed: the same phone capture with ``--plate panorama`` (the table
#: seen from the other views) 0.183, held out no gain either (+0.001 dB): it still runs there.
MIN_CROSSING = 0.05
#: The colour across the views gives no pixel its cube's colour where fewer than MIN_AGREEING of the partial
#: pixels' lines agree with the matte's alpha (capture.matting_contrast.agreeing_lines, the record's
#: ``global.agreeing.share``): the lines do not point at one colour, the step's premise (AGREEING_GATE; False:
#: the rule before).  Measured (docs/speed.md round 20): 0.40 and 0.58 on the two phone captures, where the
#: step gains nothing held out (-0.009 dB in a room), 0.84-0.995 on every path-traced capture, where it gains
#: 0.2-0.4 dB on the conifers.  The threshold was set before the two captures made to check it were measured.
MIN_AGREEING = 0.7
AGREEING_GATE = True
#: The gate reads the lines' agreement before any crossing (:func:`agreeing_before`: the first pass's share, the
#: same lines, weights and colours), so that a capture it skips does not cross its cubes at all (issue 32 round
#: 21: 1.5 s of the 72-view phone capture).  False: the rule before, the share of the last pass's record.
AGREEING_BEFORE = True
#: :func:`band_crossing` reads the arrays at the band's pixels by one flat index (round 14: a boolean
#: index per array found the band's pixels four times, 8 ms of a 1280x960 view); False: the boolean
#: indexing, the reference (the same pixels in the same order, so the same share).
CROSSING_FLAT = True
#: A pixel given its crossed cube's colour keeps the photo's part across its line, shrunk by the plate's
#: uncertainty (:func:`across_line`; False: the cube's colour alone, stop 53's rule).  Held out, alone (gather, the
#: 49-row table of scripts/issue30_table.py, docs/matting.md "The photo's part across the line"): the 36 conifer rows
#: +0.035 to +0.139 dB (mean +0.074), SSIM +0.002, the fur -0.006 to 0, every black twin the same digits.
KEEP_ACROSS = True
#: ... and so does a pixel given the object's colour (no crossed cube), by the object colour's own expected error
#: (the object crossing's sigma^2, record ``global.sigma``; :func:`object_sig2`).  Held out against KEEP_ACROSS
#: alone: conifer rows mean +0.007 dB (-0.009 to +0.044), s17city +0.017, fur -0.004 to +0.005, twins the same.
OBJECT_ACROSS = True
#: The colour across the views gives no pixel its cube's colour where the object's crossing errs by more than
#: MAX_OBJECT_SIGMA (linear; the crossing's expected colour error, the record's ``global.sigma``; SIGMA_GATE,
#: :func:`uncertain`): the lines are too scattered for their crossing to beat each view's own colour.  Measured
#: (stop 57, docs/matting.md "A furry bunny, and the colour across the views on fur"): on the 41 path-traced
#: conifer rows of scripts/issue30_table.py 0.011-0.024, where the step gains 0.4-0.8 dB held out; on the 15 fur
#: and bunny rows that have one 0.034-0.092, where it gains nothing on the turntables (it colours no pixel), costs
#: the fur orbits 0.21-0.29 dB and the furry bunny on the table 0.40, and gains the bunny before the room 0.07.
#: 0.03 is the gap's midpoint.  Rendered after the rule was set: a fur orbit at 0.030 (+0.05 gated), a bunny orbit
#: at 0.116 (+0.13 gated), a conifer in the interior at 0.016 (not gated).
MAX_OBJECT_SIGMA = 0.03
SIGMA_GATE = True
#: The keys of a view's fit sample (line_samples' arrays the fit reads).
FIT_KEYS = ("pts", "C", "B", "a", "F0", "usable")


def fit_cap(n_views: int) -> int:
    """Most partial pixels each of ``n_views`` views hands back for the fit (the constants above)."""
    return int(min(MAX_FIT_LINES_PER_VIEW, MAX_FIT_LINES // max(int(n_views), 1)))


def fit_sample(samples: dict | None, cap: int, seed: int) -> dict | None:
    """A view's line samples (capture.matting_lines.line_samples) for the fit: at most ``cap`` of them,
    drawn without replacement by ``seed`` and kept in their order (all of them, the same arrays, when
    no more), FIT_KEYS only and ``fill`` (capture.matting_global.filled, 1 byte a line); with ``n`` the
    view's partial pixels and ``lo`` / ``hi`` the bounds (3,) of all their 3D points.  None for None."""
    if samples is None:
        return None
    n = len(samples["a"])
    pts = samples["pts"]
    out = {"n": n, "lo": pts.min(0), "hi": pts.max(0)}
    if n <= cap:
        got = {k: samples[k] for k in FIT_KEYS}
    else:
        pick = np.sort(np.random.default_rng((FIT_SEED, int(seed))).choice(n, int(cap), replace=False))
        got = {k: samples[k][pick] for k in FIT_KEYS}
    return {**out, **got, "fill": filled(got["C"], got["B"], got["a"], got["F0"])}  # in the view's own exposure


def cell_grid(fits: list, cells: int = CELLS_PER_EXTENT):
    """(origin (3,), side, dims (3,) int64) of the cubes: 1 / ``cells`` of the largest extent of the
    bounds of every view's partial pixels (the fit samples' ``lo`` / ``hi``), as cell_colours takes
    them from all its samples; None where the extent is 0 or there is no view."""
    have = [f for f in fits if f is not None]
    if not have:
        return None
    lo = np.min([np.asarray(f["lo"], np.float64) for f in have], 0)
    hi = np.max([np.asarray(f["hi"], np.float64) for f in have], 0)
    extent = float((hi - lo).max())
    if extent <= 0:
        return None
    side = extent / cells
    return lo, side, np.floor((hi - lo) / side).astype(np.int64) + 1


def cell_keys(pts: np.ndarray, grid) -> np.ndarray:
    """(N,) int64 the cube of each 3D point (N, 3) on ``grid`` (:func:`cell_grid`)."""
    origin, side, dims = grid
    ijk = np.floor((np.asarray(pts, np.float64) - origin) / side).astype(np.int64)
    return (ijk[:, 0] * dims[1] + ijk[:, 1]) * dims[2] + ijk[:, 2]


def _cat(fits: list, key: str, g: np.ndarray | None = None) -> np.ndarray:
    """The fit samples' ``key`` of every view, concatenated (float64; in the common exposure, x the
    view's gain, where ``g`` (V, 3) is given: the same products as cell_colours').  Made in one array,
    each view's rows multiplied in place: every new array here is memory the machine must hand over
    (docs/speed.md round 22)."""
    parts = [f[key] for f in fits if f is not None]
    if key in ("usable", "fill"):
        return np.concatenate(parts).astype(bool)
    x = np.concatenate(parts, dtype=np.float64)
    if g is not None:
        start = 0
        for v, f in enumerate(fits):
            if f is not None:
                x[start:start + len(f[key])] *= g[v]
                start += len(f[key])
    return x


def fit_cells(fits: list, gains=None, cells: int = CELLS_PER_EXTENT) -> tuple[dict | None, dict]:
    """The table of the cubes' colours from every view's fit sample (:func:`fit_sample` or None;
    ``gains`` (V, 3) as cell_colours'): (``{"grid", "keys" (K,) sorted, "F" (K, 3) in the common
    exposure, "sig2" (K,)}`` or None, the record: pixels, lines fitted, the median expected error over
    the fitted lines in a usable cube, why none)."""
    have = [f for f in fits if f is not None]
    rec = {"cells": cells, "pixels": int(sum(f["n"] for f in have)), "fitted": int(sum(len(f["a"]) for f in have)),
           "crossed": 0, "coloured": 0}
    if not have:
        return None, {**rec, "reason": "no partial pixels with depth"}
    g = np.ones((len(fits), 3)) if gains is None else np.asarray(gains, np.float64)
    view = np.concatenate([np.full(len(f["a"]), v, np.int32) for v, f in enumerate(fits) if f is not None])
    C, B, F0 = (_cat(fits, k, g) for k in ("C", "B", "F0"))
    al = line_alpha(C, B, np.median(F0, 0))
    w = line_weights(al, _cat(fits, "usable"), np.zeros(len(al)), CELL_LINE_ALPHA)
    del al
    grid = cell_grid(fits, cells)
    if grid is None or int((w > 0).sum()) < MIN_LINES:
        return None, {**rec, "reason": "too few partial pixels before a known background"}
    uniq, inv = np.unique(cell_keys(_cat(fits, "pts"), grid), return_inverse=True)
    inv = inv.ravel()
    K = len(uniq)

    def gsum(x):
        return np.stack([np.bincount(inv, x[:, j], minlength=K) for j in range(x.shape[1])], 1)

    gsum.groups = K  # summed by bincount over ``inv``: group_fit's compiled pass (capture.matting_lines.GN_COMPILED)
    fill = _cat(fits, "fill")
    alpha = _cat(fits, "a")
    why, before = agreeing_before(C, B, w, alpha, F0)
    if why:
        return None, {**rec, "global": before, "reason": why}
    F, sig2, F_obj, k, rec["global"] = cross_cells(C, B, w, alpha, F0, fill, gsum, inv, view, len(fits))
    why = after_crossing(rec["global"])
    rec["global"].update({"gate": before["agreeing"]} if before else {})
    if why:
        return None, {**rec, "reason": why}
    ok = np.isfinite(sig2[inv])
    if ok.any():
        rec["sigma_median"] = round(float(np.sqrt(np.median(sig2[inv][ok]))), 5)
    return {"grid": grid, "keys": uniq, "F": F, "sig2": sig2, "global": F_obj, "brightness": k,
            "global_sig2": object_sig2(F_obj, rec["global"])}, rec


def object_sig2(F_obj, record: dict) -> float | None:
    """The object colour's expected squared error as one pixel's colour (its crossing's sigma^2, from the crossing's
    ``record``), None without the object's colour or OBJECT_ACROSS off."""
    if not OBJECT_ACROSS or F_obj is None or record.get("sigma") is None:
        return None
    return float(record["sigma"]) ** 2


def after_crossing(global_record: dict) -> str | None:
    """Why no pixel takes its cube's colour, read from the crossing's record (capture.matting_global.cross_cells):
    the lines' agreement where it is read after the crossing (AGREEING_BEFORE off), then :func:`uncertain`; or None."""
    return (None if AGREEING_BEFORE else disagreeing(global_record)) or uncertain(global_record)


def uncertain(global_record: dict) -> str | None:
    """Why no pixel takes its cube's colour (SIGMA_GATE: the object's crossing errs by more than MAX_OBJECT_SIGMA),
    or None; ``global_record``: capture.matting_global.cross_cells' record (no ``sigma``: None)."""
    sigma = (global_record or {}).get("sigma")
    if not SIGMA_GATE or sigma is None or sigma <= MAX_OBJECT_SIGMA:
        return None
    return (f"the object's crossing errs by {sigma:.3f} (over {MAX_OBJECT_SIGMA}, capture.matting_cells."
            "MAX_OBJECT_SIGMA): the lines are too scattered to beat each view's own colour")


def agreeing_before(C, B, w, alpha, colour) -> tuple[str | None, dict]:
    """(why no pixel takes its cube's colour, or None; the record ``{"agreeing": ...}``) from the lines'
    agreement with the matte's alpha before any crossing (AGREEING_BEFORE; capture.matting_contrast.agreeing_lines
    on the first pass's arguments: ``C``, ``B`` (N, 3), weights ``w``, ``alpha`` (N,), ``colour`` (N, 3)).
    (None, {}) when off: the gate then reads the last pass's record (:func:`disagreeing`)."""
    if not AGREEING_BEFORE:
        return None, {}
    from capture.matting_contrast import agreeing_lines

    rec = {"agreeing": agreeing_lines(C, B, w, alpha, colour)[1]}
    return disagreeing(rec), rec


def disagreeing(global_record: dict) -> str | None:
    """Why no pixel takes its cube's colour (AGREEING_GATE: the lines' agreement share under MIN_AGREEING),
    or None; ``global_record``: capture.matting_global.cross_cells' record."""
    share = ((global_record or {}).get("agreeing") or {}).get("share")
    if not AGREEING_GATE or share is None or share >= MIN_AGREEING:
        return None
    return (f"only {share:.2f} of the lines agree with the matte's alpha (under {MIN_AGREEING}, "
            "capture.matting_cells.MIN_AGREEING): they do not point at one colour")


def apply_cells(samples: dict | None, table: dict | None, sigma_alpha=None, gain=None, gated: bool = True,
                view: int | None = None):
    """One view's partial pixels (capture.matting_lines.line_samples) given their cube's colour from
    ``table`` (:func:`fit_cells`) where cell_colours would: its expected error below the unmixed
    colour's with the view's ``sigma_alpha`` (None: the view keeps its colour; ``gated`` False: no
    gate, every usable cube's colour), ``gain`` (3,) the view's exposure gain or None, ``view`` its
    position (its brightness in the table, capture.matting_global.view_brightness; None: 1).  ((flat indices,
    colours (n, 3) float32 in the view's exposure, implied alphas (n,)) or None, the counts: crossed,
    coloured)."""
    counts = {"crossed": 0, "coloured": 0, "global": 0, "filled": 0}
    if samples is None or table is None:
        return None, counts
    g = np.ones(3) if gain is None else np.asarray(gain, np.float64)
    keys = cell_keys(samples["pts"], table["grid"])
    pos = np.minimum(np.searchsorted(table["keys"], keys), len(table["keys"]) - 1)
    found = table["keys"][pos] == keys
    sig2 = np.where(found, table["sig2"][pos], np.inf)
    F = table["F"][pos]
    use = np.isfinite(sig2)
    crossed = use.copy()
    counts["crossed"] = int(use.sum())
    C, B = (samples[k].astype(np.float64) * g for k in ("C", "B"))
    a = samples["a"].astype(np.float64)
    if gated:
        sb = np.asarray(samples.get("sb", np.zeros(len(a))), np.float64)
        unmix2 = 0.0 if sigma_alpha is None else \
            (sigma_alpha ** 2 * ((B - F) ** 2).sum(-1) + ((1.0 - a) * sb) ** 2) / np.maximum(a, 1e-6) ** 2
        use &= sig2 < unmix2
    counts["coloured"] = int(use.sum())
    fill = filled(samples["C"], samples["B"], samples["a"], samples["F0"])
    k = 1.0 if view is None or table.get("brightness") is None else np.asarray(table["brightness"][view], np.float64)
    use, F, counts["global"], counts["filled"] = with_object_colour(use, crossed, fill, F, table.get("global"),
                                                                    not gated or sigma_alpha is not None, k)
    if not use.any():
        return None, counts
    imp = np.clip(_implied(C[use], B[use], F[use]), 0.0, 1.0)
    Fu = F[use]
    if KEEP_ACROSS and gated and sigma_alpha is not None:
        s2o = table.get("global_sig2")  # sb: the plate's uncertainty, read for the gate above
        where = (crossed | (s2o is not None)) & np.asarray(samples["usable"], bool)
        Fu, counts["across"] = across_line(C[use], B[use], Fu, imp, np.where(crossed, sig2, s2o or 0.0)[use],
                                           sb[use], where[use])
    return (samples["index"][use], (Fu / g).astype(np.float32), imp.astype(np.float32)), counts


def across_line(C, B, F, imp, sig2, sb, where) -> tuple[np.ndarray, int]:
    """The colours ``F`` (N, 3) of pixels of alpha ``imp`` (N,, implied by F on the line B -> C) with gamma of the
    photo's part across the line, r = (C - B) - imp (F - B), put back: F + gamma r / imp, clipped, so that the
    premultiplied colour is imp F + gamma r.  gamma = t / (t + (1 - imp)^2 sb^2 + NOISE_ABS^2), t = imp^2 ``sig2``
    (the cube colour's expected error, premultiplied), ``sb`` the plate's uncertainty (0 where a frame saw B);
    only ``where`` (a crossed cube's or the object's colour, before a background known and not blown out: elsewhere
    B is no measurement).  (The colours, how many changed.)"""
    from capture.matting_known import NOISE_ABS

    t = imp ** 2 * np.where(where, sig2, 0.0)
    gamma = t / np.maximum(t + ((1.0 - imp) * sb) ** 2 + NOISE_ABS ** 2, 1e-30)
    r = (C - B) - imp[:, None] * (F - B)
    out = np.clip(F + (gamma / np.maximum(imp, 1e-6))[:, None] * r, 0.0, 1.0)
    return out, int(np.count_nonzero(gamma > 0))



def band_crossing(image: np.ndarray, band: np.ndarray, background: np.ndarray, known: np.ndarray,
                  estimated: np.ndarray | None = None, opaque: np.ndarray | None = None,
                  over: float | None = None) -> float:
    """Share of a view's matting ``band`` (H, W) bool whose background a frame saw (``known`` and not
    ``estimated``), not blown out (capture.matting_known.clipped, with the photo ``image``) and brighter
    (linear, Euclidean over the channels) than CROSSING_DARK and than ``over`` (default CROSSING_OVER)
    x the median brightness of the photo at the ``opaque`` pixels (the depth's sure object; None: no
    such bound): where a partial pixel's line can cross another's and its unmixed colour's
    premultiplied error (a - a_true) B can be beaten (module docstring).  0 for an empty band."""
    from capture.matting_known import clipped

    n = int(np.count_nonzero(band))
    if not n:
        return 0.0
    img = np.asarray(image)
    dark2 = CROSSING_DARK ** 2
    if opaque is not None and np.any(opaque):
        obj = img[opaque][::OBJECT_STRIDE].astype(np.float32)
        dark2 = max(dark2, float((CROSSING_OVER if over is None else over) ** 2 *
                                 np.median(np.einsum("ij,ij->i", obj, obj))))
    if CROSSING_FLAT:  # the band's pixels found once, each array read there by that one index
        idx = np.flatnonzero(band)
        B = _at(background, idx).astype(np.float32)
        use = _at(np.asarray(known, bool), idx) & ~clipped(_at(img, idx).astype(np.float32), B)
        if estimated is not None:
            use &= ~_at(np.asarray(estimated, bool), idx)
    else:
        B = np.asarray(background)[band].astype(np.float32)
        use = np.asarray(known, bool)[band] & ~clipped(img[band].astype(np.float32), B)
        if estimated is not None:
            use &= ~np.asarray(estimated, bool)[band]
    use &= np.einsum("ij,ij->i", B, B) >= np.float32(dark2)
    return float(np.count_nonzero(use)) / n


def _at(a: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """``a[mask]`` of an (H, W[, C]) array for ``idx = np.flatnonzero(mask)`` (row-major, as a boolean index)."""
    a = np.asarray(a)
    return a.reshape(-1, *a.shape[2:])[idx]

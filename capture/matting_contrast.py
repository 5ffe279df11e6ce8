"""The object's colour from the lines the two alphas agree on, and each view's tint (issue 30, ninth round).

**The lines the two alphas agree on.** capture.matting_global crosses the lines B -> C of every view's
partial pixels as one group for the object's colour (capture.matting_lines.group_fit).  On the turntable
before the shaded bricks (seed 1, room 315 degrees) it came out red, 0.057 / 0.063 / 0.023 where the truth
over the same lines (the black twin) is 0.048 / 0.062 / 0.020, and the check against the cubes passed: the
cubes are crossed from the same lines.  Split by the *true* alpha, the 3.6 % of its lines whose needle
covers under a fifth of the pixel cross at red 0.157: pixels the matte calls partial whose line is mostly
the plate's error (the plate reads the room behind the crown 0.007-0.009 too dark in red there).  Such a
line is long for its alpha: the photo's alpha of the line, |C - B| / |B - ref| (capture.matting_lines
.line_alpha, as the lines were chosen), disagrees with the matte's, which its priors and neighbours set.
:func:`agreeing_lines` keeps a line for the object's colour only where the two agree within AGREE_TOL.
Measured against the truth over the lines, |F - F_true| all lines -> agreeing: made-on turntable 0.0043 ->
0.0032, made-on orbit 0.0017 -> 0.0011, unseen turntables 0.0096 -> 0.0054 and 0.0041 -> 0.0021, unseen
orbits 0.0017 -> 0.0015 and 0.0024 -> 0.0019 (smaller on all six).  The cubes keep every line (the filter
on their lines too lost held out on the orbits, docs/matting.md ninth round).

**The lines by their lever (tried, not kept: CONTRAST off).** Each line weighted by |B - F_1|^2 (F_1 the
plain crossing): nearer the truth on four captures, farther on one unseen orbit (0.0024 -> 0.0036), and
held out it lost on the unseen captures (:func:`contrast_weights`, kept off for the record).

**Each view's tint.** capture.matting_global.view_brightness gives each view one brightness k of the
object (an orbit sees the lit and the shadowed side).  The side a view sees differs in colour too
(sky-lit shade is bluer than sunlit needles): :func:`view_chroma` fits each view's three channel
factors c about k F_ref from the same lines (alpha-free, Gauss-Newton), relative to their mean over the
views (a tint every view shares is the reference's hue, left to the cubes), and shrinks each channel
towards 1 by the views' measured spread less the factors' own variance (none where the views scatter no
more than their noise; the record says so).  It runs only where the views' brightness was found.

**A view without its own alpha error.** capture.matting_colour measures each view's alpha error from its
sure colours; a view with too few keeps its colour whole (no cube's, no object's, no brightness): on the
orbits one view in 18.  :func:`pooled_alpha_errors` gives it the median of the views that measured one,
where most did (more than MIN_MEASURED_SHARE), and the gate against unmixing then decides with it as for any view
(held out: unseen orbit 26.796 -> 26.905, made-on orbit 26.937 -> 26.983, AE + lens 24.795 -> 24.792; the fur,
whose views measure none, is left as it is and the record says so).
"""

from __future__ import annotations

import numpy as np

from capture.matting_lines import MIN_LINES, group_fit, line_alpha

#: Cross the object's lines only where the photo's alpha of the line agrees with the matte's (module docstring).
AGREEING = True
#: ... within this: |a_photo - a_matte| below it (0.15 and 0.25 measured alike; docs/matting.md ninth round).
AGREE_TOL = 0.25
#: Weight the object's lines by their lever |B - F_1|^2 (module docstring; tried and not kept: off).
CONTRAST = False
#: Scale each view's colours by its own three channel factors about its brightness (:func:`view_chroma`).
VIEW_CHROMA = True
#: Give a view without its own alpha error the median of the views that measured one (:func:`pooled_alpha_errors`).
POOL_ALPHA_ERROR = True
#: ... only where more than this share of the views with samples measured one (a capture of two views, one
#: of them blind, keeps the blind one's colour).
MIN_MEASURED_SHARE = 0.5
#: Gauss-Newton steps of a view's channel factors, the largest step a channel, and their bounds.
CHROMA_ITERATIONS = 6
MAX_CHROMA_STEP = 0.3
CHROMA_BOUNDS = (0.3, 3.0)
#: Each view's tint relative to the views' mean tint (the lines' weighted mean factor a channel is 1).
CHROMA_RELATIVE = True


def _one_group(C, B, w, alpha):
    """The plain crossing of all lines with weight ``w`` > 0 as one group: ((3,) or None, its lines)."""
    li = np.flatnonzero(np.asarray(w) > 0)
    if len(li) < MIN_LINES:
        return None, li
    F, sig2 = group_fit(C[li], B[li], w[li], alpha[li], lambda x: x.sum(0, keepdims=True),
                        np.zeros(len(li), np.int64))
    return (F[0] if np.isfinite(sig2[0]) else None), li


def agreeing_lines(C, B, w, alpha, colour) -> tuple[np.ndarray, dict]:
    """(N,) the lines' weights ``w`` where the photo's alpha of the line (capture.matting_lines.line_alpha
    against the median of the matte's ``colour`` (N, 3), as the lines were chosen) is within AGREE_TOL
    of the matte's ``alpha``, 0 elsewhere; and the record (the share kept, or why all are kept: off,
    or fewer than MIN_LINES agree)."""
    w = np.asarray(w, np.float64)
    if not AGREEING:
        return w, {"reason": "off"}
    a_line = line_alpha(np.asarray(C, np.float64), np.asarray(B, np.float64), np.median(colour, 0))
    keep = np.abs(a_line - np.asarray(alpha, np.float64)) < AGREE_TOL
    lines = w > 0
    n = int((lines & keep).sum())
    if n < MIN_LINES:
        return w, {"reason": f"only {n} lines agree"}
    return np.where(keep, w, 0.0), {"share": round(n / max(int(lines.sum()), 1), 4)}


def contrast_weights(C, B, w, alpha) -> tuple[np.ndarray, dict]:
    """(N,) the lines' weights ``w`` times |B - F_1|^2 over its median on the lines (F_1 the plain
    crossing of ``C``, ``B`` (N, 3) with the matte's ``alpha`` (N,) as the start), and the record
    (F_1; or why the weights are left as they are: off, or the plain lines do not cross)."""
    if not CONTRAST:
        return w, {"reason": "off"}
    F1, li = _one_group(C, B, w, alpha)
    if F1 is None:
        return w, {"reason": "the plain lines do not cross"}
    lever = ((np.asarray(B, np.float64) - F1) ** 2).sum(-1)
    scale = float(np.median(lever[li]))
    if scale <= 0:
        return w, {"reason": "no lever: the backgrounds at the object's colour"}
    return np.asarray(w, np.float64) * lever / scale, {"plain": [round(float(x), 5) for x in F1]}


def _chroma_terms(C, B, w, Fs, c, view, n_views):
    """One Gauss-Newton linearisation of every view's channel factors ``c`` (V, 3) about ``Fs`` (N, 3):
    (normal matrices (V, 3, 3), gradients (V, 3), weighted squared residual per view (V,))."""
    def vsum(x):
        return np.bincount(view, x, minlength=n_views)

    d, fb = C - B, c[view] * Fs - B
    n2 = np.maximum((fb ** 2).sum(-1), 1e-12)
    a = np.clip((d * fb).sum(-1) / n2, 0.0, 1.0)
    r = d - a[:, None] * fb
    v = fb / np.sqrt(n2)[:, None]
    rp = r - v * (v * r).sum(-1, keepdims=True)
    m = np.empty((n_views, 3, 3))
    for i in range(3):
        for j in range(i, 3):
            m[:, i, j] = m[:, j, i] = vsum(w * a ** 2 * Fs[:, i] * Fs[:, j] * ((i == j) - v[:, i] * v[:, j]))
    g = np.stack([vsum(w * a * Fs[:, i] * rp[:, i]) for i in range(3)], 1)
    return m, g, vsum(w * (r ** 2).sum(-1))


def view_chroma(C, B, w, F_ref, view, n_views: int, k: np.ndarray) -> tuple[np.ndarray, dict]:
    """(n_views, 3) each view's channel factors c about its brightness ``k`` (n_views,): least squares
    over c of sum w |C - B - a (c k F_ref - B)|^2 (a the projection, alpha-free) from the lines ``C``,
    ``B``, ``w``, each sample's reference ``F_ref`` (N, 3) and ``view`` (N,); each channel shrunk
    towards 1 by the views' spread less the factors' own variance.  All 1 (the record says why) when
    off, with fewer than 2 views with lines, or, per channel, where the views scatter no more than
    their noise."""
    ones = np.ones((n_views, 3))
    if not VIEW_CHROMA:
        return ones, {"reason": "off"}
    view = np.asarray(view, np.int64)
    Fs = np.asarray(k, np.float64)[view][:, None] * F_ref
    n = np.bincount(view, (np.asarray(w) > 0).astype(np.float64), minlength=n_views)
    c = ones.copy()
    for it in range(CHROMA_ITERATIONS + 1):
        m, g, rss = _chroma_terms(C, B, w, Fs, c, view, n_views)
        ok = (n >= MIN_LINES) & (np.linalg.det(m) > 0)
        if it == CHROMA_ITERATIONS or not ok.any():
            break
        step = np.zeros((n_views, 3))
        step[ok] = np.linalg.solve(m[ok], g[ok][..., None])[..., 0]
        c = np.clip(c + np.clip(step, -MAX_CHROMA_STEP, MAX_CHROMA_STEP), *CHROMA_BOUNDS)
    if int(ok.sum()) < 2:
        return ones, {"reason": "too few views with lines"}
    s = rss[ok] / np.maximum(2.0 * n[ok] - 3.0, 1.0)
    var = s[:, None] * np.diagonal(np.linalg.inv(m[ok]), axis1=1, axis2=2)
    if CHROMA_RELATIVE:  # a tint every view shares is the reference's hue, not a view's: left to the cubes
        c[ok] /= (n[ok, None] * c[ok]).sum(0) / n[ok].sum()
    tau2 = np.maximum((n[ok, None] * ((c[ok] - 1.0) ** 2 - var)).sum(0) / n[ok].sum(), 0.0)
    if not (tau2 > 0).any():
        return ones, {"reason": "the views' tint scatters no more than its noise"}
    out = ones.copy()
    out[ok] = 1.0 + (c[ok] - 1.0) * tau2 / (tau2 + var)
    return out, {"tau": [round(float(x), 4) for x in np.sqrt(tau2)],
                 "range": [[round(float(x), 3) for x in out.min(0)], [round(float(x), 3) for x in out.max(0)]]}


def pooled_alpha_errors(sigma_alpha: list, present: list | None = None) -> tuple[list, dict]:
    """Each view's alpha error (``sigma_alpha``: a float or None, not measured), with the median of the
    measured ones given to the views without one, where more than MIN_MEASURED_SHARE of the views
    ``present`` (bool each: the view has samples; default all) measured one.  (The list, the record: how
    many borrowed it and its value, or why none did.)"""
    sa = list(sigma_alpha)
    have = [True] * len(sa) if present is None else [bool(p) for p in present]
    measured = [x for x, h in zip(sa, have, strict=True) if h and x is not None]
    blind = sum(1 for x, h in zip(sa, have, strict=True) if h and x is None)
    if not POOL_ALPHA_ERROR:
        return sa, {"reason": "off"}
    if not blind:
        return sa, {"borrowed": 0}
    if len(measured) <= MIN_MEASURED_SHARE * (len(measured) + blind):
        return sa, {"borrowed": 0, "reason": f"only {len(measured)} of {len(measured) + blind} views measured one"}
    med = float(np.median(measured))
    return [med if x is None else x for x in sa], {"borrowed": blind, "sigma_alpha": round(med, 5)}

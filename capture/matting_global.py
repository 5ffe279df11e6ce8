"""The needles' colour where no cube's lines cross (issue 30, eighth round).

The seventh round (capture.matting_lines.cell_colours, capture.matting_cells) gives a partial pixel
the colour its 3D cube's lines B -> C cross at across the views, where they cross.  On a turntable
(a fixed camera: the room behind a cube is one patch whatever the turn) 42 % of the conifer's
partial pixels lie in a cube whose lines do not cross, and nearly all of them keep the fill of the
sure pixels (capture.matting_known step 4, chosen by capture.matting_colour's gate), which are trunk
and branches: the crown comes out olive (the turntable's kept views: mean colour 0.063 / 0.056 /
0.026 where the truth is 0.043 / 0.068 / 0.023).

Here those pixels take one colour for the whole object: the lines of every view's partial pixels
crossed as one group (capture.matting_lines.group_fit; the backgrounds behind the whole crown differ
enough to cross even where those behind one cube do not), from the lines whose photo's alpha is at
least capture.matting_lines.CELL_LINE_ALPHA (the faint ones pull the crossing towards the room's
colour), as the cubes' own.

It knows when it cannot beat doing nothing: the colour is used only

* where the pixel's colour was filled (not unmixed: :func:`filled`), in a cube whose lines do not
  cross, in a view whose alpha error was measured (as the cubes' colour: a view without one keeps
  its colour);
* when the object's lines cross (at least MIN_LINES, well conditioned, the colour beyond the photo);
* when, over the filled pixels whose cube's lines do cross, the object's colour lies nearer the cubes'
  colours than the fill does (mean squared distance; the cube colour's own error adds to both).

Otherwise none, and the record (``cells['global']``) says why.  And a crossing that lies far from the matte's
own mean colour (:func:`mean_checked`, MAX_MEAN_GAP) gives way to that mean: where the backgrounds behind the
whole object share its hue the lines are nearly parallel and cross anywhere along them (the fifth unseen
conifer before brick paving of its trunk's colour: a third of the true colour; docs/matting.md), unless the mean
is the less sure of the two (MEAN_BIAS_CHECK: before a bright window the mean takes the window's light).

The object's colour is also the prior of the cubes' (:func:`shrink`): where the backgrounds behind a
cube are alike its crossing errs far more than the needles' colours differ from cube to cube, and
each cube's colour is drawn towards the object's by as much as its estimate's covariance (s M^-1,
capture.matting_lines.group_fit) exceeds the cubes' measured spread about the object's colour (the
spread of their estimates less the estimates' own variance).  On the turntable the spread came out
0.010 a channel, on the orbit 0.007, with the orbit's estimates far surer: its cubes barely move.
The needles' colour also depends on the side a view sees (an orbit's lit and shadowed sides: each
cube's true colour per view scores 27.13 dB held out against 26.45 across the views): each view's
brightness k of the object (:func:`view_brightness`, alpha-free, from the view's lines through k times
their cube's colour; 0.66-1.37 on the conifer orbit, 0.94-1.00 on the turntable) scales the colours
that view is given, and a filled pixel whose cube crosses takes the cube's colour (FILLED_CUBES) where
the gate against unmixing would have left it the fill (which carried the view's brightness).

Held out (gather, docs/matting.md eighth round): turntable 25.01 -> 25.24 (the object's colour) ->
25.36 (and the shrinkage, the lines from photo's alpha 0.5) -> 25.46 (and the views' brightness,
the filled pixels in crossed cubes), orbit 26.61 -> 26.62 -> 26.89, AE + lens 24.74 -> 24.80 ->
24.81; the fur and the black capture the same digits.  Twelfth round (BRIGHTNESS_LEVEL): each view's
brightness is shrunk towards the fit's own level, not towards 1 (eight captures: mean +0.0011 dB, none lost).
"""

from __future__ import annotations

import numpy as np

from capture.matting_colour import unmixed_colour
from capture.matting_contrast import agreeing_lines, contrast_weights, view_chroma
from capture.matting_lines import MIN_LINES, group_fit
from capture.matting_recross import recross

#: Give the pixels no cube colours the object's colour (held out, gather, docs/matting.md eighth round).
GLOBAL = True
#: Shrink each cube's colour towards the object's by their spread (module docstring).
SHRINK = True
#: Scale the colours each view is given by the view's brightness of the object (:func:`view_brightness`).
VIEW_BRIGHTNESS = True
#: Where the object's colour passed its check, a filled pixel in a crossed cube takes the cube's colour
#: whatever the gate against unmixing says (the pixel is not unmixed: its colour is the fill, which the
#: check found farther from the cubes than the object's colour, and a cube's shrunk colour errs less
#: than the object's where its lines cross).
FILLED_CUBES = True
#: Shrink each view's brightness towards the views' level (the brightness fit's own: the lines-weighted mean of the
#: fitted k), not towards 1, by the views' spread about that level (:func:`view_brightness`).  The level is one
#: number measured from every view's lines, so it is not shrunk by the views' spread; the re-crossing
#: (capture.matting_recross) keeps the last pass's level, which the turntables found below 1 in every pass
#: (0.983 on the made-on one) and whose removal lost held out (RECROSS_MEAN_ONE, docs/matting.md).  Whether any
#: factor is found at all is decided as when off (the spread about 1 against the noise).  On: the twelfth round's
#: rule (a mean held-out gain over the eight captures, no capture losing more than 0.03 dB, the fur and the black
#: twins the same digits) was met: mean +0.0011 dB, worst 0 (docs/matting.md).  Off: shrunk towards 1.
BRIGHTNESS_LEVEL = True
#: Steps of the scalar Gauss-Newton fit of a view's brightness (each at most MAX_K_STEP), and its bounds.
K_ITERATIONS = 6
MAX_K_STEP = 0.3
K_BOUNDS = (0.3, 3.0)
#: A colour counts as unmixed where it is within this (linear, per channel) of B + (C - B) / a.
FILLED_TOL = 1e-3
#: The least spread of the cubes' true colours about the object's (linear, squared) the shrinkage assumes:
#: where the cubes' colours scatter no more than their estimates' own variance, they are shrunk to this.
TAU2_MIN = 1e-6
#: Least crossed cubes to measure their spread.
MIN_CUBES = 4
#: Check the object's crossing colour against the matte's own mean colour (:func:`mean_colour`) and take the mean
#: where they lie more than MAX_MEAN_GAP apart (:func:`mean_checked`; False: the rule before, the crossing kept).
#: The check comes before the one against the cubes' colours, which then judges the colour taken.
MEAN_CHECK = True
#: Most distance of the crossing's colour from the matte's mean colour, relative to the mean's length.  Measured on
#: the kept views of ten path-traced room captures (docs/matting.md "The crossing checked against the matte's mean"):
#: 0.025-0.25 on nine, where each estimate lies within 0.25 of the truth (relative); 0.77 on the fifth unseen
#: conifer (s5r180), whose crossing lies 0.70 from the truth and the mean 0.23.  Two estimates more than 0.5
#: apart cannot both be within 0.25 of the truth.  Set before the capture made to check it was rendered.
MAX_MEAN_GAP = 0.5
#: The mean gives way only where it is the surer of the two: its error is the alpha's times the background,
#: MEAN_ALPHA_BIAS x |sum B| / sum a for a systematic alpha error of MEAN_ALPHA_BIAS, against the crossing's own sigma
#: (:func:`mean_checked`; False: the mean whenever the gap is over MAX_MEAN_GAP).  Before a bright window the mean
#: takes the window's light into the needles (docs/matting.md "A conifer before a blown window").
MEAN_BIAS_CHECK = True
#: The systematic alpha error the mean's check assumes: the kept views' band alpha bias, 0.004-0.041 by class on the
#: conifer before the window (docs/matting.md).
MEAN_ALPHA_BIAS = 0.03


def filled(C: np.ndarray, B: np.ndarray, alpha: np.ndarray, colour: np.ndarray) -> np.ndarray:
    """(N,) bool: the matte's ``colour`` (N, 3) is not the unmixed one, clip(B + (C - B) / a) (C, B
    clipped to [0, 1] as capture.matting_known.foreground_colour takes them), in one exposure."""
    C, B = (np.clip(np.asarray(x, np.float64), 0.0, 1.0) for x in (C, B))
    Fu = unmixed_colour(C, B, np.asarray(alpha, np.float64))
    return ~np.all(np.abs(Fu - np.asarray(colour, np.float64)) <= FILLED_TOL, axis=-1)


def object_colour(C, B, w, alpha, colour, cell_colour, crossed, fill,
                  mean: bool = False) -> tuple[np.ndarray | None, dict]:
    """The object's colour (module docstring) from N samples in the common exposure: ``C``, ``B`` (N, 3),
    line weights ``w`` (N,, capture.matting_lines.line_weights), the matte's ``alpha`` (N,) and
    ``colour`` (N, 3), each sample's cube colour ``cell_colour`` (N, 3) and whether its cube's lines
    cross ``crossed``, ``fill`` (:func:`filled`).  ((3,) or None, the record)."""
    rec: dict = {"lines": int((np.asarray(w) > 0).sum())}
    w0 = w
    if not GLOBAL:
        return None, {**rec, "reason": "off"}
    w, rec["agreeing"] = agreeing_lines(C, B, w, alpha, colour)  # capture.matting_contrast: the lines the
    w, rec["contrast"] = contrast_weights(C, B, w, alpha)  # two alphas agree on (the lever's weights: off)
    li = np.flatnonzero(np.asarray(w) > 0)  # the others add nothing to the sums
    F, sig2 = group_fit(C[li], B[li], w[li], alpha[li], lambda x: x.sum(0, keepdims=True), np.zeros(len(li), np.int64))
    if not np.isfinite(sig2[0]):
        return None, {**rec, "reason": "the object's lines do not cross (too few, parallel, or at the background)"}
    ref = np.asarray(crossed, bool) & np.asarray(fill, bool)
    if int(ref.sum()) < MIN_LINES:
        return None, {**rec, "reason": "too few filled pixels in a crossed cube to check it against"}
    sigma = float(np.sqrt(sig2[0]))
    F_obj, rec["mean"] = mean_checked(F[0], C, B, np.asarray(w0) > 0, alpha, mean, sigma)
    e_fill = float(((np.asarray(colour, np.float64)[ref] - cell_colour[ref]) ** 2).sum(-1).mean())
    e_obj = float(((F_obj - cell_colour[ref]) ** 2).sum(-1).mean())
    rec.update(colour=[round(float(x), 5) for x in F[0]], sigma=round(sigma, 5),
               check=int(ref.sum()), fill_to_cubes=round(e_fill, 7), object_to_cubes=round(e_obj, 7))
    if e_obj >= e_fill:
        return None, {**rec, "reason": "not nearer the cubes' colours than the fill"}
    return F_obj, rec


def mean_colour(C, B, alpha) -> np.ndarray | None:
    """(3,) the matte's own mean colour of N partial pixels: sum(C - (1 - a) B) / sum(a), the premultiplied
    colours its ``alpha`` (N,) unmixes from ``C``, ``B`` (N, 3) over the alpha they cover.  It does not hang on
    the lines' crossing: its error is the alpha's, sum((a - a_true) B) / sum(a), small where the alpha's
    errors do not follow the background.  None for no alpha."""
    a = np.asarray(alpha, np.float64)
    if a.sum() <= 0:
        return None
    return (np.asarray(C, np.float64) - (1.0 - a[:, None]) * np.asarray(B, np.float64)).sum(0) / a.sum()


def mean_checked(F_obj: np.ndarray, C, B, lines: np.ndarray, alpha, force: bool = False,
                 sigma: float | None = None) -> tuple[np.ndarray, dict]:
    """The object's colour after the check against the matte's mean colour over the ``lines`` (N,) bool
    (:func:`mean_colour`): ``F_obj`` where the two lie at most MAX_MEAN_GAP apart (relative to the mean), else the
    mean (a crossing that far from it has crossed where the lines are nearly parallel: the backgrounds behind the
    object all of its own hue), unless (MEAN_BIAS_CHECK) the mean's error from an alpha error of MEAN_ALPHA_BIAS is
    above the crossing's ``sigma``; and the record (the mean, the gap, which was taken, the mean's error)."""
    if not MEAN_CHECK:
        return F_obj, {"reason": "off"}
    Cl, Bl, al = np.asarray(C)[lines], np.asarray(B, np.float64)[lines], np.asarray(alpha, np.float64)[lines]
    Fm = mean_colour(Cl, Bl, al)
    if Fm is None or not np.linalg.norm(Fm) > 0:
        return F_obj, {"reason": "no alpha on the lines"}
    gap = float(np.linalg.norm(F_obj - Fm) / np.linalg.norm(Fm))
    take = gap > MAX_MEAN_GAP or bool(force)
    rec = {"colour": [round(float(x), 5) for x in Fm], "gap": round(gap, 4), "taken": take}
    if take and not force and MEAN_BIAS_CHECK and sigma is not None:
        rec["mean_error"] = round(MEAN_ALPHA_BIAS * float(np.linalg.norm(Bl.sum(0))) / float(al.sum()), 5)
        rec["taken"] = take = rec["mean_error"] <= sigma
    if force:
        rec["forced"] = True
    return (np.clip(Fm, 0.0, 1.0) if take else F_obj), rec


def shrink(F: np.ndarray, sig2: np.ndarray, terms: dict, F_obj) -> tuple[np.ndarray, np.ndarray, dict]:
    """The cubes' colours ``F`` (K, 3) (expected errors ``sig2``, inf where not crossed; ``terms`` of
    capture.matting_lines.group_fit) shrunk towards the object's ``F_obj``: each the posterior mean of
    its estimate (covariance s M^-1) under a prior about F_obj of variance tau^2 a channel, tau^2 the
    cubes' spread about F_obj less their estimates' own variance (weighted by the lines, at least
    TAU2_MIN); its expected error the spread within the cube plus the posterior's variance.  Unchanged
    (and the record says why) when off, without the object's colour or with fewer than MIN_CUBES crossed."""
    ok = np.isfinite(sig2)
    if not SHRINK or F_obj is None or int(ok.sum()) < MIN_CUBES:
        why = "off" if not SHRINK else "no object colour" if F_obj is None else "too few crossed cubes"
        return F, sig2, {"reason": why}
    P = terms["M"][ok] / np.maximum(terms["s"][ok], 1e-12)[:, None, None]  # the estimates' precision
    var = np.trace(np.linalg.inv(P), axis1=1, axis2=2) / 3.0
    n = terms["n"][ok]
    d2 = ((F[ok] - F_obj) ** 2).sum(-1) / 3.0
    tau2 = max(float((n * (d2 - var)).sum() / max(n.sum(), 1e-12)), TAU2_MIN)
    H = P + np.eye(3) / tau2
    F2, s2 = F.copy(), sig2.copy()
    F2[ok] = np.clip(F_obj + np.linalg.solve(H, (P @ (F[ok] - F_obj)[..., None]))[..., 0], 0.0, 1.0)
    s2[ok] = terms["spread"][ok] + np.trace(np.linalg.inv(H), axis1=1, axis2=2)
    return F2, s2, {"tau": round(float(np.sqrt(tau2)), 5)}


def view_brightness(C, B, w, F_ref, view, n_views: int) -> tuple[np.ndarray, dict]:
    """(n_views,) each view's brightness k of the object: the scalar that puts the view's lines through
    k F_ref (each sample's reference colour (N, 3): its cube's, or the object's; ``view`` (N,) each
    sample's view): least squares over k of sum w |C - B - a (k F_ref - B)|^2, a the projection (alpha-free,
    as capture.matting_lines.group_fit), by Gauss-Newton steps from 1.  The needles' colour on an
    orbit depends on the side the camera sees (lit or shadowed): the conifer orbit's views 0.66-1.37.
    Each k is shrunk towards the fit's level (BRIGHTNESS_LEVEL: the k's lines-weighted mean, in the record)
    by the views' measured spread about it (the spread of the k less their own variance s / m; every view
    at the level where they scatter about it no more than their noise), or, off, towards 1 by the spread
    about 1; 1 for a view with fewer than MIN_LINES lines, and all 1 when off or when the views' k scatter
    about 1 no more than their noise (the record says so)."""
    k = np.ones(n_views)
    if not VIEW_BRIGHTNESS:
        return k, {"reason": "off"}

    def vsum(x):
        return np.bincount(view, x, minlength=n_views)

    lines = (np.asarray(w) > 0).astype(np.float64)
    n = vsum(lines)
    for it in range(K_ITERATIONS + 1):
        d, fb = C - B, k[view][:, None] * F_ref - B
        n2 = np.maximum((fb ** 2).sum(-1), 1e-12)
        a = np.clip((d * fb).sum(-1) / n2, 0.0, 1.0)
        r = d - a[:, None] * fb
        v = fb / np.sqrt(n2)[:, None]
        J = F_ref - (F_ref * v).sum(-1)[:, None] * v  # d r / d k across the line
        m = vsum(w * a ** 2 * (J ** 2).sum(-1))
        if it == K_ITERATIONS:
            break
        step = np.where((n >= MIN_LINES) & (m > 0), vsum(w * a * (J * r).sum(-1)) / np.maximum(m, 1e-30), 0.0)
        k = np.clip(k + np.clip(step, -MAX_K_STEP, MAX_K_STEP), *K_BOUNDS)
    ok = (n >= MIN_LINES) & (m > 0)
    if int(ok.sum()) < 2:
        return np.ones(n_views), {"reason": "too few views with lines"}
    var = vsum(w * (r ** 2).sum(-1))[ok] / np.maximum(n[ok] - 1.0, 1.0) / m[ok]
    tau2 = float((n[ok] * ((k[ok] - 1.0) ** 2 - var)).sum() / n[ok].sum())
    if tau2 <= 0:
        return np.ones(n_views), {"reason": "the views' brightness scatters no more than its noise"}
    out, rec = np.ones(n_views), {}
    if BRIGHTNESS_LEVEL:  # the views' differences shrunk by their spread about the fit's level, the level kept
        level = float((n[ok] * k[ok]).sum() / n[ok].sum())
        tau2 = max(float((n[ok] * ((k[ok] - level) ** 2 - var)).sum() / n[ok].sum()), 0.0)
        out[ok] = level + (k[ok] - level) * tau2 / np.maximum(tau2 + var, 1e-30)
        rec["level"] = round(level, 4)
    else:
        out[ok] = 1.0 + (k[ok] - 1.0) * tau2 / (tau2 + var)
    return out, {"k": [round(float(x), 3) for x in out], "tau": round(float(np.sqrt(tau2)), 4), **rec}


def cross_cells(C, B, w, alpha, colour, fill, gsum, group, view, n_views: int):
    """The cubes' colours and the object's for N samples in the common exposure (``C``, ``B``, line
    weights ``w``, the matte's ``alpha`` and ``colour``, ``fill`` (:func:`filled`); ``gsum`` / ``group``
    as capture.matting_lines.group_fit's; ``view`` (N,) each sample's view of ``n_views``): (F (K, 3),
    sigma^2 (K,) inf where the cube's lines do not cross, the object's colour (3,) or None, each view's
    brightness (n_views,) or, with its tint (capture.matting_contrast.view_chroma), (n_views, 3), the record).
    :func:`cross_once`, then (capture.matting_recross.RECROSS) once more in each view's tint."""
    args = (C, B, w, alpha, colour, fill, gsum, group, view, n_views)
    return recross(cross_once, cross_once(*args), *args)


def cross_once(C, B, w, alpha, colour, fill, gsum, group, view, n_views: int, mean: bool = False):
    """One crossing of :func:`cross_cells` (its arguments and result); ``mean``: the object's colour is the
    matte's mean colour whatever the gap (:func:`mean_checked`: a later pass of a crossing the check refused)."""
    terms: dict = {}
    F, sig2 = group_fit(C, B, w, alpha, gsum, group, terms)
    crossed = np.isfinite(sig2[group])
    F_obj, rec = object_colour(C, B, w, alpha, colour, F[group], crossed, fill, mean)
    F, sig2, rec["shrink"] = shrink(F, sig2, terms, F_obj)
    crossed = np.isfinite(sig2[group])
    if F_obj is None:
        k, rec["brightness"] = np.ones(n_views), {"reason": "no object colour"}
    else:
        li = np.flatnonzero(w > 0)  # the others add nothing to the sums
        ref = np.where(crossed[li, None], F[group[li]], F_obj)
        vl = np.asarray(view, np.int64)[li]
        k, rec["brightness"] = view_brightness(C[li], B[li], w[li], ref, vl, n_views)
        if "k" in rec["brightness"]:  # each view's tint about its brightness (capture.matting_contrast)
            tint, rec["chroma"] = view_chroma(C[li], B[li], w[li], ref, vl, n_views, k)
            k = k[:, None] * tint
    return F, sig2, F_obj, k, rec


def with_object_colour(use: np.ndarray, crossed: np.ndarray, fill: np.ndarray, F: np.ndarray, F_obj,
                       allowed: bool = True, k=1.0) -> tuple[np.ndarray, np.ndarray, int, int]:
    """One view's samples: (the pixels given a colour, their colours (N, 3) times the view's brightness
    ``k`` (a scalar, or (3,) with its tint) where given: the cube's where ``use`` or (FILLED_CUBES) where
    the cube's lines cross and the colour was filled, the object's ``F_obj`` where they do not cross
    and the colour was filled; the filled ones only when ``allowed`` and F_obj is not None), how many
    took the object's, how many filled ones took their cube's)."""
    none = np.zeros(len(use), bool)
    crossed = np.asarray(crossed, bool)
    obj = none if F_obj is None or not allowed else ~crossed & fill
    cube = none if F_obj is None or not allowed or not FILLED_CUBES else crossed & fill & ~use
    F = np.where(obj[:, None], np.asarray(F_obj if F_obj is not None else 0.0, np.float64), F) * k
    return use | obj | cube, np.clip(F, 0.0, 1.0), int(obj.sum()), int(cube.sum())

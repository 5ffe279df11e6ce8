"""Alpha where the photo is blown out (issue 30, fifth round): a prior from the depth's coverage.

Where a channel of the photo is clipped (``CLIP_LEVEL``), C = a F + (1 - a) B says almost nothing
about alpha: behind a needle before a sunlit wall, a pixel half covered is as white as an empty one.
capture.matting_known gives such pixels no data term, and the matting Laplacian carries the alpha of
the dark pixels around them in: on the path-traced conifer turntable the kept views' band pixels
whose photo is blown out had alpha 0.06-0.13 where the truth was 0.25 (87 % of the kept views' alpha
squared error; with the true alpha there the held-out view gained 2.2 dB, docs/matting.md fifth round).

The depth still saw the needles there.  :func:`blind_prior` takes, per view, the depth's local coverage (the share
of pixels with object depth in a (2 COVERAGE_RADIUS + 1)^2 box, sharpened by the pixel's own hit) as the alpha
expected there, and gives it to the blown-out pixels as a data term of weight R^2: the share of alpha's variance the
coverage explains on the view's pixels whose data term is not weak (IDENTITY_MIN_WEIGHT).  Where it explains
nothing (R^2 <= 0), too few pixels check it (IDENTITY_MIN_TRAIN), the depth has holes or there is nothing to fill,
no such prior is given (EMPTY_PRIOR may still pull empty pixels towards 0) and the record says why.  (Until stop 83 a
table of the coverage, fitted per view on the pixels of full data weight, came first; at MIN_CONFIDENCE 1.0 it was
taught in no view of any capture measured, and it went: docs/matting.md "The coverage table removed".)

Where the photo is not blown out but the data term is weak (``WEAK_PRIOR``: a needle before a background of
nearly its own colour, where C = a F + (1 - a) B hardly moves with alpha), the same prior goes in beside the
data, weighted R^2 (1 - weight / MIN_CONFIDENCE), where the data term's candidate colour is within its SEPARATION
of B (stop 62, docs/matting.md).

Where the photo is not blown out but the pixel still has no data term because the plate does not know its
background (``UNSEEN_PRIOR``: no frame saw it and the frames' lines gave none, capture.plate_shadow took them, or
the plate is blown out behind an unclipped photo), the prior goes in as at a blown-out pixel (stop 72,
docs/matting.md "Where no frame saw the background").

The prior is sharpened by the pixel's own depth hit (``HIT_DETAIL``: the coverage box spreads a needle's hit over 9
pixels; stop 77, docs/matting.md "What the room matte smooths away").

Where the coverage is refused, a weak pixel whose coverage box holds no object depth is pulled towards alpha 0
(``EMPTY_PRIOR``: a needle before a background of its own colour; stop 74, docs/matting.md "A night park"), unless the
depth has too many holes to be trusted where it saw nothing (``EMPTY_MAX_HOLES``, :func:`depth_holes`; stop 75).
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

#: Switch of the prior (capture.matting_known step 3); off: the Laplacian alone decides there.
BLIND_PRIOR = True
#: Linear level at which a photo channel counts as blown out (capture.matting_known.CLIP_LEVEL).
CLIP_LEVEL = 0.975
#: Radius of the coverage box (3 x 3: on the conifer turntable, 3 kept views, the table fitted on
#: the known band predicted the blown-out pixels' true alpha with R^2 0.60-0.65 at 3 x 3, 0.50-0.58 at
#: 5 x 5, 0.33-0.42 at 9 x 9, 0.21-0.25 from depth > 0 alone, 0.04-0.08 from the distance to the
#: trimap's background).
COVERAGE_RADIUS = 1
#: An R^2 is only measured where the alphas it is measured on vary: below this weighted variance (an alpha standard
#: deviation of 0.01) there is nothing to explain, and the R^2 is 0 (the prior is refused).  Found on the coverage
#: table (until stop 83): held-back pixels that were all opaque had been scored R^2 = 1 (stop 82).
MIN_R2_VARIANCE = 1e-4
#: A pixel whose data-term weight (capture.matting_known's confidence) is under this is weak (WEAK_PRIOR below), and
#: the prior goes beside its data with weight R^2 (1 - weight / MIN_CONFIDENCE).  1.0 since stop 82 (0.25 before; it
#: was also the weight a pixel needed to teach the coverage table, removed in stop 83): before a bright room a 320 x
#: 240 conifer's colour data are biased (its depth-opaque colour sources hold about 0.2 of the room: alpha +0.10), and
#: the prior weighs more beside them.  Held out under a rule written before 20 room captures ran (docs/matting.md "The
#: data term's weight", stop 82): mean +0.17 dB, the 320 x 240 conifers +0.01 to +1.02, bunnies +0.05 to +0.56, fur
#: -0.04 to +0.18, the worst -0.14 (a 640 x 480 orbit), SSIM -0.004 to +0.019, black twins within 0.01 dB.
MIN_CONFIDENCE = 1.0
#: The prior also goes to the unknown pixels whose data term is weak (weight in (0, MIN_CONFIDENCE), the photo not
#: clipped) because the candidate colour is within capture.matting_known.SEPARATION of B (a needle before a background
#: of nearly its own colour: C hardly moves with alpha), weighted R^2 (1 - weight / MIN_CONFIDENCE) beside the data.
#: (The figures below were measured with MIN_CONFIDENCE 0.25.)
#: The path-traced conifer orbit's kept views (four of them before a dark part of the courtyard): alpha squared error
#: 7841 -> 4835; the turntable 3387 -> 3361 (every weak pixel, not only these: 6618, and the test scenes' alpha worse).
#: Held out +0.043 dB on average over 8 room captures (SSIM +0.0037, over white up on every one), but the orbit lost
#: 0.055 dB, past the first rule's -0.05; a confirmatory rule written before rendering two fresh captures (seed 21,
#: room turned 90 degrees) was met there: orbit +0.209, turntable +0.348 dB (docs/matting.md, stop 62).  On.
WEAK_PRIOR = True
#: The prior also goes, as at a blown-out pixel, to the unknown pixels with no data term whose photo is not blown out:
#: where the plate does not know the background.  The Laplacian alone carried the opaque pixels' alpha out there: a fur
#: ball turning on a table (path-traced, auto exposure, a lens), whose silhouette no frame sees past, came out too
#: opaque in its fringe (alpha MSE 0.030 at those pixels of the kept views; the coverage table 0.020).  Held out on
#: eleven room captures it was not found on: mean +0.058 dB, from -0.034 (a fresh fur ball on a table before an
#: interior) to +0.32 (the conifer's auto-exposure orbit), held-out alpha MSE lower or the same on every one; the fur
#: ball it was found on +0.22 (docs/matting.md).  False: blown-out pixels only (the rule before).
UNSEEN_PRIOR = True
#: Where the coverage is refused (IDENTITY_PRIOR off, too few pixels to check it, it explains nothing there, or the
#: depth has holes), a weak pixel (as WEAK_PRIOR takes it) with no object depth anywhere in its coverage box is pulled
#: towards alpha 0: target (w t) / (w + q), weight w + q, q = EMPTY_PRIOR (1 - w / MIN_CONFIDENCE).  The depth saw
#: nothing there, and the data cannot tell the needle from the background.  Found on a conifer turning before a night
#: park, whose grass is the needles' own dark green (kept views' B luminance 0.031, F 0.042): 94 % of the band weak, the
#: table refused in 17 of 18 views, and the Laplacian left a grey veil (alpha 0.3-0.5) in the gaps between the lower
#: branches; held out 26.153 -> 26.402 dB, SSIM 0.5675 -> 0.5834, sharpness 0.92 both (q at 0.5; 1: +0.23, 3: +0.15); a
#: night orbit rendered after the choice +0.14; nothing moved on the 24 other captures (every table trained;
#: docs/matting.md, stop 74).  0: off.
EMPTY_PRIOR = 0.5
#: EMPTY_PRIOR trusts the depth's emptiness; a depth that misses needles makes it wrong.  Its guard: the depth's own
#: hole rate (:func:`depth_holes`, the share of pixels without object depth among those with object depth at
#: HOLE_NEIGHBOURS or more of their 8 neighbours); above EMPTY_MAX_HOLES the rule is refused and the record says so.
#: The night conifer turntable (clean path-traced depth 0.16-0.18 a view) with its depth pixels knocked out at random
#: (scripts/depth_dropout.py): 10 % -> 0.23-0.27, the rule +0.22 dB held out; 20 % -> 0.32-0.36, the rule -0.13;
#: 30 % -> 0.40-0.48, the rule -0.26 (docs/matting.md "A depth that misses needles", stop 75).
EMPTY_MAX_HOLES = 0.3
#: The coverage itself as the prior (before stop 83 only where the coverage table was refused), before EMPTY_PRIOR:
#: the prior alpha of a pixel is the share of object depth in its 3 x 3 box (a depth sampled at the colour's pixels,
#: as a path tracer's is: on the night conifer turntable's kept views the true alpha per coverage bin was within 0.03
#: of the coverage, R^2 0.82 over the band), with weight its R^2 on the view's pixels of data weight
#: IDENTITY_MIN_WEIGHT or more (nothing fitted to them: IDENTITY_MIN_TRAIN), and only where the depth passes
#: EMPTY_MAX_HOLES.  R^2 <= 0, too few such pixels or a depth with holes: EMPTY_PRIOR as before.  Held out: night
#: turntable 26.40 / 0.583 / 0.92 -> 27.19 / 0.643 / 0.85 (over white 16.62 -> 17.68, alpha MSE 0.0437 -> 0.0340),
#: night orbit 27.41 / 0.651 -> 27.70 / 0.670 (docs/matting.md "The depth's coverage as alpha", stop 75).  False:
#: EMPTY_PRIOR alone.
IDENTITY_PRIOR = True
#: Fewest pixels (of weight IDENTITY_MIN_WEIGHT or more) for IDENTITY_PRIOR's R^2 (a fixed predictor: no halves).
IDENTITY_MIN_TRAIN = 50
#: IDENTITY_PRIOR's R^2 is measured on the band's lit pixels whose data-term weight is at least this (MIN_CONFIDENCE
#: before stop 76).  At 0.25 a night park's sure pixels were 11-42 a view once the plate knew the grass (the check
#: then refused, and alpha MSE rose from 0.009 to 0.03 in 12 of 18 views), and they were all nearly opaque (alpha
#: 0.6-1, coverage 0.67-1): a sample that could not see a dilated depth (R^2 +0.05 to +0.86 with the depth grown by
#: one pixel, whose coverage explains -0.5 to -0.75 of alpha's variance over the band).  At 0.1: 3,300-6,000 pixels a
#: view, R^2 0.48-0.66 with the true depth, -0.45 to -1.1 grown by one pixel (+0.13, +0.15 in 2 of 9 views), below
#: -0.5 grown by two, about 0 eroded by one or shifted by 4 pixels.  A second night turntable (seed 811) had 200-320
#: pixels of weight 0.1 a view and R^2 below 0 on them in 13 of 18 views (alpha MSE 0.021-0.026 there, 0.008 where
#: the prior went); at 0.05: 2,000-3,000 pixels, R^2 0.13-0.51, held out +0.43 dB; on 611 at 0.05 still -0.08 to
#: -1.4 grown by one pixel, below -0.85 by two; 13 other captures the same digits (docs/matting.md "A dark room is
#: not a backdrop").
IDENTITY_MIN_WEIGHT = 0.05
#: The prior (IDENTITY_PRIOR's) plus HIT_DETAIL x (the pixel's own depth hit - its 3 x 3 coverage), clipped to [0, 1]:
#: the coverage box spreads a needle's hit over 9 pixels, the pixel's own hit says whether the needle crosses it
#: (IDENTITY_PRIOR's prior becomes (1 - HIT_DETAIL) coverage + HIT_DETAIL hit).  On a night park the room matte kept 58
#: % of the needles' fine alpha pattern (the error's part finer than 3 x 3 regressed on the truth's: slope -0.42; the
#: black twin's backdrop matte -0.16); at 0.5 the kept views' band alpha MSE 0.0077 -> 0.0056 and the slope -0.06 (4
#: views).  The data term cannot check it (its own fine pattern is noise there: R^2 against it falls with HIT_DETAIL),
#: so it was checked held out: found on a night turntable (seed 811, 27.66 / 0.659 / 0.86 -> 27.72 / 0.679 / 0.98), then
#: on twelve room captures under a rule written down before they ran (two courtyards among them, rendered after it):
#: PSNR +0.00 to +0.16, SSIM +0.002 to +0.025, sharpness up 0.03-0.12, black twins the same digits, and the same capture
#: with its depth rendered with 3 x 3 rays a pixel (every needle's hits dilated) +0.04 / +0.018 (docs/matting.md "What
#: the room matte smooths away", stop 77).
#: 0: the coverage alone (the rule before).
HIT_DETAIL = 0.5
#: Neighbours (of 8) with object depth that make a pixel the depth's interior for :func:`depth_holes`.
HOLE_NEIGHBOURS = 6
#: Fewest interior pixels for :func:`depth_holes` to be measured: fewer and EMPTY_PRIOR is refused (cannot check).
MIN_INTERIOR = 200


def coverage(mask: np.ndarray, radius: int = COVERAGE_RADIUS) -> np.ndarray:
    """(h, w) share of pixels with object depth (``mask``) in each pixel's (2 radius + 1)^2 box."""
    return ndimage.uniform_filter(np.asarray(mask, np.float64), 2 * radius + 1, mode="constant")


def depth_holes(mask: np.ndarray) -> tuple[float, int]:
    """(hole rate, interior pixels) of the object depth ``mask`` (h, w) bool: among the pixels with object depth at
    HOLE_NEIGHBOURS or more of their 8 neighbours (the interior), the share without object depth themselves."""
    m = np.asarray(mask, bool)
    box = ndimage.uniform_filter(m.astype(np.float64), 3, mode="constant") * 9.0
    inner = (box - m) >= HOLE_NEIGHBOURS - 0.5
    n = int(inner.sum())
    return (float((inner & ~m).sum()) / n if n else 1.0), n


def _weighted_r2(pred: np.ndarray, y: np.ndarray, w: np.ndarray) -> float:
    """The share of ``y``'s ``w``-weighted variance that ``pred`` explains (1 - weighted SSE / weighted SS); 0 where
    that variance is under MIN_R2_VARIANCE (nothing to explain)."""
    mu = (w * y).sum() / w.sum()
    ss = float((w * (y - mu) ** 2).sum())
    if ss < MIN_R2_VARIANCE * float(w.sum()):
        return 0.0
    return float(1.0 - (w * (pred - y) ** 2).sum() / max(ss, 1e-12))


def blind_prior(image: np.ndarray, unknown: np.ndarray, target: np.ndarray, weight: np.ndarray,
                mask: np.ndarray | None, similar: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, dict]:
    """(target, weight, record): the data term (``target``, ``weight``, each (h, w), of
    capture.matting_known.data_term) with the coverage prior (module docstring) added at the
    ``unknown`` pixels which have no data term (with UNSEEN_PRIOR off: only those whose photo ``image`` is blown
    out); ``mask``: the object's depth (h, w) bool (None: no prior); ``similar`` (h, w) bool: where the data term's
    candidate colour is within its SEPARATION of B, the only weak pixels WEAK_PRIOR takes (None: every weak pixel).
    The record: ``used`` (the coverage was given), else ``reason``; ``r2`` (the coverage's R^2 on ``sample`` pixels,
    those of data weight IDENTITY_MIN_WEIGHT or more), ``prior`` (pixels it went to), ``depth_holes``, and
    EMPTY_PRIOR's counts (:func:`_empty_prior`)."""
    C = np.asarray(image)
    lit = C.max(axis=-1) < CLIP_LEVEL
    blind = np.asarray(unknown, bool) & (weight <= 0)
    unseen = blind & lit  # UNSEEN_PRIOR: no data term although the photo is not blown out (B not known)
    blind &= ~lit | UNSEEN_PRIOR
    weak = np.asarray(unknown, bool) & lit & (weight > 0) & (weight < MIN_CONFIDENCE)
    if not WEAK_PRIOR:
        weak[:] = False
    elif similar is not None:
        weak &= np.asarray(similar, bool)
    rec = {"blind": int(blind.sum()), "unseen": int(unseen.sum()) if UNSEEN_PRIOR else 0, "weak": int(weak.sum()),
           "band": int(np.count_nonzero(unknown))}
    if not BLIND_PRIOR or mask is None or not (blind.any() or weak.any()):
        return target, weight, dict(rec, used=False, reason="off" if not BLIND_PRIOR else
                                    "no depth" if mask is None else "nothing blown out")
    cov = coverage(mask)
    detail = HIT_DETAIL * (np.asarray(mask, np.float64) - cov)  # the pixel's own hit (HIT_DETAIL)
    empty = weak & (cov <= 0)  # EMPTY_PRIOR's pixels, where the coverage is refused
    sample = np.asarray(unknown, bool) & (weight >= IDENTITY_MIN_WEIGHT) & lit  # the coverage's check
    rec["sample"] = int(sample.sum())
    if not IDENTITY_PRIOR or rec["sample"] < IDENTITY_MIN_TRAIN:
        why = "off" if not IDENTITY_PRIOR else "too few pixels to check the coverage"
        return _empty_prior(target, weight, empty, mask, dict(rec, used=False, reason=why))
    holes = depth_holes(mask)
    r2 = _weighted_r2(cov[sample], target[sample], weight[sample])
    rec = dict(rec, r2=round(r2, 4), depth_holes=round(holes[0], 4))
    if r2 <= 0 or holes[1] < MIN_INTERIOR or holes[0] > EMPTY_MAX_HOLES:
        why = ("coverage explains nothing" if r2 <= 0 else "too little depth to check it" if holes[1] < MIN_INTERIOR
               else "the depth has holes")
        return _empty_prior(target, weight, empty, mask, dict(rec, used=False, reason=why), holes)
    t, wt = _give(target, weight, np.clip(cov + detail, 0.0, 1.0), r2, blind, weak)
    return t, wt, dict(rec, used=True, empty=0, prior=int((blind | weak).sum()))


def _give(target, weight, prior, r2: float, blind, weak) -> tuple:
    """(target, weight) with ``prior`` (h, w) given as the data term at the ``blind`` pixels (weight ``r2``) and beside
    the weak data term at the ``weak`` ones (WEAK_PRIOR: weight r2 (1 - w / MIN_CONFIDENCE))."""
    pw = np.where(weak, r2 * (1.0 - weight / MIN_CONFIDENCE), 0.0)
    mixed = (weight * target + pw * prior) / np.maximum(weight + pw, 1e-12)
    return np.where(blind, prior, np.where(weak, mixed, target)), np.where(blind, r2, weight + pw)


def _empty_prior(target: np.ndarray, weight: np.ndarray, empty: np.ndarray, mask: np.ndarray, rec: dict,
                 holes: tuple | None = None) -> tuple:
    """(target, weight, record) with the ``empty`` pixels (weak, no object depth in their coverage box) pulled towards
    alpha 0 by EMPTY_PRIOR (its comment) unless the depth ``mask`` has too many holes to be trusted empty
    (EMPTY_MAX_HOLES); the record counts them (``empty``) and, where refused, the pixels (``empty_refused``) and why
    (``empty_reason``); ``depth_holes``: the hole rate measured (``holes``: :func:`depth_holes` of ``mask`` when
    already measured)."""
    if EMPTY_PRIOR <= 0 or not empty.any():
        return target, weight, dict(rec, empty=0)
    holes, inner = depth_holes(mask) if holes is None else holes
    rec = dict(rec, depth_holes=round(holes, 4))
    if inner < MIN_INTERIOR or holes > EMPTY_MAX_HOLES:
        why = "too little depth to check it" if inner < MIN_INTERIOR else "the depth has holes"
        return target, weight, dict(rec, empty=0, empty_refused=int(empty.sum()), empty_reason=why)
    q = np.where(empty, EMPTY_PRIOR * (1.0 - weight / MIN_CONFIDENCE), 0.0)
    t = np.where(empty, weight * target / np.maximum(weight + q, 1e-12), target)
    return t, weight + q, dict(rec, empty=int(empty.sum()))

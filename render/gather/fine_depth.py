"""Gather's fine depth (GatherConfig.fine_depth): whether a model's frames take their depth from 1-pixel splats first.

Gather splats the nearest kept views' points in 2 x 2-pixel splats and keeps the nearest z (render.gather.reference,
step 1).  On a conifer a needle in front then lends its z to the pixels beside it, whose own points lie behind it:
on a path-traced courtyard turntable (hardcases61, its kept views' true mattes) the splatted z was more than 3 mm
nearer than the held-out frame's own depth at 58-64 % of the needle pixels, and the kept views' mattes, projected
with it, missed their needles (held-out alpha at true alpha >= 0.9: 0.83; with the true depth 0.90).  With the 1-pixel
splats' z wherever one lands and the 2 x 2 splats only where none does, that capture's held-out alpha MSE fell
0.0166 -> 0.0138 and its composite over white rose 0.9 dB.  On fur and furry bunnies the same costs 0.01-0.07 dB and
up to 0.007 SSIM: a body under a coat is covered by the wide splats, and the narrow ones let the coat's gaps through.

"auto" tells them apart by the kept mattes: a crown of needles is mostly partial pixels (the share of a view's matte
pixels, alpha > MATTE_MIN, with alpha < OPAQUE: 0.91-0.97 on twelve conifers), a body under fur mostly opaque
(0.21-0.29 on nine fur balls and bunnies); PARTIAL_SHARE lies between.  Measured in docs/novel_views.md "Fine depth".
"""

from __future__ import annotations

import numpy as np

from render.gather.alpha_mass import loo_views

#: Matte pixels counted (alpha above this) and those counted partial (alpha below OPAQUE).
MATTE_MIN, OPAQUE = 0.05, 0.95
#: "auto" turns fine depth on where the median share of partial matte pixels over the views sampled is at least
#: this (conifers 0.91-0.97, fur and bunnies 0.21-0.29: the midpoint).
PARTIAL_SHARE = 0.6
#: Views sampled for the share (evenly spread, render.gather.alpha_mass.loo_views).
SHARE_VIEWS = 12


def partial_share(alphas) -> float:
    """The median over ``alphas`` (an iterable of (h, w) mattes; None entries skipped) of the share of matte pixels
    (alpha > MATTE_MIN) with alpha < OPAQUE; NaN without a matte pixel."""
    shares = []
    for a in alphas:
        if a is None:
            continue
        a = np.asarray(a)
        m = a > MATTE_MIN
        if m.any():
            shares.append(float(np.mean(a[m] < OPAQUE)))
    return float(np.median(shares)) if shares else float("nan")


def use_fine(mode: str, alphas, n_views: int | None = None) -> bool:
    """Whether a model's frames take fine depth (:func:`decide`'s first value)."""
    return decide(mode, alphas, n_views)[0]


def decide(mode: str, alphas, n_views: int | None = None) -> tuple[bool, float]:
    """(whether a model's frames take fine depth, the share it was decided on): ``mode`` "on" / "off" as said (share
    NaN); "auto": :func:`partial_share` of the sampled views' mattes (``alphas``: a sequence, or a function of the
    view index with ``n_views``) at least PARTIAL_SHARE (False, NaN without a matte)."""
    if mode != "auto":
        return mode == "on", float("nan")
    if alphas is None:
        return False, float("nan")
    if callable(alphas):
        share = partial_share(alphas(k) for k in loo_views(int(n_views or 0), SHARE_VIEWS))
    else:
        share = partial_share(alphas[k] for k in loo_views(len(alphas), SHARE_VIEWS))
    return bool(share >= PARTIAL_SHARE), share

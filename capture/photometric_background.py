"""Whether the gains the object's cells ask for are in the background too (the photometric check's second witness).

The photometric stage (capture.photometric, capture.photometric_check) fits a gain per view (and channel) to what
neighbouring views see of the same *object* surface, and takes it where held-back cells agree.  On a capture
with a room behind the object that evidence is not only the camera's: each view's matted colour carries that
view's own unmixing error (the room behind it, its plate), and fur changes with the view.  A path-traced furry
bunny orbited at one fixed exposure was given gains of up to 0.38 EV (0.18 EV RMS) that way, and lost 0.15 dB
held out against no alignment (docs/real_cameras.md, stop 71).

A camera's exposure and white balance change the whole frame, the background as much as the object.  Where the
capture has a background plate (capture.plate), its exposure check (capture.plate_fixed.fixed_exposure_check,
capture.plate_exposure.panorama_exposure_check) has each view's held-back background predicted by the *other*
views at gain 1 (a fixed camera: the other frames' median; a moving camera: the panorama of the others), and
records per view the median log2 ratio of the two (``ring_log2``): the view's exposure against the others'.
:func:`background_verdict` asks whether the gains the cells proposed make those ratios more alike or less: per
view, the mean absolute deviation over the channels about the views' median, with the gains applied against
without; the gains are refused where they make it worse in at least ceil(V / 2 + sqrt(V)) views (the plate
exposure check's count) and the views' median worsens by at least BG_WORSE_EV.  Too few views with a ratio
(BG_MIN_VIEWS, each from at least BG_MIN_PIXELS ring pixels): no verdict, the cells decide as before.
"""

from __future__ import annotations

import numpy as np

#: Held-back ring pixels of a view below which its ratio is not used.
BG_MIN_PIXELS = 200
#: Views with a ratio needed for a verdict, as a share of the views.
BG_MIN_VIEWS = 0.6
#: The views' median spread (EV, all channels) must worsen by at least this for the gains to be refused.
BG_WORSE_EV = 0.02


def background_verdict(ratios, gains: np.ndarray) -> dict | None:
    """Whether the per-view ``gains`` (V, 3) are refused by the background (module docstring): None without a
    verdict, else a dict: ``refused`` (bool), ``views`` (with a ratio), ``worse`` (views made worse), ``needed``,
    ``spread_none_ev`` / ``spread_gains_ev`` (the views' median spread) and ``reason``.  ``ratios``: per view
    the (3,) log2 ratio of the plate exposure check's ``ring_log2`` or None."""
    g = np.log2(np.asarray(gains, np.float64))
    have = np.array([r is not None for r in ratios], bool)
    V = len(ratios)
    if V < 3 or have.sum() < max(3, int(np.ceil(BG_MIN_VIEWS * V))):
        return None
    r = np.asarray([ratios[i] for i in np.flatnonzero(have)], np.float64)
    with_g = r + g[have]

    def spread(x):
        return np.abs(x - np.median(x, axis=0)).mean(-1)

    s0, s1 = spread(r), spread(with_g)
    n = len(r)
    need = int(np.ceil(n / 2 + np.sqrt(n)))
    worse = int((s1 > s0).sum())
    m0, m1 = float(np.median(s0)), float(np.median(s1))
    refused = worse >= need and m1 - m0 >= BG_WORSE_EV
    words = (f"the background around the object (each view's ring against the other views, {n} views) varies by "
             f"{m0:.3f} EV about the views' median, {m1:.3f} EV with the gains applied: worse in {worse} of {n} views")
    return {"refused": bool(refused), "views": n, "worse": worse, "needed": need, "spread_none_ev": round(m0, 4),
            "spread_gains_ev": round(m1, 4), "reason": words}

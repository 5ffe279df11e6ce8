"""Where the background came from the frames' lines: unmix the colour there, or fill it (issue 30, sixth round).

Where a frame saw the background B clean, the straight colour is exact, F = B + (C - B) / a
(capture.matting_known.foreground_colour, step 4).  Where B is the frames' lines' estimate
(capture.plate_lines), its error dB enters F times (1 - a) / a; the other choice is the fill of step
4 (the nearest sure colours, push-pull; pymatting's ML foreground before a dark background), whose
error does not grow as a falls.  Neither wins everywhere: on seeded needle scenes unmixing wins when
the lines err by std 0.009 and the fill when they err by 0.027 (docs/matting.md, fifth round).

:func:`colour_gate` chooses per pixel by the expected error of the premultiplied colour a F (what a
render over black shows) of each branch:

* unmixing: a F = C - (1 - a) B_est is off by (a - a_true) B - (1 - a) dB: expected squared error
  (1 - a)^2 sigma_B^2 + sigma_a^2 |B|^2, with sigma_B the plate's own uncertainty of the lines' vertex
  (``Plate.sigma``: capture.plate_lines, held to the lines' real error on held-back pixels);
* the fill: a F_fill is off by a (F_fill - F) + (a - a_true) F: a^2 sigma_F^2 + sigma_a^2 |F_fill|^2,
  with sigma_F the fill's error measured in the same view on held-back sure colours (:func:`fill_error`:
  the exact colours of pixels whose background was seen and whose alpha is at least FILL_ALPHA, a
  checkerboard of HOLD_BLOCK-pixel blocks, each half filled from the other);
* sigma_a, the alpha's error, measured in the view where B was seen (:func:`alpha_error`, a lower
  bound) and scaled up where B lies nearer the colour than there (:func:`alpha_variance`).

Before a bright room the alpha's term decides: an alpha 0.05 off moves the unmixed colour by 0.05 |B|
and the filled one by 0.05 |F|.  A pixel is unmixed when its expected error is below the fill's;
otherwise it is filled (and with GATE_SEEN the same choice where B was seen, sigma_B 0).  When the
fill's or the alpha's error cannot be measured (fewer than HOLD_MIN pixels), or the plate reports no
sigma (or inf: not measured), the rule cannot tell which wins and falls back to filling every estimated
pixel (the fifth round's COLOUR_FROM_SEEN rule) and says so.  The record (``Matte.notes['colour']``)
counts the pixels that took each branch.
"""

from __future__ import annotations

import numpy as np

from capture.fill import push_pull
from capture.matting_fast import channel_sum
from capture.matting_known import FILL_ALPHA, MIN_SOURCES, clipped

#: Held-back blocks of the fill's error (:func:`fill_error`), pixels: a held-back sure colour lies up
#: to this far from the nearest one filled from, as a partial needle pixel lies a few pixels from the
#: nearest sure colour.
HOLD_BLOCK = 8
#: Least sure colours in each half of the checkerboard for the fill's error (as the fill's own
#: capture.matting_known.MIN_SOURCES).
HOLD_MIN = MIN_SOURCES
#: Unmixing wins where its expected premultiplied error (1 - a) sigma_B is below UNMIX_RATIO times
#: the fill's, a sigma_F: both are expected errors of the same quantity, compared as they are (1: not tuned).
UNMIX_RATIO = 1.0
#: The same choice where a frame saw B clean (sigma_B 0: only the alpha's error against the fill's; the
#: fill's own sources, alpha >= FILL_ALPHA, stay unmixed; before a dark background step 4's fill is
#: pymatting's).  Held out (gather masked PSNR, docs/matting.md sixth round), off / on: conifer
#: turntable 24.59 / 24.64, orbit 25.88 / 26.09, room + table + AE + lens 24.43 / 24.57; restricted to
#: backgrounds bright enough for the push-pull fill (whose error sigma_F is): 24.65, 26.05, 24.49.
GATE_SEEN = True
#: An estimated background of unknown uncertainty (the plate's sigma inf: a blown-out bound, or its
#: held-back check could not run) counts as this uncertain (linear): never unmixed.
SIGMA_UNKNOWN = 1e3
#: The gate's squared norms over the three channels by capture.matting_fast.channel_sum (numpy's own
#: order: the same values bit for bit), |B|^2 once; False: numpy's ``.sum(-1)`` each time (the
#: reference; docs/speed.md round 12).
GATE_SUMS = True


def _sum(x: np.ndarray) -> np.ndarray:
    return x.sum(-1)


def fill_error(F: np.ndarray, sure: np.ndarray, block: int = HOLD_BLOCK) -> float | None:
    """RMS (Euclidean over the channels) error of the push-pull fill at held-back ``sure`` pixels of the
    exact colours ``F`` (h, w, 3): the sure pixels split by a checkerboard of ``block``-pixel blocks,
    each half filled from the other; None when a half holds fewer than HOLD_MIN."""
    h, w = sure.shape
    parity = ((np.arange(h)[:, None] // block + np.arange(w)[None] // block) % 2).astype(bool)
    halves = (sure & parity, sure & ~parity)
    if min(int(x.sum()) for x in halves) < HOLD_MIN:
        return None
    sq = []
    for src, held in (halves, halves[::-1]):
        pred = push_pull(F, src.astype(np.float64))
        sq.append(((pred - F)[held] ** 2).sum(-1))
    return float(np.sqrt(np.mean(np.concatenate(sq))))


def alpha_error(image: np.ndarray, alpha: np.ndarray, background: np.ndarray, fill: np.ndarray, where: np.ndarray,
                sigma_f: float) -> tuple[float, float] | None:
    """RMS error of ``alpha`` estimated at the ``where`` pixels (B seen, partial, not a fill source):
    there the unmixed premultiplied colour C - (1 - a) B differs from the filled one a F_fill by
    (a - a_true) (B - F) - a (F_fill - F), so E|D|^2 = sigma_a^2 E|B - F|^2 + E[a^2] sigma_F^2, taken
    with F_fill for F and ``sigma_f`` the fill's error (:func:`fill_error`): (sigma_a, E|B - F|^2 there);
    None with fewer than HOLD_MIN pixels.  A lower bound: the alpha's error along the line of the
    candidate colour it was solved with (capture.matting_known step 2: the nearest sure colour, the
    fill's) does not show in D (conifer turntable: 0.042 against the true 0.057; seeded needle
    scenes 0.005-0.02 against 0.02)."""
    if int(where.sum()) < HOLD_MIN:
        return None
    a = alpha[where][:, None]
    C, B, Ff = image[where], background[where], fill[where]
    d2 = ((C - (1.0 - a) * B - a * Ff) ** 2).sum(-1)
    sep = ((B - Ff) ** 2).sum(-1)
    ref = max(float(sep.mean()), 1e-9)
    return float(np.sqrt(max(0.0, d2.mean() - float((a ** 2).mean()) * sigma_f ** 2) / ref)), ref


def alpha_variance(sigma_a: tuple[float, float], sep2: np.ndarray) -> np.ndarray:
    """(h, w) expected squared alpha error: the view's ``sigma_a`` = (sigma, E|B - F|^2 where it was
    measured; :func:`alpha_error`) scaled up where the pixel's background lies nearer its colour than
    that (``sep2`` = |B - F_fill|^2): alpha is read off where C lies between B and F, so its error grows
    as 1 / |B - F| (the conifer turntable's kept views: alpha RMS 0.12 where |B| < 0.2, 0.05 where
    |B| is 0.3-0.6); never scaled down (a background far from the colour does not make the rest of the
    solve, the Laplacian and the priors, surer than the view's measure).  At most 1."""
    s, ref = sigma_a
    return np.minimum(s ** 2 * np.maximum(1.0, ref / np.maximum(sep2, 1e-12)), 1.0)


def colour_gate(estimated: np.ndarray, sigma: np.ndarray | None, record: dict | None = None):
    """A function ``(image, alpha, background, known) -> known for the colour`` (each (h, w[, 3]) of
    one crop) for capture.matting_known.foreground_colour: ``known`` less the ``estimated`` pixels
    whose colour is better filled (module docstring); ``sigma`` (h, w): the plate's uncertainty of the
    estimated background (None: not reported).  Its record goes into ``record['colour']``."""
    est = np.asarray(estimated, bool)

    def gate(image, alpha, background, known):
        known = np.asarray(known, bool)
        a = np.asarray(alpha, np.float64)
        C = np.clip(np.asarray(image, np.float64), 0.0, 1.0)
        B = np.clip(np.asarray(background, np.float64), 0.0, 1.0)
        hot = clipped(C, B)
        open_ = known & est & ~hot & (a > 0)  # blown-out pixels stay known: step 4 fills them
        seen = known & ~est & ~hot
        F = unmixed_colour(C, B, a)
        sure = seen & (a >= FILL_ALPHA)
        measure = (open_.any() and sigma is not None) or (GATE_SEEN and seen.any())
        sigma_f = fill_error(F, sure) if measure else None
        sigma_a = None
        if sigma_f is not None:
            Ff = push_pull(F, sure.astype(np.float64))
            sigma_a = alpha_error(C, a, B, Ff, seen & (a > 0) & (a < FILL_ALPHA), sigma_f)
        unmix = drop = np.zeros(a.shape, bool)
        if sigma_a is not None:  # the alpha's error enters a F as (a - a_true) B unmixed, (a - a_true) F filled
            s_b = SIGMA_UNKNOWN if sigma is None else \
                np.minimum(np.nan_to_num(np.asarray(sigma, np.float64), nan=np.inf), SIGMA_UNKNOWN)
            norm = channel_sum if GATE_SUMS else _sum
            var_a = alpha_variance(sigma_a, norm((B - Ff) ** 2))
            b2 = norm(B ** 2)
            e_unmix = ((1.0 - a) * s_b) ** 2 + var_a * b2
            e_fill = (a * sigma_f) ** 2 + var_a * norm(Ff ** 2)
            unmix = open_ & (e_unmix < UNMIX_RATIO ** 2 * e_fill)
            if GATE_SEEN:  # where B was seen (sigma_B 0) the same comparison; the fill's sources stay unmixed
                drop = seen & (a > 0) & (a < FILL_ALPHA) & \
                    (var_a * (b2 if GATE_SUMS else norm(B ** 2)) >= UNMIX_RATIO ** 2 * e_fill)
        rec = {"estimated": int(open_.sum()), "unmixed": int(unmix.sum()), "filled": int((open_ & ~unmix).sum()),
               "seen_filled": int(drop.sum()),
               "sigma_fill": None if sigma_f is None else round(sigma_f, 5),
               "sigma_alpha": None if sigma_a is None else round(sigma_a[0], 5)}
        if open_.any() and (sigma is None or sigma_a is None):
            rec["reason"] = "no sigma from the plate" if sigma is None else \
                "too few sure colours to measure the fill" if sigma_f is None else \
                "too few partial pixels before a seen background to measure the alpha"
        if record is not None:
            record["colour"] = rec
        return known & ~(open_ & ~unmix) & ~drop

    return gate


def unmixed_colour(C: np.ndarray, B: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """(..., 3) the straight colour under a known background, F = clip(B + (C - B) / a, 0, 1), alpha
    floored at 1e-6 (``C``, ``B`` (..., 3) clipped to [0, 1] by the caller, ``alpha`` (...))."""
    return np.clip(B + (C - B) / np.maximum(alpha, 1e-6)[..., None], 0.0, 1.0)

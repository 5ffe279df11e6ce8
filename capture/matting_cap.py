"""The premultiplied colour before a blown-out plate, kept within the photo (issue 30).

Whatever lies behind a pixel (B >= 0), its premultiplied colour a F = C - (1 - a) B is at most the photo C in every
channel the photo did not clip.  Where B is known that holds by construction (F is unmixed from C); before a
blown-out plate step 4 of capture.matting_known gives the pixel the colour of the nearest sure pixels (or pymatting's
estimate) instead, and before a sunlit wall those can be far brighter than the object: on a fur ball's orbit
(s24furorb) the body before the wall (alpha 0.99, the photo 0.25 / 0.16 / 0.09) took 0.47 / 0.24 / 0.09 where the
truth is 0.19 / 0.10 / 0.04 (docs/matting.md "Other rooms behind the conifer, and a fur ball before a blown-out
wall").  :func:`blown_cap` applies the bound.  The tighter bound C - (1 - a) B_plate (the true B is at least the plate)
was tried first: where the matte's alpha is below the truth it cut the true colour (a conifer before the sunlit wall
lost 0.08 dB held out), so the bound takes no alpha.

The bound's slack is the photo's own noise, NOISE_ABS + NOISE_REL C (CAP_SLACK_OF_PHOTO): B does not enter
a F <= C.  It was NOISE_REL B, the noise of C - B in capture.matting_known.alpha_lower_bound, which before a blown
plate (B about 1) let a dark body's fill be 0.034 linear above the photo: a furry bunny's orbit had 172,689 truly
opaque kept-view pixels (their photo exactly the black twin's) 0.073 too bright in 8-bit sRGB, 27 % of its kept views'
colour error; held out 21.315 -> 21.623 dB (docs/matting.md "Before a blown-out plate, the photo bounds a dark
body's colour").
"""

from __future__ import annotations

import numpy as np

#: Cap the colour before a blown-out plate (:func:`blown_cap`); False: as before.
BLOWN_CAP = True
#: The cap's slack is the photo's noise, NOISE_ABS + NOISE_REL C (module docstring); False: NOISE_ABS + NOISE_REL B,
#: the plate's (the rule before stop 58).
CAP_SLACK_OF_PHOTO = True
#: A view is named (:func:`blown_partial`, the matte's record and console line) when at least this share of its
#: partial pixels lies before a blown-out plate: their colour is a fill there, not a measurement.  On the furry bunny's
#: path-traced orbit before the sunlit courtyard (docs/matting.md "Fur before a blown-out wall") the six views that
#: carry the room's loss have 0.11-0.58 of them, the other twelve at most 0.04; the fur ball's orbit names four
#: (0.12-0.27), the conifer's orbit before the same wall eight (0.12-0.97), the bunny on a table none.
BLOWN_VIEW_SHARE = 0.1


def blown_cap(F: np.ndarray, image: np.ndarray, alpha: np.ndarray, background: np.ndarray,
              blown: np.ndarray) -> np.ndarray:
    """``F`` (h, w, 3) with each ``blown`` pixel's channels capped where the photo's is not clipped: a F at most
    C + NOISE_ABS + NOISE_REL C (the photo's noise; with CAP_SLACK_OF_PHOTO off NOISE_REL B, B the plate clipped to
    [0, 1]), which holds for any alpha and any background.  ``F`` itself where BLOWN_CAP is off or no pixel is blown."""
    from capture.matting_known import CLIP_LEVEL, NOISE_ABS, NOISE_REL

    blown = np.asarray(blown, bool) & (np.asarray(alpha) > 0)
    if not BLOWN_CAP or not blown.any():
        return F
    C = np.asarray(image, np.float64)[blown]
    noisy = C if CAP_SLACK_OF_PHOTO else np.clip(np.asarray(background, np.float64)[blown], 0.0, 1.0)
    a = np.asarray(alpha, np.float64)[blown][:, None]
    cap = (C + NOISE_ABS + NOISE_REL * noisy) / np.maximum(a, 1e-6)
    out = np.array(F, np.float64, copy=True)
    out[blown] = np.where(C < CLIP_LEVEL, np.minimum(out[blown], cap), out[blown])
    return out


def blown_partial(alpha: np.ndarray, background: np.ndarray, known: np.ndarray) -> tuple[int, int]:
    """(partial pixels before a blown-out plate, partial pixels) of a view's matte: 0 < ``alpha`` < 1, and the known
    plate ``background`` (h, w, 3) reaching capture.matting_known.CLIP_LEVEL in a channel.  Their straight colour
    is capture.matting_known.foreground_colour's fill: a clipped background leaves C = a F + (1 - a) B without F."""
    from capture.matting_known import CLIP_LEVEL

    a = np.asarray(alpha)
    partial = (a > 0) & (a < 1)
    behind = np.asarray(background).reshape(-1, 3)[np.flatnonzero(partial & np.asarray(known, bool))]
    return int(np.count_nonzero((behind >= CLIP_LEVEL).any(axis=1))), int(np.count_nonzero(partial))

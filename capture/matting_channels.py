"""Alpha from the channels that are not clipped (issue 30): a sky blown out in red and green, not in blue.

capture.matting_known counts a pixel whose photo or plate reaches ``CLIP_LEVEL`` in any channel as one
whose background is not known: there C = a F + (1 - a) B no longer holds, since the true B of a blown-out
window is above 1.  It still holds channel by channel, in every channel that neither the photo nor the
plate clipped.  Before a bright courtyard most blown-out plate pixels are clipped in one or two channels
only (a warm sky: red and green at 1, blue below), and one channel left is one equation for one unknown
once the colour is a candidate's.

The same holds for a bound: where the plate clipped a channel and the photo did not, the true B there is at least
the plate's, and a = (B - C) / (B - F) only grows with B.  capture.matting_known.blown_bound takes F = 0 (a bound
whatever the colour); :func:`colour_bound` takes the nearest sure colour for F, which a dark needle before a sky
needs (with F = 0 it is 1 - C, the faint needle's alpha).

:func:`open_channels` says which channels hold; :func:`channel_alpha` is step 2 of capture.matting_known
(the projection of D = C - B on P - B, clipped to [bound, 1], and its confidence from how far P is from B and how
well it explains C) summed over those channels only, with the nearest sure colour as the one candidate (the
palette's margin is a rule for three channels; with one, every dark candidate fits).

Measured on the path-traced conifer turntable's 18 kept views (docs/matting.md, "The channels a clipped
pixel keeps"): 3,000-3,600 pixels a view are clipped in the photo or plate but keep a channel; their alpha
RMS against the true matte was 0.095 with no data term there (the blind prior and the Laplacian), 0.056
from the open channels with the model's colour.  The pixels before a plate clipped in every channel whose photo
kept one: alpha MSE 0.0099 with the bound at F = 0, 0.0074 with :func:`colour_bound`.
"""

from __future__ import annotations

import numpy as np

#: Switch (capture.matting_known's data term, step 2); off: a pixel clipped in any channel gets no data
#: term (the blind prior and the Laplacian decide, as before).
CLIPPED_CHANNELS = True
#: Switch of :func:`colour_bound`; off (the default): the bound against a blown plate takes F = 0
#: (capture.matting_known.blown_bound).  On, the conifer turntable's kept views' alpha MSE before a plate clipped in
#: every channel fell 0.0099 -> 0.0074, but held out it moved 8 room captures by -0.001 dB on average (-0.015 to
#: +0.006; SSIM +0.0003, over white +0.02 dB on two): not the default (docs/matting.md, stop 62).
COLOUR_BOUND = False


def open_channels(image: np.ndarray, background: np.ndarray, level: float, where: np.ndarray) -> np.ndarray | None:
    """(h, w, 3) bool: channels below ``level`` in both the photo ``image`` and the plate ``background``
    at the ``where`` (h, w) pixels (False elsewhere); None with CLIPPED_CHANNELS off."""
    if not CLIPPED_CHANNELS:
        return None
    return (np.asarray(image) < level) & (np.asarray(background) < level) & np.asarray(where, bool)[..., None]


def channel_alpha(image: np.ndarray, background: np.ndarray, colour: np.ndarray, channels: np.ndarray,
                  lower: np.ndarray, separation: float, residual: float) -> tuple[np.ndarray, np.ndarray]:
    """(alpha_hat (n,), confidence (n,)) of n pixels: ``image``, ``background``, the candidate ``colour``
    (each (n, 3), linear) over the ``channels`` (n, 3) bool that hold; ``lower`` (n,) the alpha bound.
    Confidence as capture.matting_known.candidate_alpha's (``separation``, ``residual``, linear), over
    the same channels; 0 where no channel holds."""
    w = np.asarray(channels, np.float64)
    D = (np.asarray(image, np.float64) - background) * w
    E = (np.asarray(colour, np.float64) - background) * w
    e2 = (E * E).sum(-1)
    a = np.clip((D * E).sum(-1) / np.maximum(e2, 1e-9), lower, 1.0)
    res2 = ((D - a[:, None] * E) ** 2).sum(-1)
    conf = (e2 / (e2 + separation ** 2)) * (residual ** 2 / (res2 + residual ** 2))
    return a, np.where(w.any(-1), conf, 0.0)


def open_channel_term(image: np.ndarray, background: np.ndarray, nearest: np.ndarray, channels: np.ndarray,
                      where: np.ndarray, target: np.ndarray, weight: np.ndarray,
                      constants: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray]:
    """(target, weight) of capture.matting_known's data term with :func:`channel_alpha` put in at the
    ``where`` (h, w) pixels that keep an open channel (``channels`` (h, w, 3)); the candidate is the
    nearest sure colour ``nearest`` (h, w, 3); ``constants``: capture.matting_known's (DATA_WEIGHT,
    SEPARATION, RESIDUAL): the weight is DATA_WEIGHT times the confidence."""
    data_weight, separation, residual = constants
    idx = np.nonzero(np.asarray(where, bool) & channels.any(-1))
    if not len(idx[0]):
        return target, weight
    a, conf = channel_alpha(image[idx], background[idx], nearest[idx], channels[idx], 0.0, separation, residual)
    target, weight = target.copy(), weight.copy()
    target[idx], weight[idx] = a, data_weight * conf
    return target, weight


def open_count(image: np.ndarray, background: np.ndarray, level: float, where: np.ndarray) -> int:
    """Pixels of ``where`` that keep an open channel (:func:`open_channels`; 0 with CLIPPED_CHANNELS off)."""
    ch = open_channels(image, background, level, where)
    return 0 if ch is None else int(ch.any(-1).sum())


def colour_bound(image: np.ndarray, background: np.ndarray, colour: np.ndarray, where: np.ndarray, level: float,
                 noise: float) -> np.ndarray:
    """(h, w) least alpha at the ``where`` pixels from each channel that the plate clipped (``level``) and the photo
    did not: in such a channel the true B is at least the plate's, and a = (B - C) / (B - F) only grows
    with B, so a >= (B - C - noise) / (B - F) with the candidate colour ``colour`` for F (a dark needle before a sky
    the plate holds at 1 covers more than 1 - C); the largest over those channels, 0 elsewhere and with COLOUR_BOUND
    off.  Only the photo's ``noise`` is allowed for: a clipped plate's own error can only raise B, and the bound."""
    out = np.zeros(np.shape(image)[:2])
    if not COLOUR_BOUND:
        return out
    C, B = np.asarray(image), np.asarray(background)
    use = np.asarray(where, bool) & (C.min(-1) < level) & (B.max(-1) >= level)
    if not use.any():
        return out
    c, b, f = (np.asarray(x, np.float64)[use] for x in (C, B, colour))
    lo = (b - c - noise) / np.maximum(b - f, 1e-6)
    out[use] = np.clip(np.where((b >= level) & (c < level) & (f < c), lo, 0.0).max(-1), 0.0, 1.0)
    return out

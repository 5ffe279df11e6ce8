"""The object's interior before a blown-out plate keeps the photo's colour (issue 30).

Before a blown-out window, C = a F + (1 - a) B does not give F, and capture.matting_known.foreground_colour fills
every pixel there, opaque or not, with the nearest sure colours (an "opaque" alpha there is the depth's guess: a
pixel that lets some of the window through carries its light, which the plate, clipped at 1, cannot take out).
But a pixel whose every neighbour within the camera's spread is opaque too has no window in it: the photo is its
colour.  A camera's pixel gathers light from about 2 px around its centre (the lens, demosaicing; a path tracer's
Gaussian film filter of standard deviation 0.5 px reaches 2 px): on a conifer path-traced before the ``interior``
map's window, the near-opaque pixels (true alpha 0.85-0.99) within 2 px of the blown window took a background 4.0
linear behind them (median), against the plate's 0.25-0.75 (docs/matting.md "The interior before a blown window").

:func:`interior` names the pixels kept: the plate blown out there, the photo not clipped,
and alpha at least OPAQUE_ALPHA over the (2 INTERIOR_PX + 1)^2 square around.  On the furry bunny before the same
window (hardcases24), 199,112 of its kept views' pixels; their photo's colour errs by 0.00078 (mean squared,
linear, against the black twin's colour) where the fill erred by 0.00325; on the conifer before the window no
pixel is kept (its alpha is nowhere opaque over 5 x 5), where the photo of its "opaque" pixels errs by 0.075.

Two more steps keep the window's light out of the colour.  :func:`opaque_sources`: where a view has too few sure
pixels and the fill takes the opaque ones as its sources (a fur ball wholly before the window), those before a
blown-out plate count only in the interior, not the lit edge.  :func:`unseen_fill`: an opaque pixel whose background
no frame saw (a ball turning in place hides the room behind its fur's outer band, where alpha is the depth's
coverage) beside a blown-out plate, whose photo is over UNSEEN_RATIO times the fill's brightness, takes the fill.
Held out, fur balls turning before the window gained 1.0 dB from the two (docs/matting.md).
"""

from __future__ import annotations

import numpy as np

from capture.matting_fast import channel_max, erode

#: Keep the photo's colour in the object's interior before a blown-out plate (:func:`interior`); False: the fill,
#: as before stop 80.
INTERIOR_PHOTO = True
#: Where the fill's sources are the opaque pixels (too few sure ones), those before a blown-out plate count only in the
#: interior (:func:`opaque_sources`); False: every opaque pixel whose photo is not clipped, as before.
INTERIOR_SOURCES = True
#: An opaque pixel whose background no frame saw, before a known plate that is blown out around it, and whose photo is
#: more than UNSEEN_RATIO times as bright as the fill there, takes the fill (:func:`unseen_fill`); False: its photo.
UNSEEN_BLOWN = True
UNSEEN_RATIO = 1.5
#: The camera's spread (px at the photo's resolution): an interior pixel's neighbours up to this far are opaque.
INTERIOR_PX = 2


def blown_plate(background: np.ndarray, known: np.ndarray, clip_level: float) -> np.ndarray | None:
    """(h, w) bool: the ``known`` pixels of the plate ``background`` (h, w, 3) blown out (a channel at
    ``clip_level``); None where there is none (one reduction decides it where nothing reaches the level)."""
    if not np.size(background) or float(np.max(background)) < clip_level:
        return None
    blown = np.asarray(known, bool) & (channel_max(np.asarray(background)) >= clip_level)
    return blown if blown.any() else None


def interior(image: np.ndarray, alpha: np.ndarray, background: np.ndarray, known: np.ndarray, opaque_alpha: float,
             clip_level: float, record: dict | None = None) -> np.ndarray:
    """(h, w) bool: the pixels whose plate ``background`` (h, w, 3) is ``known`` and blown out (a channel at
    ``clip_level``), whose photo ``image`` (h, w, 3) is not clipped (every channel below it) and whose ``alpha``
    (h, w) is at least ``opaque_alpha`` over the square of side 2 INTERIOR_PX + 1 around them (the frame's edge
    counts as not opaque).  All False with INTERIOR_PHOTO off or no plate pixel blown out (one reduction: the test
    costs a view nothing before a background that is nowhere blown out).  ``record`` (a dict) gets ``interior``,
    how many, where there are any."""
    a = np.asarray(alpha)
    blown = blown_plate(background, known, clip_level) if INTERIOR_PHOTO else None
    if blown is None:
        return np.zeros(a.shape, bool)
    solid = erode(a >= opaque_alpha, iterations=INTERIOR_PX, square=True)
    out = blown & solid & (channel_max(np.asarray(image)) < clip_level)
    if record is not None and (n := int(np.count_nonzero(out))):
        record["interior"] = n
    return out


def opaque_sources(blown: np.ndarray, inner: np.ndarray) -> np.ndarray:
    """(h, w) bool: where an opaque pixel may be a source of the fill (capture.matting_known.OPAQUE_SOURCES): not
    before a blown-out plate (``blown``), or in the interior (``inner``, :func:`interior`); everywhere with
    INTERIOR_SOURCES off."""
    blown = np.asarray(blown, bool)
    return ~blown | np.asarray(inner, bool) if INTERIOR_SOURCES else np.ones(blown.shape, bool)


def unseen_fill(F: np.ndarray, image: np.ndarray, alpha: np.ndarray, background: np.ndarray, known: np.ndarray,
                blown: np.ndarray | None, record: dict | None = None) -> np.ndarray:
    """``F`` (h, w, 3, the matte's straight colour) with the opaque pixels (alpha >= OPAQUE_ALPHA) whose background
    no frame saw (not ``known``) but whose nearest known plate is blown out (the push-pull of the known ``background``,
    blown pixels included, reaching CLIP_LEVEL) given the fill of the colours of the sure pixels around them (alpha
    >= FILL_ALPHA, not before a blown or such an unseen background, the photo not clipped), where their photo
    ``image`` is more than UNSEEN_RATIO times the fill's brightness (largest channel).  On a fur ball turning
    before a window, the depth calls the fur's outer band opaque where no frame saw behind it, and its photo holds
    the window's light (docs/matting.md "The interior before a blown window").  ``record`` gets ``unseen_blown``.
    ``blown``: the pixels before a blown-out plate or clipped in the photo (None: found here).  ``F`` itself with
    UNSEEN_BLOWN off, no known pixel blown out, or fewer than MIN_SOURCES sources."""
    from capture.fill import push_pull
    from capture.matting_known import CLIP_LEVEL, FILL_ALPHA, MIN_SOURCES, OPAQUE_ALPHA, clipped

    known = np.asarray(known, bool)
    if not UNSEEN_BLOWN or blown_plate(background, known, CLIP_LEVEL) is None:
        return F
    a = np.asarray(alpha)
    behind = channel_max(push_pull(np.asarray(background, np.float64), known.astype(np.float64))) >= CLIP_LEVEL
    unseen = ~known & behind
    hot = unseen & (a >= OPAQUE_ALPHA)
    if not hot.any():
        return F
    C = np.asarray(image)
    blown = known & clipped(C, background) & (a > 0) if blown is None else np.asarray(blown, bool)
    src = (a >= FILL_ALPHA) & ~unseen & ~blown & (channel_max(C) < CLIP_LEVEL)
    if np.count_nonzero(src) < MIN_SOURCES:
        return F
    fill = push_pull(np.asarray(F, np.float64), src.astype(np.float64))
    hot &= channel_max(C) > UNSEEN_RATIO * channel_max(fill)
    if record is not None and (n := int(np.count_nonzero(hot))):
        record["unseen_blown"] = n
    return np.where(hot[..., None], fill, F)

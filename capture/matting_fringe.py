"""The colour of a partial pixel that nothing measures, from the view's measured fringe (issue 30).

Before a blown-out window, or a bright background no frame saw, C = a F + (1 - a) B does not give F, and step 4
of capture.matting_known fills the colour from the nearest *sure* colours: pixels whose F = B + (C - B) / a is
exact with alpha >= FILL_ALPHA, the object's body.  A partial pixel is not the body: it is a strand's tip or a
needle, seen without the body's self-shadow and, with a window behind it, lit from behind. A furry bunny
path-traced before the ``interior`` map's window (docs/matting.md "A bunny before a blown window") glows along its
whole outline in the black twin (mean straight colour 0.35 / 0.29 / 0.17 linear where the window is blown), and
took the body's 0.10 / 0.06 / 0.05.

:func:`fill_colour` keeps the body's fill for pixels at alpha >= FILL_ALPHA and gives the partial pixels before a
blown-out plate (or clipped in the photo: capture.matting_known.clipped) the push-pull fill of the view's own
measured fringe instead: the pixels whose colour is exact (B known and not clipped, ``ok``), partial (alpha in
[FRINGE_LOW, FILL_ALPHA)) and told from B (|F - B| >= FRINGE_SEPARATION: where the object's colour is close to B the
alpha, and so the unmixed colour, is the least sure). A view with fewer than ``min_sources`` such pixels keeps the
body's fill everywhere. It takes no model of the light: the fringe's colour is what the same view measured on its
fringe where something darker was behind it. Held out, the bunny gains 0.39 dB (18.48 -> 18.87, SSIM 0.249 -> 0.257)
and ten other room captures score the same; before a bright background no frame saw (the plate unknown, not blown)
the same fill cost fur before a background of its own colour 0.29 dB, so it is not used there (docs/matting.md "The
fringe's colour before a blown window").
"""

from __future__ import annotations

import numpy as np

from capture.fill import push_pull

#: Partial pixels filled take the view's measured fringe colour (:func:`fill_colour`); False: the body's, as before
#: stop 79.
FRINGE_FILL = True
#: The fringe's colour sources have alpha at least this (a fainter pixel's F carries its noise times 1 / alpha).
FRINGE_LOW = 0.2
#: ... and F at least this far from B (linear, Euclidean): capture.matting_known.SEPARATION, where the data term
#: gives half weight.
FRINGE_SEPARATION = 0.1


def fringe_sources(F: np.ndarray, B: np.ndarray, a: np.ndarray, ok: np.ndarray, fill_alpha: float) -> np.ndarray:
    """(h, w) bool: the pixels whose exact colour ``F`` (``ok``: B known and not clipped) is a fringe's colour:
    alpha in [FRINGE_LOW, ``fill_alpha``) and |F - B| >= FRINGE_SEPARATION."""
    far = np.sqrt(((np.asarray(F, np.float64) - B) ** 2).sum(-1)) >= FRINGE_SEPARATION
    return np.asarray(ok, bool) & (a >= FRINGE_LOW) & (a < fill_alpha) & far


def fill_colour(F: np.ndarray, B: np.ndarray, a: np.ndarray, ok: np.ndarray, sure: np.ndarray, blown: np.ndarray,
                fill_alpha: float, min_sources: int, record: dict | None = None) -> np.ndarray:
    """(h, w, 3) float64 colour for the pixels filled (elsewhere undefined): the push-pull fill of the ``sure``
    colours (the body's) and, with FRINGE_FILL, at the ``blown`` pixels (the plate or the photo clipped; every one of
    them is filled) with alpha < ``fill_alpha`` that of the :func:`fringe_sources` when there are at least
    ``min_sources`` of them.  ``F``: (h, w, 3) exact colour where ``ok``; ``B``: the plate; ``a``: alpha.
    ``record`` (a dict) gets ``fringe``: the pixels that took the fringe's colour."""
    body = push_pull(F, np.asarray(sure, np.float64))
    if not FRINGE_FILL:
        return body
    tgt = np.asarray(blown, bool) & (a < fill_alpha)
    src = fringe_sources(F, B, a, ok, fill_alpha)
    if not tgt.any() or src.sum() < min_sources:
        return body
    if record is not None:
        record["fringe"] = int(tgt.sum())
    return np.where(tgt[..., None], push_pull(F, src.astype(np.float64)), body)

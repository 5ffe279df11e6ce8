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
enough to cross even where those behind one cube do not).  Only lines whose photo's alpha is at least
GLOBAL_LINE_ALPHA enter: the faint ones pull the crossing towards the room's colour (red on the
conifer's courtyard; measured on the turntable, docs/matting.md eighth round).

It knows when it cannot beat doing nothing: the colour is used only

* where the pixel's colour was filled (not unmixed: :func:`filled`), in a cube whose lines do not
  cross, in a view whose alpha error was measured (as the cubes' colour: a view without one keeps
  its colour);
* when the object's lines cross (at least MIN_LINES, well conditioned, the colour beyond the photo);
* when, over the filled pixels whose cube's lines do cross, the global colour lies nearer the cubes'
  colours than the fill does (mean squared distance; the cube colour's own error adds to both).

Otherwise none, and the record (``cells['global']``) says why.
"""

from __future__ import annotations

import numpy as np

from capture.matting_lines import MIN_LINES, group_fit

#: Give the pixels no cube colours the object's colour (held out, gather, docs/matting.md eighth round).
GLOBAL = True
#: Least photo's alpha (capture.matting_lines.line_alpha) of the lines crossed for the object's colour.
#: Turntable, held out (the kept views' dumped samples, numpy twin of gather): 0.1 25.06 dB, 0.3 25.16,
#: 0.5 25.24 (the cubes alone 25.01); orbit 26.61 whatever the bound (1 % of its pixels uncrossed).
GLOBAL_LINE_ALPHA = 0.5
#: A colour counts as unmixed where it is within this (linear, per channel) of B + (C - B) / a.
FILLED_TOL = 1e-3


def filled(C: np.ndarray, B: np.ndarray, alpha: np.ndarray, colour: np.ndarray) -> np.ndarray:
    """(N,) bool: the matte's ``colour`` (N, 3) is not the unmixed one, clip(B + (C - B) / a) (C, B
    clipped to [0, 1] as capture.matting_known.foreground_colour takes them), in one exposure."""
    C, B = (np.clip(np.asarray(x, np.float64), 0.0, 1.0) for x in (C, B))
    a = np.maximum(np.asarray(alpha, np.float64), 1e-6)[:, None]
    Fu = np.clip(B + (C - B) / a, 0.0, 1.0)
    return ~np.all(np.abs(Fu - np.asarray(colour, np.float64)) <= FILLED_TOL, axis=-1)


def object_colour(C, B, w, a_line, alpha, colour, cell_colour, crossed, fill) -> tuple[np.ndarray | None, dict]:
    """The object's colour for the pixels no cube colours (module docstring) from N samples in the
    common exposure: ``C``, ``B`` (N, 3), line weights ``w`` and photo's alphas ``a_line`` (N,,
    capture.matting_lines.line_weights / line_alpha), the matte's ``alpha`` (N,) and ``colour`` (N, 3),
    each sample's cube colour ``cell_colour`` (N, 3) and whether its cube's lines cross ``crossed``,
    ``fill`` (:func:`filled`).  ((3,) or None, the record)."""
    rec: dict = {"line_alpha": GLOBAL_LINE_ALPHA}
    if not GLOBAL:
        return None, {**rec, "reason": "off"}
    wl = np.where(np.asarray(a_line) >= GLOBAL_LINE_ALPHA, w, 0.0)
    rec["lines"] = int((wl > 0).sum())
    F, sig2 = group_fit(C, B, wl, alpha, lambda x: x.sum(0, keepdims=True), np.zeros(len(wl), np.int64))
    if not np.isfinite(sig2[0]):
        return None, {**rec, "reason": "the object's lines do not cross (too few, parallel, or at the background)"}
    ref = np.asarray(crossed, bool) & np.asarray(fill, bool)
    if int(ref.sum()) < MIN_LINES:
        return None, {**rec, "reason": "too few filled pixels in a crossed cube to check it against"}
    e_fill = float(((np.asarray(colour, np.float64)[ref] - cell_colour[ref]) ** 2).sum(-1).mean())
    e_obj = float(((F[0] - cell_colour[ref]) ** 2).sum(-1).mean())
    rec.update(colour=[round(float(x), 5) for x in F[0]], sigma=round(float(np.sqrt(sig2[0])), 5),
               check=int(ref.sum()), fill_to_cubes=round(e_fill, 7), object_to_cubes=round(e_obj, 7))
    if e_obj >= e_fill:
        return None, {**rec, "reason": "not nearer the cubes' colours than the fill"}
    return F[0], rec


def with_object_colour(use: np.ndarray, crossed: np.ndarray, fill: np.ndarray, F: np.ndarray, F_obj,
                       allowed: bool = True) -> tuple[np.ndarray, np.ndarray, int]:
    """One view's samples: (the pixels given a colour, their colours (N, 3) where given: the cube's
    where ``use``, the object's ``F_obj`` where the cube's lines do not cross and the colour was
    filled, when ``allowed`` and F_obj is not None), how many took the object's."""
    extra = np.zeros(len(use), bool) if F_obj is None or not allowed else ~np.asarray(crossed, bool) & fill
    return use | extra, np.where(extra[:, None], np.asarray(F_obj, np.float64), F), int(extra.sum())

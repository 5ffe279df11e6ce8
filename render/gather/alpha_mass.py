"""Gather's alpha held to the mass of the mattes it is gathered from (issue 30, stop 83).

The gather method (render/gather/reference.py) splats its kept views' points 2 x 2, lets an occluded camera add a
little of what it saw (its visibility floor) and composites a second layer under the front: each keeps the frame's
thin strands whole, and each adds alpha.  On path-traced conifers (docs/novel_views.md "Gather's alpha mass") a
held-out frame's alpha summed to 1.05-1.07 times what its cameras' mattes hold, the excess spread over the partial
pixels (rendered 0.30 where the truth was 0.19 and the kept mattes 0.24), and the premultiplied colour with it; on a
fur ball, whose partial pixels are a fringe around a solid body, 1.00.

The excess is measured per model (:func:`excess`), leave-one-out: kept views (LOO_VIEWS of them, spread over the
capture) are drawn from the other views as a new eye would be, and the drawn alpha mass is compared with the view's
own matte's; ``f`` is the median ratio.  A frame's alpha a is then pulled to a - d a (1 - a) (:func:`normalise`), d
chosen so that its mass is its drawn mass / f: 0 and 1 stay, the mid alphas move most; and its premultiplied colour
with it, pixel by pixel (:func:`pull`: the straight colour is kept).  Only where f exceeds 1 + MIN_EXCESS, and d at
most MAX_PULL.  The GL renderer measures f with its own frames and reads each frame back through the same numpy step
as the twin (reference.gather_frame's ``excess``; :func:`loo_excess_reference` measures f with the twin's frames).

By default (GatherConfig.alpha_mass "auto") only a model whose every kept view was matted against a backdrop is
pulled (:func:`backdrop_matted`): there the kept views' premultiplied colour is exact, and on six fresh black captures
the pull gained over black (conifers +0.30 dB, bunnies +0.08, SSIM up, fur untouched).  A room matte carries its own
colour error (the room in the needles), which the pull moved with the coverage: "on" cost a conifer before a sunset
0.008 SSIM (docs/novel_views.md "Gather's alpha mass").

(Tried first and not kept: the frame's mass set to its two blend cameras' matte masses, brought to the eye's scale;
on a furry bunny circling before a room it cost 0.54 dB over white: a body's silhouette changes between views, and
the neighbours' mean is not the eye's mass.  Then the partial pixels scaled by one factor to the measured excess: the
bunny's body pixels, alpha 0.99, let 3 % of the white through, -0.9 dB.  The alpha alone pulled, the colour left:
over white the same as with it, over black nothing gained.)
"""

from __future__ import annotations

import numpy as np

#: Largest pull d of a - d a (1 - a) (:func:`normalise`; under 1 the map is monotone and keeps alpha in [0, 1]): the
#: conifers took 0.2-0.3; a frame that would need more is left as drawn.
MAX_PULL = 0.9
#: Kept views drawn leave-one-out to measure the excess (evenly spread over the capture's order).
LOO_VIEWS = 12
#: Fewest kept views with a matte and a drawn frame for a measured excess (fewer: f = 1, the frames as drawn).
MIN_LOO = 3
#: Excess under which the frames are left as drawn: fur and a furry bunny measured 1.001 and 1.005 (their fringes'
#: mass is kept), the conifers 1.050-1.063.
MIN_EXCESS = 0.01


def matte_mass(alpha) -> float:
    """The mass of a matte (its alpha summed in float64); 0 for None."""
    return 0.0 if alpha is None else float(np.sum(alpha, dtype=np.float64))


def backdrop_matted(params: dict | None) -> bool:
    """Whether a model's every kept view was matted against a backdrop (its parameters' surroundings.matte.methods,
    capture.matting: the premultiplied colour C - (1 - a) B is exact there); False where the record is missing."""
    methods = (((params or {}).get("surroundings") or {}).get("matte") or {}).get("methods") or {}
    return bool(methods) and set(methods) == {"backdrop"}


def loo_views(n: int, at_most: int = LOO_VIEWS) -> list[int]:
    """Up to ``at_most`` of ``n`` kept views, evenly spread (all of them when there are no more)."""
    if n <= at_most:
        return list(range(n))
    return sorted({int(round(x)) for x in np.linspace(0, n - 1, at_most)})


def excess(drawn: list[float], own: list[float]) -> float:
    """f: the median of drawn / own alpha mass over the views measured (``drawn``: each view's frame drawn from the
    others; ``own``: its matte's sum); 1 with fewer than MIN_LOO views where both are positive."""
    r = [d / o for d, o in zip(drawn, own, strict=True) if o > 0 and d > 0]
    return float(np.median(r)) if len(r) >= MIN_LOO else 1.0


def normalise(alpha: np.ndarray, f: float) -> tuple[np.ndarray, float]:
    """(alpha, d): ``alpha`` (H, W) pulled to a - d a (1 - a), d chosen so that the frame's alpha sums to its drawn
    sum / ``f``: 0 and 1 stay, the mid alphas (where gather's excess lies on a conifer) move most, a body's nearly
    opaque pixels hardly at all; d = 0 (``alpha`` itself) where f is at most 1 + MIN_EXCESS, the frame has no
    partial pixels, or d would exceed MAX_PULL."""
    a = np.asarray(alpha)
    if not f > 1.0 + MIN_EXCESS:
        return a, 0.0
    q = a * (1.0 - a)
    qs = float(q.sum(dtype=np.float64))
    if qs <= 0:
        return a, 0.0
    d = float(a.sum(dtype=np.float64)) * (1.0 - 1.0 / f) / qs
    if d > MAX_PULL:
        return a, 0.0
    return (a - np.float32(d) * q).astype(a.dtype, copy=False), d


def pull(rgb: np.ndarray, alpha: np.ndarray, f: float) -> tuple[np.ndarray, np.ndarray, float]:
    """(rgb, alpha, d): the frame's coverage pulled by :func:`normalise` (``alpha`` (H, W)) and its premultiplied
    colour ``rgb`` (H, W, 3) scaled with it pixel by pixel, a' / a: the straight colour rgb / alpha is kept (the
    excess is coverage, in the colour as in the alpha)."""
    a2, d = normalise(alpha, f)
    if d == 0.0:
        return rgb, alpha, d
    a = np.asarray(alpha)
    ratio = np.where(a > 0, a2 / np.where(a > 0, a, 1), 1).astype(np.float32)
    return (np.asarray(rgb) * ratio[..., None]).astype(np.asarray(rgb).dtype, copy=False), a2, d


def loo_excess_reference(clouds, cameras, rgb, depth, centre, cfg, alpha, measured=None) -> float:
    """:func:`excess` measured with the numpy twin's frames (render.gather.reference.gather_frame, the rule off):
    each of :func:`loo_views`'s views drawn from the others (their ``clouds`` and images), against its own matte."""
    from dataclasses import replace

    from render.gather.reference import gather_frame
    from render.points.reference import back_project

    if clouds is None and measured is None:
        clouds = back_project(cameras, rgb, depth)
    off = replace(cfg, alpha_mass="off")
    drawn, own = [], []
    for k in loo_views(len(cameras)):
        rest = [i for i in range(len(cameras)) if i != k]
        sub = (None if clouds is None else [clouds[i] for i in rest], [cameras[i] for i in rest], rgb[rest],
               depth[rest], centre, off, alpha[rest], None if measured is None else measured[rest])
        drawn.append(matte_mass(gather_frame(cameras[k], *sub)[1]))
        own.append(matte_mass(alpha[k]))
    return excess(drawn, own)

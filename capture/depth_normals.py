"""Normals of a z-depth map: the back-projected points of neighbouring pixels give two tangents
(along rows and along columns); their cross product, normalised and turned towards the eye, is
the normal. Where a neighbour is missing (no depth, a depth edge) the rules below differ; each
is used by the stage named.

* ``"central"``: p[i+1] - p[i-1], only where both neighbours have depth (compositing's normals
  for the light-reflection map, ``render.composite.pipeline``);
* ``"smaller_step"``: the one-sided difference on the side with the smaller depth (z) step, so a
  1-2 pixel wide strand keeps a normal (signed-distance fusion, ``volume.fusion``);
* ``"average"``: the mean of the two one-sided differences where both are usable, else the usable
  one; optionally a one-sided step with |dz| above ``max_step`` is not usable (a depth edge is no
  tangent) (projective registration, ``capture.registration.projective``).
"""

from __future__ import annotations

import numpy as np

DIFFERENCE_RULES = ("central", "smaller_step", "average")


def _along(axis: int, lo: int | None, hi: int | None) -> tuple:
    sl = [slice(None), slice(None)]
    sl[axis] = slice(lo, hi)
    return tuple(sl)


def neighbour_differences(points: np.ndarray, valid: np.ndarray, axis: int, rule: str,
                          max_step=None) -> tuple[np.ndarray, np.ndarray]:
    """Tangent (H, W, 3) along image ``axis`` (1: columns, 0: rows) of the (H, W, 3) points
    under ``rule`` (module doc) and the (H, W) bool mask of the pixels that have one.
    ``max_step``: scalar or (H, W) largest |dz| of a usable one-sided step ("average" only)."""
    if rule not in DIFFERENCE_RULES:
        raise ValueError(f"neighbour_differences: unknown rule {rule!r} (have {DIFFERENCE_RULES})")
    p = np.asarray(points)
    valid = np.asarray(valid, bool)
    if rule == "central":
        d = np.zeros_like(p)
        ok = np.zeros_like(valid)
        d[_along(axis, 1, -1)] = p[_along(axis, 2, None)] - p[_along(axis, None, -2)]
        ok[_along(axis, 1, -1)] = valid[_along(axis, 2, None)] & valid[_along(axis, None, -2)]
        return d, ok
    step = p[_along(axis, 1, None)] - p[_along(axis, None, -1)]
    both = valid[_along(axis, 1, None)] & valid[_along(axis, None, -1)]
    fwd, bwd = np.zeros_like(p), np.zeros_like(p)
    okf, okb = np.zeros_like(valid), np.zeros_like(valid)
    fwd[_along(axis, None, -1)] = step
    okf[_along(axis, None, -1)] = both
    bwd[_along(axis, 1, None)] = step
    okb[_along(axis, 1, None)] = both
    if rule == "smaller_step":
        use_f = okf & (~okb | (np.abs(fwd[..., 2]) <= np.abs(bwd[..., 2])))
        return np.where(use_f[..., None], fwd, bwd), okf | okb
    if max_step is not None:
        okf &= np.abs(fwd[..., 2]) <= max_step
        okb &= np.abs(bwd[..., 2]) <= max_step
    out = np.where((okf & okb)[..., None], 0.5 * (fwd + bwd), np.where(okf[..., None], fwd, bwd))
    return out, okf | okb


def depth_normals(points: np.ndarray, valid: np.ndarray, rule: str, eye=(0.0, 0.0, 0.0),
                  max_step=None) -> tuple[np.ndarray, np.ndarray]:
    """(normals (H, W, 3) unit, facing ``eye``; 0 where not ok, ok (H, W) bool) of the (H, W, 3)
    back-projected points of a depth map (any frame; ``eye`` = the camera centre in that frame)
    with ``valid`` (H, W) the pixels that have depth; ``rule`` / ``max_step``: module doc."""
    p = np.asarray(points)
    du, oku = neighbour_differences(p, valid, 1, rule, max_step)
    dv, okv = neighbour_differences(p, valid, 0, rule, max_step)
    n = np.cross(du, dv)
    norm = np.linalg.norm(n, axis=-1)
    ok = np.asarray(valid, bool) & oku & okv & (norm > 0)
    n = np.where(ok[..., None], n / np.where(norm > 0, norm, 1.0)[..., None], 0.0)
    away = np.sum(n * (np.asarray(eye, np.float64) - p), axis=-1) < 0
    return np.where(away[..., None], -n, n), ok

"""Harder fur balls: curly strands and melanin patches (issue 22), as on the path-traced
evaluation fur ball the turntable registration failed on, and one uniform coat on a sphere
(issue 31), the same from every side at coarse scale.

* **Curl** is the fur ball's own helix (``FurballParams.curl`` / ``curl_turns``), made tighter
  and stronger by :data:`CURLY`: strands that wind about themselves do not repeat from one view
  to the next (their depth and colour at a pixel change with the viewpoint).
* **Uniform coat** (:data:`UNIFORM`, :func:`uniform_coat`): one brown coat with a small
  per-strand jitter on a spherical body; only the lighting and the strands' fine texture tell one
  turntable angle from another (near-rotational symmetry about the vertical).
* **Melanin patches** (:func:`melanin_patches`): blotches of dark (eumelanin-rich) and light
  (melanin-poor) coat over the base colour, like a calico or a piebald coat.  Light strands
  scatter more (TT / TRT), so the patches carry the highlights too; their edges are soft.
"""

from __future__ import annotations

import numpy as np

#: Overrides of ``FurballParams`` for the curly fur ball (``furrow synth furball --curly``).
CURLY = {"curl": 0.9, "curl_turns": 2.5, "length": 0.034, "comb": 0.9, "gravity": 0.5, "patches": 14}
#: Overrides of ``FurballParams`` for the uniform fur ball (``furrow synth furball --coat uniform``):
#: one coat on a sphere of the default body's mean radius.
UNIFORM = {"coat": "uniform", "body_axes": (0.063, 0.063, 0.063)}
#: Linear albedo of the uniform brown coat ...
UNIFORM_COAT = (0.30, 0.17, 0.085)
#: ... and the range of its per-strand brightness jitter (uniform).
UNIFORM_JITTER = (0.85, 1.15)
#: Linear albedo of the dark (eumelanin) and light (melanin-poor) patches.
DARK_PATCH = (0.035, 0.022, 0.015)
LIGHT_PATCH = (0.80, 0.74, 0.62)
#: Patch radius on the unit sphere of the body (radians), uniform in this range.
PATCH_RADIUS = (0.25, 0.6)
#: Soft edge of a patch (fraction of its radius).
PATCH_EDGE = 0.3
#: Seed offset of the patch layout (the strands keep the scene seed's layout).
PATCH_SEED_OFFSET = 7919


def melanin_patches(seed: int, roots: np.ndarray, axes: np.ndarray, base: np.ndarray, n: int) -> np.ndarray:
    """(S, 3) linear albedo: ``base`` (S, 3) with ``n`` dark / light patches blended in by the
    direction of each root (S, 3) on the body of semi-axes ``axes``."""
    if n <= 0:
        return base
    rng = np.random.default_rng(seed + PATCH_SEED_OFFSET)
    q = roots / axes
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    centres = rng.normal(size=(n, 3))
    centres /= np.linalg.norm(centres, axis=1, keepdims=True)
    radius = rng.uniform(*PATCH_RADIUS, size=n)
    dark = rng.uniform(size=n) < 0.5
    out = np.array(base, np.float64)
    for c, r, d in zip(centres, radius, dark):
        ang = np.arccos(np.clip(q @ c, -1, 1))
        w = np.clip((r - ang) / (PATCH_EDGE * r), 0.0, 1.0)[:, None]
        col = np.asarray(DARK_PATCH if d else LIGHT_PATCH)
        jitter = rng.uniform(0.85, 1.15)
        out = out * (1 - w) + col * jitter * w
    return out


def uniform_coat(seed: int, n: int) -> np.ndarray:
    """(n, 3) linear albedo: ``UNIFORM_COAT`` with a seeded per-strand brightness jitter."""
    rng = np.random.default_rng(seed + PATCH_SEED_OFFSET)
    return np.asarray(UNIFORM_COAT) * rng.uniform(*UNIFORM_JITTER, size=(n, 1))

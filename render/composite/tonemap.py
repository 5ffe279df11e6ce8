"""Tone mapping: scene-linear HDR radiance -> display-referred linear RGB in [0, 1]
(the last step of ``render.composite.pipeline.composite_frame``)."""

from __future__ import annotations

import numpy as np

#: Tone-mapping operators: "clamp" (display = min(x, 1)), "reinhard" (extended Reinhard with white
#: point TONE_WHITE: x (1 + x / w^2) / (1 + x), exactly 1 at x = w and clipped above).
TONE_MAPS = ("clamp", "reinhard")
TONE_WHITE = 4.0


def tonemap(linear, exposure: float = 1.0, method: str = "reinhard", white: float = TONE_WHITE) -> np.ndarray:
    """Display-referred linear RGB in [0, 1] from scene-linear RGB: f(exposure * x) per channel,
    f monotone non-decreasing, f(0) = 0, f(x) = 1 for x >= display_white(method, white)."""
    if method not in TONE_MAPS:
        raise ValueError(f"tonemap: unknown method {method!r} (have {TONE_MAPS})")
    if not exposure > 0:
        raise ValueError(f"tonemap: exposure must be > 0, got {exposure}")
    x = np.maximum(np.asarray(linear, np.float64) * exposure, 0.0)
    if method == "clamp":
        return np.minimum(x, 1.0)
    if not white > 0:
        raise ValueError(f"tonemap: white must be > 0, got {white}")
    return np.minimum(x * (1 + x / white**2) / (1 + x), 1.0)


def display_white(method: str = "reinhard", white: float = TONE_WHITE) -> float:
    """The scene-linear value (after exposure) the tone map shows as full white."""
    return 1.0 if method == "clamp" else float(white)

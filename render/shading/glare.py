"""Glare streaks for highlights brighter than the display (docs/methods.md §4, seed 002 Eq. 6-12).

Each bright pixel spawns ``n_dirs`` pairs of opposite streaks. A pair is a thin rhombus with
half-length L_s along the streak direction and width W_s across (area L_s W_s: two streaks of
S = L_s W_s / 2 each, Eq. 6), a fan of 4 triangles with the centre colour c and a black rim,
interpolated. The light of a pair is the integral of that tent, c * L_s W_s / 3; c is chosen so
that the pairs of a pixel carry exactly the pixel's excess energy (its radiance above the display
maximum times the pixel area): the frame's total light is unchanged (energy-preserving glare).

This module is the shape and energy (numpy). Drawing (instanced additive fans in moderngl, with
supersampling for sub-pixel widths), the light-source / light-reflection / specular-parameter
maps and the compositing live in render/composite/glare_layer.py, render/shading/glare_maps.py and
render/composite/pipeline.py (the compositing helper's), which call these functions.

Shape (Eq. 7-12), with I = k_s I_l the highlight intensity and n the Blinn exponent:
    L_s = k_length * I (n + 2) / (8 pi)   (Eq. 7, proportional to the normalised peak, Eq. 4)
    S   = k_size * I                      (Eq. 8, independent of n)
    L_s = sqrt(S) below n_g = 8 pi sqrt(S) / (k_length I) - 2   (Eq. 9-10, 12)
    W_s = 2 S / L_s                        (Eq. 11)
Streak directions: random in [0, 180) degrees per frame seed, rotated with the highlight's
screen x, length multiplied by an eyelash table peaking 20 degrees from horizontal (our smooth
stand-in for Nakamae's table, which the paper does not print).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from capture.camera import corner_from_cv
from render.shading.lights import LUMA


@dataclass(frozen=True)
class GlareConfig:
    """Global glare settings (seed 002 §3.4-3.5)."""

    k_length: float = 0.5
    """Eq. 7: streak half-length (px) per unit of normalised peak intensity (scale with window size)."""
    k_size: float = 2.0
    """Eq. 8: streak area (px^2) per unit intensity (scale with window area)."""
    n_dirs: int = 6
    """Streak pairs per highlight pixel."""
    seed: int = 0
    """Seed of the random base directions."""
    rotate_per_px: float = 0.05
    """Degrees of rotation of the streak directions per pixel of screen x."""
    display_max: float = 1.0
    """Radiance the display shows as white; the excess above it becomes glare."""
    max_length: float = 400.0
    """Cap of L_s in pixels (keeps a sun from covering the frame)."""


def streak_shape(intensity, n, k_length: float, k_size: float):
    """(L_s, W_s) in pixels for highlight intensity I = k_s I_l and Blinn exponent n (Eq. 7-12)."""
    i = np.asarray(intensity, np.float64)
    n = np.asarray(n, np.float64)
    length = k_length * i * (n + 2) / (8 * np.pi)
    area = k_size * i
    length = np.maximum(length, np.sqrt(area))  # Eq. 9-10: never shorter than a square pair
    with np.errstate(invalid="ignore", divide="ignore"):
        width = np.where(length > 0, 2 * area / np.where(length > 0, length, 1.0), 0.0)
    return length, width


def n_g(intensity, k_length: float, k_size: float):
    """Eq. 12: the exponent below which L_s = sqrt(S)."""
    i = np.asarray(intensity, np.float64)
    return 8 * np.pi * np.sqrt(k_size * i) / (k_length * i) - 2


def eyelash_factor(angle_deg) -> np.ndarray:
    """Length multiplier of a streak at ``angle_deg`` (0 = horizontal), peaking (1.0) at 20 and
    160 degrees (20 degrees from horizontal), 0.4 far from them."""
    a = np.mod(np.asarray(angle_deg, np.float64), 180.0)
    g = np.maximum(np.exp(-((a - 20) / 15) ** 2), np.exp(-((a - 160) / 15) ** 2))
    return 0.4 + 0.6 * g


def streak_directions(x_px, cfg: GlareConfig) -> np.ndarray:
    """(N, n_dirs) streak angles in degrees for highlights at screen x ``x_px`` (N,)."""
    base = np.random.default_rng(cfg.seed).uniform(0, 180, cfg.n_dirs)
    return np.mod(base[None] + cfg.rotate_per_px * np.asarray(x_px, np.float64)[:, None], 180.0)


def streak_triangles(centres, energy, intensity, n_exp, cfg: GlareConfig):
    """Triangle list of the streak fans: (T*3, 2) float32 vertex positions in pixels and (T*3, 3)
    float32 colours. centres (N,2) pixel coordinates (x right, y down, pixel centres at +0.5),
    energy (N,3) the light to spread (radiance x px^2), intensity (N,) drives the shape,
    n_exp scalar or (N,) the Blinn exponent."""
    c = np.asarray(centres, np.float64).reshape(-1, 2)
    e = np.asarray(energy, np.float64).reshape(-1, 3)
    N = len(c)
    length, width = streak_shape(intensity, np.broadcast_to(n_exp, (N,)), cfg.k_length, cfg.k_size)
    ang = streak_directions(c[:, 0], cfg)  # (N, D)
    Ls = np.minimum(length[:, None] * eyelash_factor(ang), cfg.max_length)  # (N, D)
    Ws = width[:, None] * np.ones_like(Ls)
    rad = np.radians(ang)
    u = np.stack([np.cos(rad), -np.sin(rad)], -1)  # along (screen y down)
    v = np.stack([np.sin(rad), np.cos(rad)], -1)  # across
    tip1 = c[:, None] + Ls[..., None] * u
    tip2 = c[:, None] - Ls[..., None] * u
    side1 = c[:, None] + 0.5 * Ws[..., None] * v
    side2 = c[:, None] - 0.5 * Ws[..., None] * v
    # pair light = peak * area / 3, area = Ls * Ws; the D pairs share the pixel's energy
    peak = 3.0 * e[:, None, :] / (cfg.n_dirs * np.maximum(Ls * Ws, 1e-12))[..., None]  # (N, D, 3)
    cen = np.broadcast_to(c[:, None], tip1.shape)
    tris = [(cen, tip1, side1), (cen, side1, tip2), (cen, tip2, side2), (cen, side2, tip1)]
    pos = np.stack([np.stack(t, 2) for t in tris], 2)  # (N, D, 4, 3, 2)
    col = np.zeros(pos.shape[:-1] + (3,))
    col[..., 0, :] = peak[:, :, None, :]
    return pos.reshape(-1, 2).astype(np.float32), col.reshape(-1, 3).astype(np.float32)


def streak_energy(pos, col) -> np.ndarray:
    """(3,) analytic light of a triangle list with linearly interpolated colours:
    sum over triangles of area * mean vertex colour."""
    p = np.asarray(pos, np.float64).reshape(-1, 3, 2)
    c = np.asarray(col, np.float64).reshape(-1, 3, 3)
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    area = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    return (area[:, None] * c.mean(1)).sum(0)


def bright_pixel_indices(img, display_max: float):
    """Pixels whose luminance exceeds display_max: (ij (N, 2) int64 (column, row), excess energy
    (N, 3) = the colour above luminance display_max (hue kept), intensity (N,) = luminance /
    display_max)."""
    img = np.asarray(img, np.float64)
    lum = img @ LUMA
    ys, xs = np.nonzero(lum > display_max)
    val = img[ys, xs]
    clipped = val * (display_max / lum[ys, xs])[:, None]
    return np.stack([xs, ys], 1), val - clipped, lum[ys, xs] / display_max


def bright_pixels(img, display_max: float):
    """:func:`bright_pixel_indices` with the pixels as centres (N, 2) in corner-origin pixel
    coordinates (``capture.camera.corner_from_cv``), the convention of :func:`streak_triangles`."""
    ij, excess, intensity = bright_pixel_indices(img, display_max)
    return corner_from_cv(ij), excess, intensity

"""The palette of a view's sure foreground colours: seeded k-means (capture.matting_known, step 2;
the frames' lines, capture.plate_lines)."""

from __future__ import annotations

import numpy as np

#: Colours in the view's palette of sure foreground colours (k-means; step 2).
PALETTE_SIZE = 6
#: k-means: samples and iterations (seeded).
PALETTE_SAMPLES = 4000
PALETTE_ITERATIONS = 8
PALETTE_SEED = 0


def palette(colours: np.ndarray, k: int | None = None) -> np.ndarray:
    """(<= k, 3) k-means centres of (N, 3) ``colours`` (seeded, PALETTE_SAMPLES of them at most;
    k default PALETTE_SIZE)."""
    c = np.asarray(colours, np.float64).reshape(-1, 3)
    k = PALETTE_SIZE if k is None else k
    if len(c) == 0 or k == 0:
        return np.zeros((0, 3))
    rng = np.random.default_rng(PALETTE_SEED)
    if len(c) > PALETTE_SAMPLES:
        c = c[rng.choice(len(c), PALETTE_SAMPLES, replace=False)]
    k = min(k, len(c))
    centres = c[rng.choice(len(c), k, replace=False)]
    for _ in range(PALETTE_ITERATIONS):
        lab = np.argmin(((c[:, None] - centres[None]) ** 2).sum(-1), axis=1)
        for j in range(k):
            if np.any(lab == j):
                centres[j] = c[lab == j].mean(0)
    return centres

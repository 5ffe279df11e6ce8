"""The photometric alignment shown to help, or not applied (capture.photometric, step 5).

An estimator that can be wrong must know when it cannot beat doing nothing.  The alignment's
data are the cells' log ratios ``d = log c_j - log c_i`` of every compared pair (view i, view j);
a gain explains them when ``d ~ x_i - x_j``.  So the cells are split into ``check_folds`` folds by
blocks of :data:`CHECK_BLOCK`^3 cells (held-back cells lie apart from the ones the gains come
from, as a different part of the object would), and for each fold the gains are estimated from
the other folds (capture.photometric.log_gains: the same solve and appearance split) and judged on
the fold's cells -- per pair, the median of its held-back cells' ratios, so that the cells' own
appearance averages out and a wrong exposure does not -- three ways:

* ``none``: no alignment (the residual is ``d`` itself);
* ``ev``: one exposure per view (the mean over channels of the estimated log gain);
* ``full``: exposure and white balance (the estimate as it is).

The loss of a held-back ratio is its squared residual in robust standard deviations (of the
``full`` residuals), clipped at :data:`LOSS_CLIP` (sheen, an occlusion the depth missed); its
standard error comes from the spread of the pairs' summed loss differences.  The simplest choice
whose mean loss is within ``check_z`` standard errors of the best one is applied.  A capture whose
views differ by exposure is aligned (the gains predict cells they never saw); one whose views
differ in ways no gain explains (strands that do not correspond, sheen that moves) keeps its
colour, and the record says why.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from capture.photometric import MAD_TO_SIGMA, SIGMA_FLOOR, PhotometricConfig, log_gains
from capture.photometric_cells import CellGrid
from capture.photometric_pairs import PairCells

#: The three corrections, simplest first (module docstring).
CHOICES = ("none", "ev", "full")
#: What each choice does, for the record and the console.
CHOICE_WORDS = {"none": "no alignment", "ev": "one exposure per view", "full": "exposure and white balance"}
#: Cells per side of a block held back as one (the blocks are split into the folds at random).
CHECK_BLOCK = 4
#: A held-back residual counts at most this many robust standard deviations (squared).
LOSS_CLIP = 3.0
#: Fewer held-back (pair, fold) ratios than this: nothing can be shown, the views keep their colour.
MIN_CHECK_ROWS = 12
#: A pair's held-back cells in a fold count when there are at least this many (their median is its ratio).
MIN_HELD_CELLS = 3
#: Seed of the blocks' split into folds.
SEED = 0


@dataclass(frozen=True)
class AlignmentCheck:
    """The check's outcome: ``chosen`` (one of :data:`CHOICES`); ``losses`` the mean held-back loss
    of each choice; ``se`` the standard error of each choice's loss minus the best one's; ``rows`` the
    held-back (pair, fold) ratios judged, ``blocks`` the pairs they come from; ``reason`` one line saying why."""

    chosen: str
    losses: dict
    se: dict
    rows: int
    blocks: int
    reason: str

    def apply(self, x: np.ndarray) -> np.ndarray:
        """The log gains (V, 3) of the chosen correction made of the estimate ``x``."""
        return as_choice(x, self.chosen)

    def record(self) -> dict:
        return {"chosen": self.chosen, "reason": self.reason, "rows": self.rows, "blocks": self.blocks,
                "losses": {k: round(float(v), 5) for k, v in self.losses.items()},
                "se": {k: round(float(v), 5) for k, v in self.se.items()}}


def as_choice(x: np.ndarray, choice: str) -> np.ndarray:
    """Log gains (V, 3) ``x`` as ``choice`` applies them: none 0, ev the mean over channels, full ``x``."""
    if choice == "none":
        return np.zeros_like(x)
    if choice == "ev":
        return np.repeat(x.mean(axis=1, keepdims=True), 3, axis=1)
    return x


def _folds(pairs: list[PairCells], grid: CellGrid, folds: int) -> list[np.ndarray]:
    """Per pair, the fold (M,) of each of its cells: blocks of CHECK_BLOCK^3 cells, split at random."""
    r = grid.res
    nb = -(-r // CHECK_BLOCK)

    def block(cells):
        i, j, k = cells // (r * r), (cells // r) % r, cells % r
        return ((i // CHECK_BLOCK) * nb + j // CHECK_BLOCK) * nb + k // CHECK_BLOCK

    blocks = [block(p.cells) for p in pairs]
    uniq = np.unique(np.concatenate(blocks)) if blocks else np.zeros(0, np.int64)
    fold_of = dict(zip(uniq.tolist(), (np.random.default_rng(SEED).permutation(len(uniq)) % folds).tolist()))
    return [np.array([fold_of[b] for b in bl.tolist()], np.int64) for bl in blocks], blocks


def held_back_residuals(n_views: int, pairs: list[PairCells], forward, cfg: PhotometricConfig, grid: CellGrid):
    """({choice: (R, 3) residuals}, (R,) the pair of each): per pair and fold with MIN_HELD_CELLS held-back
    cells, the median of those cells' log ratios minus what each choice's gains (estimated without the fold)
    predict for the pair.  One number per pair and fold: the cells' own appearance (a strand texture, the
    coat seen more or less edge-on) averages out in the median, a wrong exposure does not."""
    fold, _ = _folds(pairs, grid, cfg.check_folds)
    res = {c: [] for c in CHOICES}
    where = []
    for f in range(cfg.check_folds):
        use = [fk != f for fk in fold]
        if not any(u.any() for u in use) or all(u.all() for u in use):
            continue
        x = log_gains(n_views, pairs, forward, cfg, use)[0]
        for k, (p, u) in enumerate(zip(pairs, use)):
            held = ~u
            if held.sum() < MIN_HELD_CELLS:
                continue
            d = np.median(p.d[held], axis=0)
            for c in CHOICES:
                xc = as_choice(x, c)
                res[c].append(d - (xc[p.i] - xc[p.j]))
            where.append(k)
    if not where:
        return {c: np.zeros((0, 3)) for c in CHOICES}, np.zeros(0, np.int64)
    return {c: np.stack(v) for c, v in res.items()}, np.asarray(where)


def check_alignment(n_views: int, pairs: list[PairCells], forward, cfg: PhotometricConfig,
                    grid: CellGrid) -> AlignmentCheck:
    """Which correction the held-back cells support (module docstring)."""
    res, blocks = held_back_residuals(n_views, pairs, forward, cfg, grid)   # clustered by pair
    rows = len(blocks)
    if rows < MIN_CHECK_ROWS:
        return AlignmentCheck("none", {}, {}, rows, 0, f"kept the views as they are: only {rows} pair ratios could be "
                              f"held back (fewer than {MIN_CHECK_ROWS}), too few to show that an alignment helps")
    full = res["full"]
    sigma = MAD_TO_SIGMA * np.median(np.abs(full - np.median(full, axis=0)), axis=0) + SIGMA_FLOOR
    loss = {c: np.minimum((r / sigma) ** 2, LOSS_CLIP ** 2).sum(axis=1) for c, r in res.items()}
    mean = {c: float(v.mean()) for c, v in loss.items()}
    best = min(CHOICES, key=mean.get)
    ub, bi = np.unique(blocks, return_inverse=True)
    nb = np.bincount(bi).astype(np.float64)
    se = {}
    for c in CHOICES:
        diff = loss[c] - loss[best]
        delta = diff.mean()
        d_b = np.bincount(bi, diff, len(ub))
        se[c] = float(np.sqrt(np.sum((d_b - nb * delta) ** 2) * len(ub) / max(len(ub) - 1, 1)) / rows)
    chosen = next(c for c in CHOICES if mean[c] - mean[best] <= cfg.check_z * se[c])
    return AlignmentCheck(chosen, mean, se, rows, len(ub), _reason(chosen, best, mean, se, cfg.check_z, rows))


def _reason(chosen: str, best: str, mean: dict, se: dict, z: float, rows: int) -> str:
    """One line on the check's outcome (``furrow model`` prints it)."""
    nums = ", ".join(f"{CHOICE_WORDS[c]} {mean[c]:.3f}" for c in CHOICES)
    tail = f"(mean clipped squared residual of {rows} held-back pair ratios: {nums})"
    if chosen == "none":
        return f"kept the views as they are: no alignment beats none by {z:g} standard errors {tail}"
    if chosen != best:
        return (f"{CHOICE_WORDS[chosen]}: {CHOICE_WORDS[best]} is no better by {z:g} standard errors "
                f"({mean[chosen] - mean[best]:+.3f} +- {se[chosen]:.3f}) {tail}")
    return f"{CHOICE_WORDS[chosen]}: shown on cells it did not see {tail}"

"""Where the held-out alpha's error lies (docs/novel_views.md, "The held-out alpha"): `furrow eval`
with each held-out view's rendered alpha kept beside its true matte, then the error split into
missed coverage, extra coverage and the pixels both cover, with the bias, the correlation, the best
integer shift and the agreement of 3 x 3 averages.

    PYTHONPATH=. .venv/bin/python scripts/heldout_alpha_split.py OUT -- eval CAPTURE --holdout 2 --methods gather

Everything after ``--`` is `furrow`'s command line; use one method (each frame is one record).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from scipy.ndimage import uniform_filter

SHIFT = 2
"""Largest shift (pixels) tried between the rendered and the true alpha."""


def run_eval(out: Path, furrow_args: list[str]) -> int:
    """`furrow` with ``furrow_args``, each scored frame's alpha and true matte saved to ``out``."""
    from furrow.cli import main
    from render import evaluate as ev

    out.mkdir(parents=True, exist_ok=True)
    scored = ev.composite_scores
    count = [0]

    def keep(scan, frame):
        if scan.alpha is not None:
            np.savez_compressed(out / f"view{count[0]:03d}.npz", rendered=np.asarray(frame.alpha, np.float32),
                                true=np.asarray(scan.alpha, np.float32))
            count[0] += 1
        return scored(scan, frame)

    ev.composite_scores = keep
    try:
        return main(furrow_args)
    finally:
        ev.composite_scores = scored


def split(rendered: np.ndarray, true: np.ndarray) -> dict:
    """The error of one view's ``rendered`` alpha against its ``true`` matte (both (H, W))."""
    r, t = rendered.astype(np.float64), true.astype(np.float64)
    region = (r > 0) | (t > 0)
    n = max(int(region.sum()), 1)
    e = r - t
    parts = {"missed": (r <= 0) & (t > 0), "extra": (r > 0) & (t <= 0), "both": (r > 0) & (t > 0)}
    rec = {f"{k}_share": m.sum() / n for k, m in parts.items()}
    rec.update({f"{k}_mse": np.sum(e[m] ** 2) / n for k, m in parts.items()})
    b = parts["both"]
    rec.update(mse=np.sum(e[region] ** 2) / n, bias_both=float(e[b].mean()), std_rendered=float(r[b].std()),
               std_true=float(t[b].std()), corr=float(np.corrcoef(r[b], t[b])[0, 1]))
    shifts = [(np.corrcoef(np.roll(r, (dy, dx), (0, 1))[b], t[b])[0, 1], dy, dx)
              for dy in range(-SHIFT, SHIFT + 1) for dx in range(-SHIFT, SHIFT + 1)]
    rec["best_shift"] = max(shifts)[1:]
    r3, t3 = uniform_filter(r, 3), uniform_filter(t, 3)
    rec.update(corr_3x3=float(np.corrcoef(r3[b], t3[b])[0, 1]), mse_3x3=float(np.mean((r3 - t3)[b] ** 2)))
    return rec


def main(argv=None) -> None:
    argv = sys.argv[1:] if argv is None else argv
    if "--" not in argv or argv.index("--") != 1:
        raise SystemExit(__doc__)
    out = Path(argv[0])
    rc = run_eval(out, argv[2:])
    if rc:
        raise SystemExit(rc)
    recs = [split(d["rendered"], d["true"]) for d in map(np.load, sorted(out.glob("view*.npz")))]
    for k in recs[0]:
        if k != "best_shift":
            print(f"{k:>14}: {np.mean([x[k] for x in recs]):.4f}")
    print(f"{'best_shift':>14}: {sorted({x['best_shift'] for x in recs})}")


if __name__ == "__main__":
    main()

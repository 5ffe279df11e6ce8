"""How much of the needles' fine alpha pattern a model's kept views keep (issue 30, stop 77; docs/matting.md
"What the room matte smooths away").

For a model of the kept views (``furrow model CAP --frames 0::2``) and the capture's true mattes (``mask_path``), per
kept view inside the band (true alpha in (0.02, 0.98)):

* the model's mean alpha per class of the true alpha (0.02-0.3, 0.3-0.7, 0.7-0.95, >= 0.95);
* the alpha MSE, and its share left after a 3 x 3 and a 7 x 7 mean of the error (how much of it is finer than that);
* the **detail slope**: the error's fine part (minus its 3 x 3 mean) regressed on the truth's fine part. 0: the fine
  pattern kept; -1: smoothed away entirely. Also the fine parts' standard deviations, model against truth.

    PYTHONPATH=. .venv/bin/python scripts/alpha_detail.py MODEL CAPTURE [--views N]

CAPTURE is the capture with its true mattes (not the ``_hidden`` copy the model was built from); its frames 0, 2,
4, ... must be the model's views in order.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from scipy.ndimage import uniform_filter

#: Classes of the true alpha for the model's mean alpha: (low, high).
CLASSES = ((0.02, 0.3), (0.3, 0.7), (0.7, 0.95), (0.95, 1.01))
#: The band: true alpha strictly between these.
BAND = (0.02, 0.98)


def view_figures(a: np.ndarray, m: np.ndarray) -> list[float]:
    """The figures of one view (module docstring) from its model alpha ``a`` and true alpha ``m`` (h, w)."""
    band = (m > BAND[0]) & (m < BAND[1])
    e = a - m
    mse = float((e ** 2)[band].mean())
    fine_e, fine_m, fine_a = e - uniform_filter(e, 3), m - uniform_filter(m, 3), a - uniform_filter(a, 3)
    slope = float((fine_e[band] * fine_m[band]).sum() / max((fine_m[band] ** 2).sum(), 1e-12))
    means = [float(a[band & (m >= lo) & (m < hi)].mean()) if (band & (m >= lo) & (m < hi)).any() else np.nan
             for lo, hi in CLASSES]
    return means + [mse, float((uniform_filter(e, 3) ** 2)[band].mean()) / mse,
                    float((uniform_filter(e, 7) ** 2)[band].mean()) / mse, slope,
                    float(fine_a[band].std()), float(fine_m[band].std())]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("model", type=Path)
    ap.add_argument("capture", type=Path)
    ap.add_argument("--views", type=int, default=None, help="the first N kept views only")
    args = ap.parse_args()
    from capture.io import read_scanset
    from volume.model import load_model

    rgbz = load_model(args.model).rgbz
    scans = read_scanset(args.capture).scans
    kept = list(range(0, len(scans), 2))[: args.views]
    rows = []
    for k, i in enumerate(kept):
        if scans[i].alpha is None:
            raise SystemExit(f"{args.capture}: frame {i} has no true matte (mask_path)")
        rows.append(view_figures(np.asarray(rgbz.alpha[k], np.float64), np.asarray(scans[i].alpha, np.float64)))
    r = np.nanmean(np.asarray(rows), axis=0)
    classes = ", ".join(f"{lo:g}-{min(hi, 1):g}: {v:.3f}" for (lo, hi), v in zip(CLASSES, r[:4], strict=True))
    print(f"{len(rows)} kept views; model's mean alpha by true alpha {classes}")
    print(f"band alpha MSE {r[4]:.4f}; left after a 3 x 3 mean {r[5]:.2f}, 7 x 7 {r[6]:.2f}; detail slope {r[7]:+.3f} "
          f"(fine sd model {r[8]:.3f}, truth {r[9]:.3f})")


if __name__ == "__main__":
    main()

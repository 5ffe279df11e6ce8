"""The plate stage's JSON record (capture.plate.background_plates): the chosen mode, the paths' errors,
the shares of the matting band with a known, an estimated and a crossing background, and each view's."""

from __future__ import annotations

import numpy as np


def summary(errs, k: int = 0) -> float | None:
    """The median of the finite ``k``-th entries (0 error, 1 rmse) of (error, rmse) pairs, rounded; None
    without any."""
    e = [x[k] for x in errs if np.isfinite(x[k])]
    return round(float(np.median(e)), 5) if e else None


def plate_record(mode: str, plates: list, gains: np.ndarray, tried: dict) -> dict:
    """JSON-able record of the plates (capture.plate.Plate, one a view) made by ``mode``; ``gains`` (V, 3)
    each view's gain, ``tried`` each tried path's per-view (error, rmse) pairs on the held-back rings
    (recorded as their medians over views: ``tried_error`` and ``tried_rmse``, the one choose_mode
    compares)."""
    band = [p.band_known for p in plates]
    return {"mode": mode, "tried_error": {m: summary(e) for m, e in tried.items()},
            "tried_rmse": {m: summary(e, 1) for m, e in tried.items()},
            "band_known_mean": round(float(np.mean(band)), 4), "band_known_min": round(float(np.min(band)), 4),
            "band_estimated_mean": round(float(np.mean([p.band_estimated for p in plates])), 4),
            "band_crossing_mean": round(float(np.mean([p.band_crossing for p in plates])), 4),
            "error_median": summary([(p.error, p.error_rmse) for p in plates]),
            "gains_ev": [[round(float(x), 3) for x in np.log2(g)] for g in gains],
            "per_view": [p.record() for p in plates]}

"""How far the known-background matte's per-pixel alpha (its data term, before the smooth solve) is off, by how far
its candidate colour lies from the background (issue 30, stop 73: capture.matting_known.SEPARATION).

Step 2 of capture.matting_known reads each partial pixel's alpha off the line from its background B through its
photo C, against a candidate colour P (the nearest sure colour, or a palette colour): alpha = (C - B).(P - B) /
|P - B|^2.  A colour error dP moves that alpha by about alpha |dP| / |P - B|, so the nearer P lies to B, the less
the data term can be trusted; its weight against the matting Laplacian is sep^2 / (sep^2 + SEPARATION^2) with sep =
|P - B|.  This script measures the error that weight stands for: on the kept views of a room capture (the default
plate; the matte's full-size path on the whole frame, the depth trimap with its rim opened), the data term's alpha
against the true matte, on pixels of true alpha 0.3-0.9 whose background a frame saw and where neither the photo nor
the plate is blown out, binned by |P - B|; and the candidate's own error |P - F_true| (F_true = C_black / a_true
from the black twin).

    PYTHONPATH=. .venv/bin/python scripts/data_term_error.py ROOM BLACK_TWIN [--frames 0::2]

The room capture must not have auto exposure (the black twin's photo is the truth at the room's exposure).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import capture.matting_known as mk
from capture.matting import depth_trimap, warm_up
from capture.matting_rim import open_rim
from capture.plate import PlateConfig, background_plates

sys.path.insert(0, str(Path(__file__).parent))
from plate_error_split import kept_with_twin, room_twin_args

#: The true alpha's range read.
TRUE_RANGE = (0.3, 0.9)
#: Bins of |P - B| (linear, Euclidean).
BINS = (0.0, 0.05, 0.1, 0.2, 0.4, 2.0)


def data_term_alpha(scan, object_depth, plate) -> tuple[np.ndarray, np.ndarray] | None:
    """(alpha_hat (H, W), candidate colour P (H, W, 3)) of step 2 for one view, from the full-size path run on the
    whole frame (capture.matting_known.known_background_matte with its candidate fit observed); None when the fit
    did not run (no colour source)."""
    seen = {}
    fit = mk.fit_candidates

    def observed(image, background, nearest, sources, lower, extra=()):
        out = fit(image, background, nearest, sources, lower, extra)
        if "a_hat" not in seen:  # the first pass: the data term the solve starts from
            seen["a_hat"], seen["near"] = np.array(out[0]), np.array(nearest)
        return out

    img = scan.linear_rgb
    tri, _ = open_rim(depth_trimap(object_depth), img, plate)
    mk.fit_candidates = observed
    try:
        mk.known_background_matte(img, tri, plate.background, plate.known, plate.noise, np.asarray(object_depth) > 0)
    finally:
        mk.fit_candidates = fit
    return (seen["a_hat"], seen["near"]) if "a_hat" in seen else None


def main(argv=None) -> None:
    a = room_twin_args(__doc__, argv)
    warm_up()
    ss, bs, out, rep, views = kept_with_twin(a.room, a.black, a.frames)
    plates, _ = background_plates(views, PlateConfig(), rep.plane, (rep.focus_center, rep.focus_radius))
    err, sep, cand = [], [], []
    for s, o, b, pl in zip(ss.scans, out.scans, bs.scans, plates, strict=True):
        if pl is None:
            continue
        pl = pl.full() if getattr(pl, "frame", None) is not None else pl
        got = data_term_alpha(s, o.depth, pl)
        if got is None:
            continue
        C, Cb, at = s.linear_rgb.astype(np.float64), b.linear_rgb.astype(np.float64), np.asarray(s.alpha, np.float64)
        B = pl.background.astype(np.float64)
        known = pl.known if pl.estimated is None else pl.known & ~pl.estimated
        m = known & (at >= TRUE_RANGE[0]) & (at < TRUE_RANGE[1]) & (C.max(-1) < mk.CLIP_LEVEL) & \
            (B.max(-1) < mk.CLIP_LEVEL)
        err.append(got[0][m] - at[m])
        sep.append(np.linalg.norm(got[1][m] - B[m], axis=-1))
        cand.append(np.linalg.norm(got[1][m] - Cb[m] / at[m, None], axis=-1))
    err, sep, cand = (np.concatenate(x) for x in (err, sep, cand))
    print(f"{a.room}: {err.size} pixel-views; candidate |P - F_true| RMS {np.sqrt(np.mean(cand ** 2)):.4f}, "
          f"median {np.median(cand):.4f}; |P - B| median {np.median(sep):.3f}")
    print(f"  |P - B|        share   data-term alpha error RMS / mean   weight at SEPARATION {mk.SEPARATION}")
    for lo, hi in zip(BINS[:-1], BINS[1:], strict=True):
        m = (sep >= lo) & (sep < hi)
        if m.any():
            w = np.mean(sep[m] ** 2 / (sep[m] ** 2 + mk.SEPARATION ** 2))
            rms = np.sqrt(np.mean(err[m] ** 2))
            print(f"  [{lo:.2f}, {hi:.2f})   {m.mean():.3f}   {rms:.3f} / {err[m].mean():+.3f}{w:21.2f}")


if __name__ == "__main__":
    main()

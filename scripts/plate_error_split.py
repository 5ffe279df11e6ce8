"""Where the kept views' colour goes wrong before a room (issue 30): the premultiplied colour alpha x F
of the default plate + matte on a room capture's kept views against the same renders over black (its
black twin: the true premultiplied colour), split by what the plate knew behind each object pixel:
the background known and not clipped, known but clipped (capture.matting_known.clipped), not known;
the known pixels that no frame saw clean but the frames' lines gave (capture.plate_lines, fixed
camera) are a class of their own ("B estimated").  Also with the true matte given (F from the same
plate), which isolates the alpha's share, and the estimated background against the true one
((room - black) / (1 - true alpha) where the true alpha is below TRUTH_ALPHA and the truth is not
blown out).

    PYTHONPATH=. .venv/bin/python scripts/plate_error_split.py ROOM_CAPTURE BLACK_TWIN [--frames 0::2]

e.g. /work/cache/hardcases/conifer_room_turntable /work/cache/hardcases/conifer_black_turntable.
Prints per class: its share of the object pixels (true or estimated alpha > 0), its share of the
summed squared error, and the mean squared error (linear, summed over channels).
"""

from __future__ import annotations

import argparse
import contextlib
import io

import numpy as np

from capture.extent import remove_surroundings
from capture.io import read_scanset
from capture.matting import MatteConfig, matte_scan, warm_up
from capture.matting_known import CLIP_LEVEL, clipped
from capture.plate import PlateConfig, PlateView, background_plates
from capture.scan import Scan

CLASSES = ("B known, not clipped", "B known, clipped", "B estimated, not clipped", "B estimated, clipped",
           "B not known")
#: The true background is read where the true alpha is below this.
TRUTH_ALPHA = 0.9


def _classes(scan, matte, plate, seen) -> dict:
    """Class name -> (H, W) bool over the object pixels of one view; ``seen``: (H, W) the plate's
    known pixels without the lines' estimate."""
    obj = (scan.alpha > 0) | (matte.alpha > 0)
    known = plate.known if plate is not None else np.zeros(obj.shape, bool)
    bg = plate.background if plate is not None else np.zeros(scan.linear_rgb.shape, np.float32)
    cl = clipped(scan.linear_rgb, bg)
    est = known & ~seen
    return dict(zip(CLASSES, (obj & seen & ~cl, obj & seen & cl, obj & est & ~cl, obj & est & cl, obj & ~known),
                    strict=True))


def _plates(views, rep):
    """(plates, record, per view the known pixels without the lines' estimate)."""
    from capture import plate_fixed

    args = (views, PlateConfig(), rep.plane, (rep.focus_center, rep.focus_radius))
    plates, rec = background_plates(*args)
    keep = plate_fixed.FIXED_ESTIMATE_UNSEEN
    plate_fixed.FIXED_ESTIMATE_UNSEEN = False
    try:
        seen = [p.full().known if p is not None else None for p in background_plates(*args)[0]]
    finally:
        plate_fixed.FIXED_ESTIMATE_UNSEEN = keep
    return plates, rec, seen


def _background_error(scan, black, plate, seen) -> np.ndarray:
    """Largest channel's |estimated B - true B| over the view's estimated pixels where the truth is
    readable (true alpha below TRUTH_ALPHA) and not blown out."""
    if plate is None:
        return np.zeros(0)
    a = np.asarray(scan.alpha, np.float64)[..., None]
    truth = (scan.linear_rgb.astype(np.float64) - black.linear_rgb) / np.maximum(1.0 - a, 1e-6)
    m = plate.known & ~seen & (a[..., 0] < TRUTH_ALPHA) & (truth.max(-1) < CLIP_LEVEL) & \
        (scan.linear_rgb.max(-1) < CLIP_LEVEL)
    return np.abs(plate.background - truth).max(-1)[m]


def room_twin_args(doc: str, argv=None) -> argparse.Namespace:
    """The command line of the scripts that score a room capture's kept views against its black twin: ROOM BLACK
    [--frames SPEC]; ``doc``: the script's docstring (its first line is the description)."""
    p = argparse.ArgumentParser(description=doc.splitlines()[0])
    p.add_argument("room")
    p.add_argument("black")
    p.add_argument("--frames", default="0::2", help="the kept frames (default 0::2, furrow eval --holdout 2)")
    return p.parse_args(argv)


def kept_with_twin(room: str, black: str, frames: str):
    """(room scan set, black twin's, the room's after the extent stage, its report, the plate stage's views) of the
    kept ``frames`` of a room capture and its black twin; SystemExit when the room's kept frames have no true matte.
    Shared by the scripts that score the kept views against the truth (alpha_bias_views, data_term_error)."""
    ss, bs = read_scanset(room, frames), read_scanset(black, frames)
    if any(s.alpha is None for s in ss.scans):
        raise SystemExit(f"{room}: the kept frames need their true matte (mask_path)")
    out, rep = remove_surroundings(ss)
    views = [PlateView(o.camera, o.linear_rgb, o.depth, s.depth) for s, o in zip(ss.scans, out.scans, strict=True)]
    return ss, bs, out, rep, views


def main(argv=None) -> None:
    a = room_twin_args(__doc__, argv)
    warm_up()
    ss, bs, out, rep, views = kept_with_twin(a.room, a.black, a.frames)
    plates, rec, seens = _plates(views, rep)
    err = {k: np.zeros(3) for k in CLASSES}  # estimated matte, true matte, pixels
    b_err = []
    for s, o, b, pl, seen in zip(ss.scans, out.scans, bs.scans, plates, seens, strict=True):
        with contextlib.redirect_stdout(io.StringIO()):
            est = matte_scan(Scan(s.rgb, s.depth, s.camera, s.name), o.depth, MatteConfig(), pl)
            given = matte_scan(s, o.depth, MatteConfig(), pl)
        truth = b.linear_rgb.astype(np.float64)
        e = [((m.alpha[..., None] * m.foreground - truth) ** 2).sum(-1) for m in (est, given)]
        for k, mask in _classes(s, est, pl, seen).items():
            err[k] += (e[0][mask].sum(), e[1][mask].sum(), mask.sum())
        b_err.append(_background_error(s, b, pl, seen))
    tot = sum(v[0] for v in err.values())
    npx = sum(v[2] for v in err.values())
    print(f"{a.room}: plate {rec['mode']}, band known {rec.get('band_known_mean')}, of it estimated "
          f"{rec.get('band_estimated_mean', 0.0)}")
    be = np.concatenate(b_err)
    if len(be):
        print(f"  estimated B against the truth ({len(be)} pixel-views, truth not blown out): largest channel's "
              f"|error| median {np.median(be):.4f}, 90 % {np.quantile(be, 0.9):.4f}")
    for k, (e_est, e_true, n) in err.items():
        print(f"  {k:22s} pixels {n / npx:6.1%}  error share {e_est / tot:6.1%}  mean {e_est / max(n, 1):.5f}"
              f"  (true matte: mean {e_true / max(n, 1):.5f})")


if __name__ == "__main__":
    main()

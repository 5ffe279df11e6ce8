"""Where a room capture's kept views lose their premultiplied colour, and where their alpha's error comes from
(issue 30, tenth round; docs/matting.md "Issue 30, tenth round").

Against the truth from the black twin (a_true: the room capture's ``mask_path``; premultiplied P_true = C_black):

1. per true-alpha class, the premultiplied error P = a F of the model's kept views split into the alpha's
   part (a - a_true) F and the colour's a_true (F - F_true), and the true colour's own spread about its
   class mean (what a colour constant over the class cannot hold), with the model's and the truth's sd;
2. (with DUMP, ``scripts/cells_variants.py``'s dump of the same model's line samples) the alpha's RMS error
   at the usable partial pixels, before seen and estimated backgrounds: the matte's, and the alpha on the
   pixel's line B -> C given the model's colour with the plate's B, with the true B, and with the true colour.

    PYTHONPATH=. python scripts/ssim_sources.py ROOM BLACK MODEL [DUMP]
"""

from __future__ import annotations

import argparse
import pickle
import sys
from pathlib import Path

import numpy as np

from capture.io import read_scanset

#: The true-alpha classes of the split (low, high).
CLASSES = ((0.1, 0.3), (0.3, 0.5), (0.5, 0.85), (0.85, 2.0))
#: The dump's partial pixels compared: true alpha in this range (B_true = (C - C_black) / (1 - a_true)).
TRUE_RANGE = (0.02, 0.8)


def premultiplied_split(at, cb, rgb, al) -> None:
    """Prints step 1 (module docstring) for the kept views' true alpha ``at``, C_black ``cb`` and the model."""
    ft = cb / np.maximum(at, 1e-3)[..., None]
    for lo, hi in CLASSES:
        m = (at >= lo) & (at < hi)
        p_err = rgb[m] * al[m][:, None] - cb[m]
        e_a = (al[m] - at[m])[:, None] * rgb[m]
        e_f = at[m][:, None] * (rgb[m] - ft[m])
        spread = at[m][:, None] * (ft[m] - cb[m].sum(0) / at[m].sum())
        print(f"a_true {lo:.2f}-{hi:.2f}: P mse {np.mean(p_err ** 2):.2e} = alpha's {np.mean(e_a ** 2):.2e} + "
              f"colour's {np.mean(e_f ** 2):.2e} + cross {2 * np.mean(e_a * e_f):+.1e};  the true colour's spread "
              f"{np.mean(spread ** 2):.2e};  sd F model {rgb[m].std(0).round(4)} true {ft[m].std(0).round(4)}")


def _line(C, B, F):
    d = F - B
    return np.clip(((C - B) * d).sum(1) / np.maximum((d * d).sum(1), 1e-9), 0.0, 1.0)


def alpha_sources(room, black, kept, rgb, samples) -> None:
    """Prints step 2 (module docstring)."""
    rows = []
    for v, s in enumerate(samples):
        if s is None:
            continue
        i, idx = kept[v], s["index"]
        at = np.asarray(room[i].alpha).reshape(-1)[idx].astype(np.float64)
        cb = black[i].linear_rgb.reshape(-1, 3)[idx].astype(np.float64)
        ok = s["usable"] & (at > TRUE_RANGE[0]) & (at < TRUE_RANGE[1])
        C, B, F = s["C"][ok].astype(np.float64), s["B"][ok].astype(np.float64), rgb[v].reshape(-1, 3)[idx][ok]
        a, cb = at[ok], cb[ok]
        bt, ft = (C - cb) / (1 - a)[:, None], cb / a[:, None]
        rows.append(np.stack([a, s["a"][ok], _line(C, B, F), _line(C, bt, F), _line(C, B, ft),
                              np.abs(B - bt).mean(1), s["sb"][ok] > 0], 1))
    r = np.concatenate(rows)
    for name, m in (("all", np.ones(len(r), bool)), ("B seen", r[:, 6] == 0), ("B estimated", r[:, 6] == 1)):
        q = r[m]
        rms = [np.sqrt(np.mean((q[:, k] - q[:, 0]) ** 2)) for k in (1, 2, 3, 4)]
        print(f"{name:12s} {m.sum():7d} px  |B - B_true| {q[:, 5].mean():.4f}  alpha RMS: matte {rms[0]:.4f}, "
              f"line(plate B, model F) {rms[1]:.4f}, line(true B, model F) {rms[2]:.4f}, "
              f"line(plate B, true F) {rms[3]:.4f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("room")
    ap.add_argument("black")
    ap.add_argument("model")
    ap.add_argument("dump", nargs="?")
    a = ap.parse_args()
    sys.path.insert(0, str(Path(__file__).parent))
    from ssim_split import _arrays

    room, black = read_scanset(a.room).scans, read_scanset(a.black).scans
    kept = [i for i in range(len(room)) if i % 2 == 0]
    _, rgb, _, al, _ = _arrays(a.model)
    at = np.stack([np.asarray(room[i].alpha, np.float32) for i in kept])
    cb = np.stack([black[i].linear_rgb.astype(np.float32) for i in kept])
    premultiplied_split(at, cb, rgb, al)
    if a.dump:
        with open(a.dump, "rb") as f:
            alpha_sources(room, black, kept, rgb, pickle.load(f)["samples"])


if __name__ == "__main__":
    main()

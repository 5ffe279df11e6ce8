"""Issue 30's tables side by side: the output folders of scripts/issue30_table.py for a baseline and its
variants, read back (nothing is run), as one markdown table of gather's held-out masked PSNR / SSIM /
sharpness per capture, each variant's change against the first folder, the black twins' digits compared,
and the mean change over the room captures.

    python scripts/issue30_compare.py main=/tmp/t_main a=/tmp/t_a b=/tmp/t_b
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path


def scores(out: Path) -> dict:
    """{capture tag: (PSNR, SSIM, sharpness)} of every eval json in an issue30_table.py folder."""
    got = {}
    for js in sorted(out.glob("*__*.json")):
        g = json.loads(js.read_text())["gather"]
        got[js.stem] = (g["psnr_masked"], g["ssim_masked"], g["sharpness"])
    return got


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("runs", nargs="+", help="NAME=FOLDER, the baseline first")
    a = p.parse_args(argv)
    runs = [(r.split("=", 1)[0], scores(Path(r.split("=", 1)[1]))) for r in a.runs]
    base = runs[0][1]
    rooms = [t for t in base if "_black_" not in t and not t.endswith("fur_black_similar")]
    print("| capture | " + " | ".join(n for n, _ in runs) + " |")
    print("|---|" + "---|" * len(runs))
    for t in rooms:
        cells = [f"{base[t][0]:.4f} / {base[t][1]:.4f} / {base[t][2]:.3f}"]
        for _, s in runs[1:]:
            x = s.get(t)
            cells.append("-" if x is None else f"{x[0]:.4f} / {x[1]:.4f} / {x[2]:.3f} ({x[0] - base[t][0]:+.4f})")
        print(f"| {t.replace('__', '/')} | " + " | ".join(cells) + " |")
    means = []
    for n, s in runs[1:]:
        d = [s[t][0] - base[t][0] for t in rooms if t in s]
        means.append(f"{n}: mean {sum(d) / max(len(d), 1):+.4f} over {len(d)}, worst {min(d, default=0):+.4f}")
    print("\n" + "; ".join(means))
    for t in (t for t in base if t not in rooms):
        same = ["same digits" if s.get(t) == base[t] else f"differs: {s.get(t)}" for _, s in runs[1:]]
        print(f"black twin {t}: {base[t][0]:.6f} / {base[t][1]:.5f}; " + ", ".join(same))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

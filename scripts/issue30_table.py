"""Issue 30's table in one command: every conifer / fur capture in a room beside its black twin, each scored
as the issue scores it (the kept views' mattes hidden by scripts/hide_mattes.py, then `furrow eval CAP
--holdout 2 --methods gather,points`), the gap to the twin against the issue's 1.5 dB.  Run it on the
captures a change was made on *and* on ones it was not (docs/matting.md "The eighth round on captures it
was not made on"): a step chosen on three captures lost on a fourth.

    PYTHONPATH=. .venv/bin/python scripts/issue30_table.py /work/cache/hardcases /work/cache/hardcases_unseen/* \\
        -o /tmp/issue30 [--extra ARG ...]

Each ROOT is searched for folders named ``*_room_*`` / ``fur_similar_bg*`` (the room captures) and their twin
(``room`` -> ``black``; ``fur_similar_bg`` and ``fur_room_table_ae_lens`` -> ``fur_black_similar``).
``--extra`` passes arguments on to every
`furrow eval` (``--extra=--matte-across --extra=off``).  ``--switches`` runs every eval through
scripts/cells_switches.py with its ``ABL`` (``--switches RECROSS=1,CELL_LINE_ALPHA=0.4``: a step's module
switches; they act in the main process, where the colour across the views is fitted).  The evals run one
after another (about 20-40 s each at 640x480 on 2 cores); a capture already scored in OUT with the same
arguments is read back.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

#: The issue's targets: the gap of a room capture to its black twin (dB), the AE + lens capture's.
GAP_TARGET = 1.5
GAP_TARGET_AE = 2.0


def twin(room: Path) -> Path | None:
    """The black twin of a room capture folder, or None."""
    fur = room.name in ("fur_similar_bg", "fur_similar_bg_jump_ae", "fur_similar_bg_orbit", "fur_room_table_ae_lens")
    name = ("fur_black_similar_orbit" if room.name.endswith("_orbit") else "fur_black_similar") if fur \
        else room.name.replace("_room_", "_black_")
    if "_table_ae_lens" in name:   # the AE + lens capture is measured against the turntable's twin
        name = name.replace("_table_ae_lens", "_turntable")
    if name.endswith("_ae"):   # the auto-exposure orbit against the orbit's twin
        name = name[: -len("_ae")]
    if name.endswith("_jump"):   # the turntable whose exposure jumps in a few views against the turntable's
        name = name[: -len("_jump")]
    t = room.parent / name
    return t if t.is_dir() and t != room else None


def score(capture: Path, out: Path, extra: list[str], switches: str = "") -> dict:
    """Gather's and the points' held-out scores of ``capture`` with its kept mattes hidden (cached in ``out``);
    ``switches``: cells_switches.py's ABL (module docstring)."""
    tag = f"{capture.parent.name}__{capture.name}"
    js = out / f"{tag}.json"
    args_file = out / f"{tag}.args"
    said = " ".join(extra) + (f" ABL={switches}" if switches else "")
    if js.is_file() and args_file.is_file() and args_file.read_text() == said:
        return json.loads(js.read_text())
    cap = out / f"cap_{tag}"
    py = [sys.executable]
    subprocess.run(py + ["scripts/hide_mattes.py", str(capture), str(cap)], check=True, capture_output=True)
    log = out / f"{tag}.log"
    with log.open("w") as f:
        cli = ["scripts/cells_switches.py"] if switches else ["-m", "furrow"]
        env = {**os.environ, "ABL": switches} if switches else None
        r = subprocess.run(py + cli + ["eval", str(cap), "--holdout", "2", "--methods", "gather,points",
                                       "--json", str(js), "-o", str(out / f"ev_{tag}"), *extra],
                           stdout=f, stderr=f, env=env)
    if r.returncode:
        raise SystemExit(f"{capture}: furrow eval failed (exit {r.returncode}); see {log}")
    args_file.write_text(said)
    return json.loads(js.read_text())


def row(d: dict) -> tuple[float, float, float, float]:
    g = d["gather"]
    return g["psnr_masked"], g["ssim_masked"], g["sharpness"], d["points"]["psnr_masked"]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("roots", nargs="+", type=Path)
    p.add_argument("-o", "--out", type=Path, required=True)
    p.add_argument("--extra", action="append", default=[], help="an argument passed on to every furrow eval")
    p.add_argument("--switches", default="", metavar="ABL",
                   help="module switches for every eval, as scripts/cells_switches.py's ABL (RECROSS=1,...)")
    a = p.parse_args(argv)
    a.out.mkdir(parents=True, exist_ok=True)
    rooms = sorted(c for r in a.roots for c in r.iterdir()
                   if c.is_dir() and ("_room_" in c.name or c.name.startswith("fur_similar_bg")))
    if not rooms:
        raise SystemExit(f"no room captures under {', '.join(map(str, a.roots))}")
    print("| capture | gather PSNR / SSIM / sharpness | points | black twin | gap | target |")
    print("|---|---|---|---|---|---|")
    for room in rooms:
        ps, ss, sh, pt = row(score(room, a.out, a.extra, a.switches))
        tw = twin(room)
        if tw is None:
            print(f"| {room.parent.name}/{room.name} | {ps:.3f} / {ss:.3f} / {sh:.2f} | {pt:.2f} | - | - | - |")
            continue
        bp, bs, _, _ = row(score(tw, a.out, a.extra, a.switches))
        target = GAP_TARGET_AE if "ae_lens" in room.name or room.name.endswith("_ae") else GAP_TARGET
        gap = ps - bp
        verdict = "met" if -gap <= target else "**missed**"
        if room.name.startswith("fur"):
            verdict = "(fur: no worse than before)"
        print(f"| {room.parent.name}/{room.name} | {ps:.3f} / {ss:.3f} / {sh:.2f} | {pt:.2f} | {bp:.3f} / {bs:.3f} "
              f"| {gap:+.2f} | {target}: {verdict} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

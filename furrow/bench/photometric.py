"""``furrow bench photometric``: recovered exposure and white balance against the synthetic truth.

For each capture (``furrow synth --auto-exposure``; its true per-view camera gains in
``gt/exposure.json``; a capture without that file is taken at fixed exposure, truth = 1), the
kept views (i % --holdout == 0, those `furrow eval` builds from) are aligned by
capture.photometric exactly as the model build does, and per view

    e_c = log2(recovered correction_c) + log2(true camera gain_c) - median over views of the same

(the one global gain no method can know is removed) gives the EV error (mean of e over r g b)
and the white-balance error (e_c minus that mean, in percent of gain).  Prints median and max over
views of both, and the stage's wall and CPU seconds.  The numbers in the issue-21 report come from

    furrow synth furball -o out/ae/furball_ae --size 640x480 --auto-exposure
    furrow bench photometric out/ae/furball_ae out/ae/furball
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path


def truth_gains(folder: Path, names: list[str]):
    """(V, 3) true camera gains of the named views (1 where gt/exposure.json is absent)."""
    import numpy as np

    from datasets_synthetic.camera_traits import EXPOSURE_FILE

    path = folder / EXPOSURE_FILE
    if not path.is_file():
        return np.ones((len(names), 3)), False
    rec = {Path(v["name"]).stem: v["gain"] for v in json.loads(path.read_text())["views"]}
    missing = [n for n in names if Path(n).stem not in rec]
    if missing:
        raise ValueError(f"{path}: no gains for views {missing[:3]}")
    return np.array([rec[Path(n).stem] for n in names], np.float64), True


def errors(recovered, truth) -> dict:
    """EV and white-balance errors (module docstring) of (V, 3) corrections against camera gains."""
    import numpy as np

    e = np.log2(recovered) + np.log2(truth)
    e = e - np.median(e, axis=0)
    ev = e.mean(axis=1)
    wb = 100 * (np.exp2(e - ev[:, None]) - 1)
    return {"ev_median": float(np.median(np.abs(ev))), "ev_max": float(np.abs(ev).max()),
            "wb_pct_median": float(np.median(np.abs(wb))), "wb_pct_max": float(np.abs(wb).max()),
            "true_ev_spread": float(np.std(np.log2(truth).mean(axis=1)))}


def bench_one(scans: Path, holdout: int, reference: str) -> dict:
    from capture.io import read_scanset, resolve_transforms
    from capture.photometric import PhotometricConfig, estimate_gains

    ss = read_scanset(scans, f"0::{holdout}")
    names = [s.name for s in ss.scans]
    truth, jittered = truth_gains(resolve_transforms(scans).parent, names)
    t0, c0 = time.perf_counter(), time.process_time()
    res = estimate_gains(ss.scans, PhotometricConfig(reference=reference))
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return {"scans": str(scans), "views": len(names), "jittered": jittered, "pairs": res.pairs,
            "samples": res.samples, "seconds": wall, "cpu_seconds": cpu, "size": list(ss.scans[0].rgb.shape[1::-1]),
            **errors(res.gains, truth)}


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="furrow bench photometric", description=__doc__.splitlines()[0])
    p.add_argument("scans", type=Path, nargs="+", help="captures (transforms.json or its folder), with or "
                   "without gt/exposure.json")
    p.add_argument("--holdout", type=int, default=2, help="align the views i %% K == 0 (default 2)")
    p.add_argument("--reference", default="median", help="gauge: median (default), mean or a view name")
    p.add_argument("--json", action="store_true", help="print JSON")
    args = p.parse_args(argv)
    rows = [bench_one(s, args.holdout, args.reference) for s in args.scans]
    if args.json:
        print(json.dumps(rows, indent=1))
        return 0
    from rich.console import Console
    from rich.table import Table

    t = Table(title="photometric alignment against the synthetic truth (kept views)")
    for c in ("capture", "views", "size", "truth", "EV err median", "EV err max", "WB err % median", "WB err % max",
              "pairs", "samples", "wall s", "CPU s"):
        t.add_column(c, justify="right")
    for r in rows:
        t.add_row(Path(r["scans"]).name, str(r["views"]), "x".join(map(str, r["size"])),
                  f"{r['true_ev_spread']:.2f} EV" if r["jittered"] else "fixed", f"{r['ev_median']:.4f}",
                  f"{r['ev_max']:.4f}", f"{r['wb_pct_median']:.2f}", f"{r['wb_pct_max']:.2f}", str(r["pairs"]),
                  str(r["samples"]), f"{r['seconds']:.2f}", f"{r['cpu_seconds']:.2f}")
    Console().print(t)
    return 0

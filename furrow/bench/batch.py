"""``furrow bench batch``: N small captures through ``furrow batch`` (Ray, --workers W) against the same N
run one after another with ``furrow model``.

Both sides do the same work: the model step only, at the same --max-res, each capture in its own
process (``furrow model`` is started once per capture, as a user would; ``furrow batch`` starts one
Ray worker per capture, ``max_calls=1``).  The captures are ``furrow synth torus --small --seed i``,
cached under OUT/data.  Reported:

- ``speedup`` = sequential wall time / batch wall time (the ideal is W on W free cores);
- ``overhead_per_task_s`` = (batch wall x W - sum of the tasks' own run_capture seconds) / N: the
  slot time each task costs beyond its work (cluster start and stop, worker start and imports,
  scheduling, idle slots at the tail);
- ``ray_start_stop_s``: starting and stopping the local cluster alone;
- ``contention`` = mean task seconds inside batch / mean `furrow model` seconds: how much slower a
  capture runs when W of them share the machine.

Timings on a shared machine are noisy: the median over --repeat runs is reported.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path
from statistics import median

from furrow.bench import OUT_ROOT
from furrow.bench._common import print_result


def _furrow(*args: str) -> float:
    """Run ``furrow ARGS`` in a fresh process; its wall time in seconds (error if it fails)."""
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-m", "furrow", *args], capture_output=True, text=True)
    dt = time.perf_counter() - t0
    if p.returncode not in (0,):
        raise SystemExit(f"furrow {' '.join(args)} failed ({p.returncode}): {p.stderr.strip()[-500:]}")
    return dt


def captures(n: int, data: Path) -> list[Path]:
    out = []
    for i in range(n):
        c = data / f"torus_{i}"
        if not (c / "transforms.json").is_file():
            _furrow("synth", "torus", "-o", str(c), "--small", "--seed", str(i), "--overwrite")
        out.append(c)
    return out


def ray_start_stop(workers: int) -> float:
    """Seconds to start and stop a local Ray cluster (furrow.batch.start_ray), in a fresh process."""
    code = ("import time, ray; from furrow.batch import start_ray; t = time.perf_counter(); "
            f"start_ray(None, {workers}); ray.shutdown(); print(time.perf_counter() - t)")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return float(p.stdout.strip().splitlines()[-1])


def one_round(caps: list[Path], out: Path, workers: int, max_res: int) -> dict:
    seq = [_furrow("model", str(c), "-o", str(out / "seq" / c.name), "--max-res", str(max_res), "--overwrite")
           for c in caps]
    bdir = out / "batch"
    if bdir.exists():
        import shutil

        shutil.rmtree(bdir)
    t_batch = _furrow("batch", *map(str, caps), "-o", str(bdir), "--steps", "model", "--max-res", str(max_res),
                      "--workers", str(workers))
    recs = json.loads((bdir / "batch.json").read_text())["captures"]
    task = [recs[c.name]["seconds"] for c in caps]
    return {"sequential_s": sum(seq), "batch_s": t_batch, "model_s": seq, "task_s": task,
            "speedup": sum(seq) / t_batch,
            "overhead_per_task_s": (t_batch * workers - sum(task)) / len(caps),
            "contention": (sum(task) / len(task)) / (sum(seq) / len(seq))}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="furrow bench batch", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--captures", type=int, default=4, help="number of small captures N (default 4)")
    ap.add_argument("--workers", type=int, default=2, help="Ray workers W (default 2)")
    ap.add_argument("--max-res", type=int, default=64, help="model L_max on both sides (default 64)")
    ap.add_argument("--repeat", type=int, default=1, help="rounds; medians are reported (default 1)")
    ap.add_argument("-o", "--out", type=Path, default=OUT_ROOT / "bench" / "batch")
    ap.add_argument("--json", action="store_true", help="print the result as JSON on stdout")
    args = ap.parse_args(argv)
    caps = captures(args.captures, args.out / "data")
    rounds = [one_round(caps, args.out, args.workers, args.max_res) for _ in range(args.repeat)]
    keys = ("sequential_s", "batch_s", "speedup", "overhead_per_task_s", "contention")
    res = {"captures": args.captures, "workers": args.workers, "max_res": args.max_res, "repeat": args.repeat,
           **{k: median(r[k] for r in rounds) for k in keys}, "ray_start_stop_s": ray_start_stop(args.workers),
           "rounds": rounds}

    def tables(r):
        print(f"{r['captures']} captures (torus --small), model step at max-res {r['max_res']}, "
              f"median of {r['repeat']} round(s)")
        print(f"  sequential `furrow model` x {r['captures']}: {r['sequential_s']:8.1f} s")
        print(f"  `furrow batch --workers {r['workers']}`:      {r['batch_s']:8.1f} s")
        print(f"  speed-up {r['speedup']:.2f} x (ideal {r['workers']}), overhead per task "
              f"{r['overhead_per_task_s']:.1f} s, Ray start + stop {r['ray_start_stop_s']:.1f} s, "
              f"contention {r['contention']:.2f} x")

    return print_result(res, args.json, tables)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

"""``furrow batch CAPTURES... -o OUT``: many captures, one Ray task each (furrow.batch)."""

from __future__ import annotations

import argparse
from pathlib import Path

HELP = "run many captures (model, held-out eval, orbit video) as Ray tasks, locally or on a cluster"
DESCRIPTION = """Each capture (a folder holding a transforms.json, a plain folder or a COLMAP folder) is one task on
Ray: a local cluster on this machine by default (--workers CPUs), an existing cluster with --address.
Per capture OUT/NAME/ gets model/ (as `furrow model`, with the same model flags: --max-res, --matte,
--no-photometric, ...), eval.json (as `furrow eval`, the same model), orbit.mp4 (as
`furrow render --orbit --video`) and done.json, each written atomically; a capture that fails
(corrupt depth, flagged registration, out of memory) is reported by name with its one-line reason
and the others go on; a re-run skips complete captures.  OUT/batch.json holds every capture's
status, stage times and eval scores.  Exit status 1 when any capture failed.

Needs Ray: pip install 'furrow[cluster]'.  On a remote cluster every node needs furrow installed.

examples:
  furrow batch scans/* -o out/batch
  furrow batch scans/plant_* -o out/plants --steps model,orbit --max-res 128 --workers 2
  furrow batch scans/* -o out/batch --address ray://head-node:10001"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("captures", type=Path, nargs="+", help="capture folders (or transforms.json files)")
    p.add_argument("-o", "--out", type=Path, required=True, help="output root: OUT/NAME per capture, OUT/batch.json")
    p.add_argument("--address", default=None, metavar="ADDR",
                   help="an existing Ray cluster (e.g. ray://host:10001 or auto); default: a local cluster")
    p.add_argument("--workers", type=int, default=2, help="local cluster: CPUs, i.e. captures at once (default 2)")
    p.add_argument("--steps", default="model,eval,orbit", help="steps per capture, from model,eval,orbit (default all)")
    p.add_argument("--holdout", type=int, default=2, help="eval: keep frames i %% K == 0 (default 2)")
    p.add_argument("--orbit-frames", type=int, default=36, help="orbit video frames (default 36)")
    p.add_argument("--fps", type=float, default=24.0, help="orbit video frames per second (default 24)")
    p.add_argument("--allow-flagged", action="store_true", help="model captures whose registration.json flags scans")
    from furrow.model_flags import add_model_arguments

    add_model_arguments(p, frames=False)
    p.add_argument("--debug", action="store_true", help="show tracebacks")


STATUS_STYLE = {"queued": "dim", "done": "green", "failed": "bold red", "skipped": "cyan"}


def table(batch_state: dict, names: list[str]):
    """The progress table: one row per capture."""
    from rich.table import Table

    t = Table(title="furrow batch")
    for col, just in (("capture", "left"), ("status", "left"), ("seconds", "right"), ("stages", "left"),
                      ("PSNR", "right"), ("reason", "left")):
        t.add_column(col, justify=just, overflow="fold")
    for n in names:
        r = batch_state.get(n, {"status": "queued"})
        st = r.get("status", "queued")
        psnr = r.get("scores", {}).get("microfacet", {}).get("psnr")
        stages = " ".join(f"{k} {v:.0f}s" for k, v in r.get("stages", {}).items())
        t.add_row(n, f"[{STATUS_STYLE.get(st, '')}]{st}", f"{r['seconds']:.0f}" if "seconds" in r else "",
                  stages, f"{psnr:.2f}" if psnr is not None else "", r.get("reason", "") if st != "skipped" else "")
    return t


def run(args, console) -> int:
    from rich.live import Live

    from furrow.batch import BATCH_FILE, CaptureConfig, parse_steps, run_batch
    from furrow.model_flags import pipeline_config

    steps = parse_steps(args.steps)
    if args.workers < 1:
        raise ValueError(f"--workers must be >= 1, got {args.workers}")
    try:
        import ray  # noqa: F401
    except ModuleNotFoundError:
        raise RuntimeError("furrow batch needs Ray: pip install 'furrow[cluster]'") from None
    if args.view_workers is None:  # Ray already runs --workers captures at once: each in one process
        args.view_workers = 1
    cfg = CaptureConfig(pipeline=pipeline_config(args), holdout=args.holdout, orbit_frames=args.orbit_frames,
                        fps=args.fps, allow_flagged=args.allow_flagged)
    missing = [str(c) for c in args.captures if not c.exists()]
    if missing:
        raise ValueError(f"no such capture: {', '.join(missing)}")
    names = [c.name if c.is_dir() else c.parent.name for c in args.captures]
    state: dict = {}
    with Live(table(state, names), console=console, refresh_per_second=2, transient=False) as live:
        def on_update(rec):
            state[rec["capture"]] = rec
            live.update(table(state, names))

        batch = run_batch(args.captures, args.out, steps, cfg, address=args.address, workers=args.workers,
                          on_update=on_update)
    if not console.is_terminal:
        console.print()
    s = batch["summary"]
    for rec in batch["captures"].values():
        if rec["status"] == "failed":
            console.print(f"[bold red]failed[/] {rec['capture']}: {rec['reason']}", highlight=False)
    console.print(f"{s['done']} done, {s['skipped']} skipped, {s['failed']} failed in {batch['seconds']:.1f} s "
                  f"-> {args.out / BATCH_FILE}", highlight=False)
    return 1 if s["failed"] else 0

"""``furrow bench NAME [args]``: speed-against-error benchmarks from ``bench/NAME.py``."""

from __future__ import annotations

import argparse
import importlib.util
from pathlib import Path

HELP = "speed-against-error benchmarks (model, register, render, shading, or all)"
DESCRIPTION = """Run a benchmark from the repository's bench/ folder. Each prints its table,
saves plots under out/bench/NAME/ (or -o DIR) and accepts --json. Arguments after NAME go to
the benchmark itself: `furrow bench render --help`."""

BENCH_DIR = Path(__file__).resolve().parent.parent / "bench"


def available() -> list[str]:
    return sorted(p.stem for p in BENCH_DIR.glob("*.py") if not p.stem.startswith("_"))


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("name", help=f"benchmark to run: {', '.join(available() + ['all'])}")
    p.add_argument("rest", nargs=argparse.REMAINDER, help="arguments passed to the benchmark")


def _load(name: str):
    path = BENCH_DIR / f"{name}.py"
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such benchmark (available: {', '.join(available()) or 'none'})")
    spec = importlib.util.spec_from_file_location(f"furrow_bench_{name}", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def run(args, console) -> int:
    names = available() if args.name == "all" else [args.name]
    rc = 0
    for n in names:
        console.rule(f"bench {n}")
        rc = max(rc, int(_load(n).main(list(args.rest)) or 0))
    return rc

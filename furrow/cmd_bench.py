"""``furrow bench NAME [args]``: speed-against-error benchmarks from ``furrow.bench.NAME``."""

from __future__ import annotations

import argparse
import importlib
import pkgutil

import furrow.bench

HELP = "speed-against-error benchmarks (model, register, render, shading, or all)"
DESCRIPTION = """Run a benchmark of the furrow.bench package. Each prints its table,
saves plots under out/bench/NAME/ (or -o DIR) and accepts --json. Arguments after NAME go to
the benchmark itself: `furrow bench render --help`."""


def available() -> list[str]:
    return sorted(m.name for m in pkgutil.iter_modules(furrow.bench.__path__) if not m.name.startswith("_"))


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("name", help=f"benchmark to run: {', '.join(available() + ['all'])}")
    p.add_argument("rest", nargs=argparse.REMAINDER, help="arguments passed to the benchmark")


def _load(name: str):
    if name not in available():
        raise ValueError(f"unknown benchmark {name!r} (available: {', '.join(available()) or 'none'})")
    return importlib.import_module(f"furrow.bench.{name}")


def run(args, console) -> int:
    names = available() if args.name == "all" else [args.name]
    rc = 0
    for n in names:
        console.rule(f"bench {n}")
        rc = max(rc, int(_load(n).main(list(args.rest)) or 0))
    return rc

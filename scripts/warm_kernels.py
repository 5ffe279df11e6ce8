"""Compile furrow's numba kernels once, at set-up (``make setup`` runs this after installing the packages).

numba compiles a kernel on its first call and caches the machine code beside its module
(``__pycache__/*.nbi``, ``*.nbc``); on a fresh clone every first call pays that compile, about 50 s of CPU over
the kernels of reading, the plate, the matte, fusion and the renderers.  This script makes a tiny capture of the
kind ``make demo`` makes (a fur ball, the room behind it in half the views, a turntable disc in the depth, auto
exposure) in a temporary folder and evaluates it, which calls every kernel the demo and the tests call first,
so that neither pays the compile.  It changes nothing but the caches; run it again after changing a kernel's
types if you like (numba recompiles a changed kernel on its own at its next call).

    .venv/bin/python scripts/warm_kernels.py
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from furrow.cli import main


def run(args: list[str]) -> None:
    """``furrow ARGS``; exit with its code when it fails."""
    code = main(args)
    if code != 0:
        sys.exit(f"warm_kernels: furrow {' '.join(args)} exited {code}")


def warm() -> float:
    """Synthesise, model and evaluate a tiny room capture in a temporary folder; the seconds it took."""
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="furrow-warm-") as tmp:
        scan = os.path.join(tmp, "scan")
        run(["synth", "furball", "-o", scan, "--small", "--views", "8", "--size", "160x120", "--seed", "3",
             "--background", "env", "--support", "disc", "--background-frames", "0::2", "--auto-exposure"])
        run(["eval", scan, "--holdout", "2", "-o", os.path.join(tmp, "eval")])
        phone = os.path.join(tmp, "phone")  # the room behind every view, a table, depth at a quarter of the size
        run(["synth", "plant", "-o", phone, "--small", "--views", "8", "--size", "320x240", "--depth-size", "80x60",
             "--seed", "3", "--background", "env", "--support", "table"])
        run(["model", phone, "-o", os.path.join(tmp, "phone_model"), "--max-res", "64"])
        black = os.path.join(tmp, "black")  # over black: the backdrop matte
        run(["synth", "furball", "-o", black, "--small", "--views", "6", "--size", "160x120", "--seed", "3"])
        run(["model", black, "-o", os.path.join(tmp, "black_model"), "--max-res", "64"])
    return time.perf_counter() - start


if __name__ == "__main__":
    print(f"numba kernels compiled and cached in {warm():.0f} s", file=sys.stderr)

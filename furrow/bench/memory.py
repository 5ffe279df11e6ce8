"""``furrow bench memory``: what memory a run touches for the first time costs on this machine.

A run's large captures are bounded in memory by spilling their scans to disk (capture.scan_store), so
they write and read gigabytes, and every stage makes arrays it has not had before.  On an ordinary
Linux machine a page touched for the first time costs the kernel a page of zeros (10-16 GB/s).  On a
virtual machine that hands its freed pages back to its host (free page reporting, a balloon), a page
freed a few seconds ago must come back from the host first: the machine these benchmarks were written
on touched such memory at 0.19-0.28 GB/s, and wrote new files at 0.14-0.34 GB/s (docs/speed.md round
22).  There, every byte a run writes or first touches costs about 4 s a GB, which is why the spill
store keeps what it writes small (``capture.scan_store.SPILL_RGB_BASE``).

This prints three rates over ``--size-mb`` of memory (medians over ``--repeats``):

* **warm**: an array filled right after an array of the same size was freed (the kernel's own pages);
* **cold**: the same after a pause of ``--pause`` seconds (time for a VM to hand the pages back);
* **file**: that many bytes written to new files in a temporary folder (the page cache), then removed.

    furrow bench memory [--size-mb 512] [--pause 5] [--repeats 3] [--json]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

#: Cold over warm rate below this: the machine is taken to hand freed memory back to its host.
HANDED_BACK_RATIO = 0.25
#: Bytes written per file in the file test (a spilled 1280x960 view is 5-16 MB).
FILE_CHUNK_BYTES = 16 << 20


def touch_rate(nbytes: int) -> float:
    """GB/s of making and filling a new array of ``nbytes`` (the array freed after)."""
    t = time.perf_counter()
    a = np.ones(nbytes // 8, np.float64)
    dt = time.perf_counter() - t
    del a
    return nbytes / max(dt, 1e-9) / 1e9


def file_rate(nbytes: int, folder: Path) -> float:
    """GB/s of writing ``nbytes`` as new files of FILE_CHUNK_BYTES in ``folder`` (removed after)."""
    chunk = np.ones(max(1, min(nbytes, FILE_CHUNK_BYTES)) // 8, np.float64).tobytes()
    files, written = [], 0
    t = time.perf_counter()
    while written < nbytes:
        f = folder / f"chunk{len(files):05d}.bin"
        f.write_bytes(chunk)
        files.append(f)
        written += len(chunk)
    dt = time.perf_counter() - t
    for f in files:
        f.unlink()
    return written / max(dt, 1e-9) / 1e9


def measure(size_mb: int, pause: float, repeats: int) -> dict:
    """The three rates' medians (GB/s) and whether the cold rate says memory goes back to a host."""
    nbytes = int(size_mb) << 20
    warm, cold, file = [], [], []
    with tempfile.TemporaryDirectory(prefix="furrow-bench-memory-") as tmp:
        for _ in range(repeats):
            touch_rate(nbytes)  # these pages are the kernel's now
            warm.append(touch_rate(nbytes))
            time.sleep(pause)
            cold.append(touch_rate(nbytes))
            time.sleep(pause)
            file.append(file_rate(nbytes, Path(tmp)))
    res = {"size_mb": int(size_mb), "pause_s": float(pause), "repeats": int(repeats),
           "warm_gb_s": statistics.median(warm), "cold_gb_s": statistics.median(cold),
           "file_gb_s": statistics.median(file)}
    res["handed_back"] = res["cold_gb_s"] < HANDED_BACK_RATIO * res["warm_gb_s"]
    res["seconds_per_gb_cold"] = 1.0 / max(res["cold_gb_s"], 1e-9)
    return res


def _print(res: dict) -> None:
    from rich.table import Table

    from furrow.console import console

    t = Table(title=f"first touch of {res['size_mb']} MB (medians of {res['repeats']}; "
                    f"cold after {res['pause_s']:g} s)")
    for c in ("case", "GB/s", "s per GB"):
        t.add_column(c)
    for key, name in (("warm_gb_s", "warm: memory freed a moment before"), ("cold_gb_s", "cold: after the pause"),
                      ("file_gb_s", "new files (page cache)")):
        t.add_row(name, f"{res[key]:.2f}", f"{1.0 / max(res[key], 1e-9):.2f}")
    console.print(t)
    if res["handed_back"]:
        console.print(f"cold is under {HANDED_BACK_RATIO:g} x warm: this machine hands freed memory back to its host; "
                      f"what a run writes or first touches costs about {res['seconds_per_gb_cold']:.1f} s a GB here")
    else:
        console.print("cold is close to warm: memory touched for the first time costs the kernel's zeroing only")


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="furrow bench memory", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--size-mb", type=int, default=512, help="memory touched and bytes written per case")
    p.add_argument("--pause", type=float, default=5.0, help="seconds before the cold touch (and the file test)")
    p.add_argument("--repeats", type=int, default=3, help="runs of each case (the median is printed)")
    p.add_argument("--json", action="store_true", help="print the results as JSON on stdout")
    a = p.parse_args(argv)
    if a.size_mb <= 0 or a.repeats <= 0 or a.pause < 0:
        p.error("--size-mb and --repeats must be positive, --pause at least 0")
    from furrow.bench._common import print_result

    return print_result(measure(a.size_mb, a.pause, a.repeats), a.json, _print)

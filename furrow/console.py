"""The one rich console of the CLI, progress bars and the per-stage timing table."""

from __future__ import annotations

import contextlib
import sys
import time
from collections.abc import Iterable, Iterator
from typing import TypeVar

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn
from rich.table import Table

from volume.pipeline.pool import peak_rss_mb, reset_peak_rss

#: Width used when stderr is not a terminal (logs, CI): wide enough for the result tables.
LOG_WIDTH = 140
console = Console(stderr=True, width=None if sys.stderr.isatty() else LOG_WIDTH)
T = TypeVar("T")


def _library_log() -> None:
    """Messages the libraries log on logger ``furrow`` (e.g. depth resampled to the colour camera) go to the console."""
    import logging

    from rich.logging import RichHandler

    log = logging.getLogger("furrow")
    if not any(isinstance(h, RichHandler) for h in log.handlers):
        log.addHandler(RichHandler(console=console, show_time=False, show_path=False, markup=False))
        log.setLevel(logging.INFO)


_library_log()


def fail(msg: str) -> None:
    """Print a one-line error."""
    console.print(f"[bold red]error:[/] {msg}", highlight=False, soft_wrap=True)


def track(items: Iterable[T], description: str, total: int | None = None) -> Iterator[T]:
    """Iterate with a progress bar on the CLI console."""
    with Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                  TimeRemainingColumn(), console=console, transient=False,
                  disable=not console.is_terminal) as prog:
        yield from prog.track(items, total=total, description=description)


class StageTimer:
    """Times named stages: wall seconds, process CPU seconds (all threads) and peak resident
    memory (MiB) reached inside the stage; ``table()`` renders the closing per-stage table."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}
        self.cpu_seconds: dict[str, float] = {}
        self.peak_mb: dict[str, float] = {}

    @contextlib.contextmanager
    def stage(self, name: str, quiet: bool = False):
        """Time the body as row ``name`` (added to the row's earlier times; ``quiet``: no "> name"
        line, for a row entered once per view)."""
        reset_peak_rss()
        t0 = time.perf_counter()
        c0 = time.process_time()
        if not quiet:
            console.print(f"[cyan]>[/] {name} ...", highlight=False)
        try:
            yield
        finally:
            self.seconds[name] = self.seconds.get(name, 0.0) + time.perf_counter() - t0
            self.cpu_seconds[name] = self.cpu_seconds.get(name, 0.0) + time.process_time() - c0
            self.peak_mb[name] = max(self.peak_mb.get(name, 0.0), peak_rss_mb())

    def add(self, name: str, seconds: float, cpu_seconds: float, peak_mb: float = 0.0) -> None:
        """Add time measured elsewhere to row ``name`` (per-view stages in worker processes)."""
        self.seconds[name] = self.seconds.get(name, 0.0) + seconds
        self.cpu_seconds[name] = self.cpu_seconds.get(name, 0.0) + cpu_seconds
        self.peak_mb[name] = max(self.peak_mb.get(name, 0.0), peak_mb)

    def table(self, title: str = "stage timings") -> Table:
        t = Table(title=title)
        t.add_column("stage")
        t.add_column("seconds", justify="right")
        t.add_column("cpu s", justify="right")
        t.add_column("peak MiB", justify="right")
        for k, v in self.seconds.items():
            t.add_row(k, f"{v:.2f}", f"{self.cpu_seconds.get(k, 0.0):.2f}", f"{self.peak_mb.get(k, 0.0):.0f}")
        t.add_row("[bold]total", f"[bold]{sum(self.seconds.values()):.2f}",
                  f"[bold]{sum(self.cpu_seconds.values()):.2f}",
                  f"[bold]{max(self.peak_mb.values(), default=0.0):.0f}")
        return t

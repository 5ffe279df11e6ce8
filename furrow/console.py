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
    console.print(f"[bold red]error:[/] {msg}", highlight=False)


def track(items: Iterable[T], description: str, total: int | None = None) -> Iterator[T]:
    """Iterate with a progress bar on the CLI console."""
    with Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                  TimeRemainingColumn(), console=console, transient=False,
                  disable=not console.is_terminal) as prog:
        yield from prog.track(items, total=total, description=description)


class StageTimer:
    """Times named stages; ``table()`` renders the closing per-stage timing table."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}

    @contextlib.contextmanager
    def stage(self, name: str):
        t0 = time.perf_counter()
        console.print(f"[cyan]>[/] {name} ...", highlight=False)
        try:
            yield
        finally:
            self.seconds[name] = self.seconds.get(name, 0.0) + time.perf_counter() - t0

    def table(self, title: str = "stage timings") -> Table:
        t = Table(title=title)
        t.add_column("stage")
        t.add_column("seconds", justify="right")
        for k, v in self.seconds.items():
            t.add_row(k, f"{v:.2f}")
        t.add_row("[bold]total", f"[bold]{sum(self.seconds.values()):.2f}")
        return t

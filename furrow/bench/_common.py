"""Helpers shared by the benchmarks: writing a figure, printing a result (``furrow bench``
skips this module: its name starts with an underscore)."""

from __future__ import annotations

import json
from pathlib import Path

from capture.atomic import atomic_write


def save_figure(fig, path: Path, dpi: int = 100) -> Path:
    """Lay out ``fig``, write it to ``path`` (atomically, parent folder made), close it; ``path``."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    with atomic_write(path) as tmp:
        fig.savefig(tmp, dpi=dpi)
    plt.close(fig)
    return Path(path)


def print_result(res: dict, as_json: bool, print_tables, *lines: str) -> int:
    """``res`` as JSON on stdout, or its tables (``print_tables(res)``) and ``lines``; exit status 0."""
    if as_json:
        print(json.dumps(res, indent=1, default=float))
    else:
        print_tables(res)
        for line in lines:
            print(line)
    return 0

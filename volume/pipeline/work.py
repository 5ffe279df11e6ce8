"""What passes between the pipeline's stages (:class:`Work`), what the runner hands each stage
(:class:`Context`) and what a command hands the runner (:class:`Hooks`)."""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from capture.scan import ScanSet
from capture.sources import FrameRef, Source


@dataclass(frozen=True)
class Work:
    """What the pipeline has made so far; each stage returns a new one (``dataclasses.replace``).

    Attributes:
        source: the capture (frames picked by the read stage's ``frames``).
        refs: the views, in capture order (after view selection: the kept ones).
        scans: the views' scans (capture.scan.Scan, or capture.scan_store.SpilledScan on disk),
            aligned with ``refs``; None until the views are read.
        bounds: (2, 3) float64 object bounds (metres), None until the views are read.
        metadata: the scan set's metadata (source, format, what reading did).
        records: stage name -> what the stage reports (JSON values; the model report).
        parts: what the volume stages made, by name (fused levels, pyramid, spheres, mesh, RGBz, model).
    """

    source: Source
    refs: tuple[FrameRef, ...]
    scans: tuple | None = None
    bounds: np.ndarray | None = None
    metadata: dict = field(default_factory=dict)
    records: dict = field(default_factory=dict)
    parts: dict = field(default_factory=dict)

    @property
    def scanset(self) -> ScanSet:
        """The views as a ScanSet (they must have been read)."""
        if self.scans is None:
            raise RuntimeError("the views have not been read yet (a stage that needs scans runs after reading)")
        return ScanSet(self.scans, self.bounds, self.metadata)

    def with_scanset(self, ss: ScanSet) -> Work:
        """This work with the scans, bounds and metadata of ``ss``."""
        return replace(self, scans=tuple(ss.scans), bounds=ss.bounds, metadata=ss.metadata)

    def record(self, name: str, rec) -> Work:
        """This work with ``rec`` as stage ``name``'s record."""
        return replace(self, records={**self.records, name: rec})

    def made(self, **parts) -> Work:
        """This work with ``parts`` added (name -> what a stage made)."""
        return replace(self, parts={**self.parts, **parts})


def null_row(name: str):
    """A stage-table row that times nothing (library use, tests)."""
    return contextlib.nullcontext()


@dataclass(frozen=True)
class Hooks:
    """What a command gives the runner: its stage table and its progress bars (furrow/console.py)."""

    row: Callable[[str], contextlib.AbstractContextManager] = null_row
    """A timed row of the stage table, entered once (``StageTimer.stage``)."""
    view_row: Callable[[str], contextlib.AbstractContextManager] | None = None
    """A row entered once per view and summed (``StageTimer.stage(name, quiet=True)``); None = ``row``."""
    progress: Callable[[Iterable, str], Iterable] | None = None
    """``progress(items, description)``: a progress bar over a loop (``furrow.console.track``)."""
    add: Callable[[str, float, float, float], None] | None = None
    """``add(row, seconds, cpu_seconds, peak_mb)``: time measured elsewhere added to a row (per-view
    stages run in worker processes, volume/pipeline/runner.py; ``StageTimer.add``); None = one row
    for the pooled per-view stages together."""


@dataclass(frozen=True)
class Context:
    """What the runner hands a whole-set stage besides its own config.

    Attributes:
        config: the whole PipelineConfig (for what a later stage will need: the fuse stage
            completes the levels the mesh and the spheres read).
        keep: each new scan a stage makes goes through it (capture.scan_store: memory or disk).
        row: a timed row of the stage table, for a stage that names its own rows (``rows=True``).
        progress: ``progress(items, description)`` or None.
        work_dir: the spill folder (RGBz crops are streamed there), or None.
        map_views: ``map_views(step, views, arg, description) -> (scans, notes)``: a per-view step
            ``step(view, ref, arg) -> (view, note)`` (a top-level function: it may run in a worker
            process) over every view of ``views`` (a Work, or a sequence of scans whose ref is their
            position), each changed view kept (None: unchanged); the runner's own per-view loop (one
            place to run views in parallel, ``--view-workers``).
    """

    config: object
    keep: Callable
    row: Callable[[str], contextlib.AbstractContextManager] = null_row
    progress: Callable | None = None
    work_dir: Path | None = None
    map_views: Callable | None = None

    def track(self, items, description: str):
        """``items`` with a progress bar when the command has them."""
        return self.progress(items, description) if self.progress else items

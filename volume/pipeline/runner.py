"""The pipeline's runner: the stages of volume/pipeline/stages.py in order, and what no stage does
itself -- where the views wait (capture/scan_store.py), the progress bars and the stage table
(through the command's :class:`~volume.pipeline.work.Hooks`).

Per-view stages are queued and run when a whole-set stage needs the views (or at the end): each
view goes through every queued stage before the next view is read, and the result is kept in
memory or on disk.  A cameras stage (view selection) works on the cameras the source gives before
any image, so the views it drops are never read.  Reading makes the scan set: the capture's bounds
or the robust box of the depth, and the metadata of what reading did (capture/sources.finish_scanset).

``workers > 1`` maps the per-view stages, and the per-view passes of whole-set stages
(``ctx.map_views``: extent, photometric, RGBz), over one pool of processes for the run
(volume/pipeline/pool.py).  At most 2 x workers views are in flight; a spilled view goes to a
worker as its file name and comes back as one (the worker reads and writes the spill folder), a
view in memory goes and comes back pickled, and the results are kept in view order, so the model
is the same as with one process.  The per-view stages' rows of the stage table are made from the
workers' own times: each stage's share of their summed wall time, of the pool's wall time.  A
row's peak memory counts the workers too: the main process's peak plus each worker's peak in the
row's views (an upper bound), for the per-view stages and for the whole-set stages' passes in
the pool (extent, matte, photometric, RGBz).
"""

from __future__ import annotations

import time
from contextlib import contextmanager, nullcontext
from dataclasses import replace
from functools import partial
from pathlib import Path

from capture.scan import ScanSet, select_indices
from capture.scan_store import spill_for
from capture.sources import FrameRef, Source, finish_scanset
from capture.view_map import arg_of
from volume.pipeline.config import PipelineConfig
from volume.pipeline.stages import CAMERAS, SET, STAGES, VIEW
from volume.pipeline.work import Context, Hooks, Work


def _start(source, cfg: PipelineConfig) -> Work:
    """The first Work: a Source's frames picked by ``cfg.read.frames``, or a ScanSet's scans in memory."""
    if isinstance(source, ScanSet):
        refs = tuple(FrameRef(i, s.name, s.camera, s.camera, None, None, None) for i, s in enumerate(source.scans))
        src = Source(Path(source.metadata.get("source", "<scans in memory>")), "memory", refs, source.bounds,
                     dict(source.metadata))
        work = Work(src, refs, tuple(source.scans), source.bounds, dict(source.metadata))
        if cfg.read.frames:
            idx = select_indices(cfg.read.frames, len(refs))
            work = replace(work, refs=tuple(refs[i] for i in idx), scans=tuple(source.scans[i] for i in idx))
        return work
    src = source.select(cfg.read.frames)
    return Work(src, src.frames)


def _view_items(views):
    """(what the first per-view step gets, the refs): a Work's views (nothing before reading: the
    step reads the frame) and FrameRefs, or a sequence of scans and their positions."""
    if isinstance(views, Work):
        return ([None] * len(views.refs) if views.scans is None else list(views.scans)), list(views.refs)
    return list(views), list(range(len(views)))


def _steps_of(steps, k: int):
    """``steps`` with each argument as view ``k`` gets it (capture.view_map.PerView)."""
    return [(st, fn, arg_of(cfg, k), row) for st, fn, cfg, row in steps]


def _apply(steps, view, ref):
    """``view`` through ``steps`` [(stage, fn, cfg, row)]: (the view, the notes); a step that gives
    None for the view left it unchanged."""
    notes = []
    for _, fn, cfg, row in steps:
        with row():
            out, note = fn(view, ref, cfg)
        view = view if out is None else out
        notes.append(note)
    return view, notes


class Run:
    """One run of the pipeline: its :class:`Work` and the spill folder its views and RGBz crops wait
    in (owned: :meth:`close`, or leave ``with``).  :func:`run_pipeline` makes it."""

    def __init__(self, work: Work, cfg: PipelineConfig, hooks: Hooks):
        self.work, self.cfg, self.hooks = work, cfg, hooks
        self.spill, self._spill_decided = None, False
        self._pool = None
        self._set_peaks = None  # in a whole-set stage: its workers' peak MiB by process id
        self._set_cpu = 0.0  # ... and their CPU seconds in it
        from volume.pipeline.pool import keep_freed_memory, workers_for

        self.workers = workers_for(cfg.workers, work.refs, cfg.matte.mode)
        keep_freed_memory()  # this process's heap too (the plate stage's threads, fusion)

    # ------------------------------------------------------------------ what the stages made
    @property
    def model(self):
        return self.work.parts.get("model")

    def summary(self) -> dict:
        """The ``furrow model --json`` summary keys (volume/pipeline/report.summary) and where the views waited."""
        from volume.pipeline.report import summary

        return {**summary(self.work), "spill": "disk" if self.spill is not None else "memory"}

    # ------------------------------------------------------------------ resources
    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
        if self.spill is not None:
            self.spill.close()

    def __enter__(self) -> Run:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _decide_spill(self) -> None:
        """The spill folder, chosen once by the pixels of the views (after view selection, ``cfg.spill``)."""
        if not self._spill_decided:
            self._spill_decided = True
            self.spill = spill_for(sum(r.camera.width * r.camera.height for r in self.work.refs), self.cfg.spill)

    def keep(self, scan):
        """Where a stage's new scan waits: the spill folder once the views are many (``cfg.spill``)."""
        self._decide_spill()
        return self.spill.keep(scan) if self.spill is not None else scan

    def context(self) -> Context:
        self._decide_spill()
        return Context(self.cfg, self.keep, self.row, self.hooks.progress,
                       self.spill.path if self.spill is not None else None, self.map_views)

    # ------------------------------------------------------------------ running
    def run(self, stages=STAGES) -> Run:
        from volume.pipeline.pool import main_blas_threads

        with main_blas_threads():  # the stages' own threads and workers are the parallelism
            try:
                return self._run(stages)
            except ValueError as e:  # ModelError too: a later stage's error, where the depth said why first
                raise _with_agreement(e, self.work) from None

    def _run(self, stages) -> Run:
        pending = []
        for st in stages:
            cfg = getattr(self.cfg, st.key)
            if not st.on(cfg):
                continue
            if st.kind == VIEW:
                pending.append(st)
                continue
            if st.kind == SET and pending:
                self.views(pending)
                pending = []
            if st.kind == CAMERAS:
                self.select(st, cfg)
            else:
                self.whole(st, cfg)
        if pending:
            self.views(pending)
        return self

    def select(self, st, cfg) -> None:
        """A cameras stage: the kept views (and their scans, when read)."""
        with self.hooks.row(st.row_name(self.cfg)):
            kept, rec = st.fn(self.work.refs, cfg)
        w = self.work
        scans = None if w.scans is None else tuple(w.scans[k] for k in kept)
        self.work = replace(w, refs=tuple(w.refs[k] for k in kept), scans=scans).record(st.name, rec)

    def whole(self, st, cfg) -> None:
        """A whole-set stage, in its row (or its own rows), each row through :meth:`row`."""
        ctx = self.context()
        if st.rows:
            self.work = st.fn(self.work, cfg, ctx)
            return
        with self.row(st.row_name(self.cfg)):
            self.work = st.fn(self.work, cfg, ctx)

    @contextmanager
    def row(self, name: str):
        """A whole-set stage's row of the stage table (the command's ``hooks.row``); its peak memory
        is the main process's plus, when its per-view passes ran in the pool, each worker's peak in
        them (an upper bound, as for the per-view stages: :meth:`_rows`), and its CPU seconds the
        main process's plus the workers' in those passes (the row's own: not added to an outer row's)."""
        from volume.pipeline.pool import peak_rss_mb, release_free_memory

        release_free_memory()  # what earlier stages freed is not this row's
        outer, self._set_peaks = self._set_peaks, {}
        outer_cpu, self._set_cpu = self._set_cpu, 0.0
        try:
            with self.hooks.row(name):
                yield
            peak_main = peak_rss_mb()  # the row's own: the stage table reset the mark at its start
        finally:
            peaks, self._set_peaks = self._set_peaks, outer
            cpu, self._set_cpu = self._set_cpu, outer_cpu
            if outer is not None:
                for pid, mb in peaks.items():
                    outer[pid] = max(outer.get(pid, 0.0), mb)
        if (peaks or cpu) and self.hooks.add is not None:
            self.hooks.add(name, 0.0, cpu, peak_main + sum(peaks.values()))

    def views(self, pending) -> None:
        """Queued per-view stages, view by view (module docstring); reading ends in the scan set."""
        w = self.work
        from_files = w.scans is None
        todo = [st for st in pending if from_files or not st.reads_frame]
        if not todo:
            return
        view_row = self.hooks.view_row or self.hooks.row
        steps = [(st, st.fn, getattr(self.cfg, st.key), partial(view_row, st.row_name(self.cfg))) for st in todo]
        for st, _, cfg, _ in steps:
            if st.before is not None:
                with self.hooks.row(f"{st.name} warm-up"):
                    st.before(cfg)
        desc = f"reading {len(w.refs)} views" if from_files else ", ".join(st.name for st in todo)
        if self._pooled(len(w.refs)) and self.hooks.add is None:  # no rows from the workers' times: one row
            with self.hooks.row(f"{', '.join(st.name for st in todo)} ({self.workers} processes)"):
                scans, notes = self._map(steps, w, desc)
        else:
            scans, notes = self._map(steps, w, desc)
        w = replace(w, scans=scans)
        by_stage = {st.name: [n[k] for n in notes] for k, st in enumerate(todo)}
        if from_files:
            with self.hooks.row("bounds"):  # the robust box of every view's depth when the capture has none
                ss = finish_scanset(w.source, scans, by_stage, self._sampler(len(scans)))
            w = replace(w, bounds=ss.bounds, metadata=ss.metadata)
        for st, _, cfg, _ in steps:
            if st.reduce is not None:
                w = st.reduce(w, by_stage, cfg)
        self.work = w

    def map_views(self, fn, views, arg, description: str):
        """``fn(view, ref, arg) -> (view, note)`` over ``views`` (a Work, or a sequence of scans whose
        ref is their position), each changed view kept (None: unchanged); (views, notes)
        (Context.map_views)."""
        scans, notes = self._map([(None, fn, arg, nullcontext)], views, description)
        return scans, [n[0] for n in notes]

    def _sampler(self, n_views: int):
        """The bounds' depth points sampled in the pool (capture.extent.mapped_sampled_points: the same
        points as in this process, the views read side by side), or None without a pool."""
        if not self._pooled(n_views):
            return None
        from capture.extent import mapped_sampled_points

        return partial(mapped_sampled_points, self.map_views)

    def _pooled(self, n_views: int) -> bool:
        return self.workers > 1 and n_views > 1

    def _map(self, steps, views, description: str):
        """(kept views, per-view notes): every view through ``steps``, in this process or the pool."""
        items, refs = _view_items(views)
        self._decide_spill()
        out, notes = [], []
        hooks_track = self.hooks.progress or (lambda it, d: it)
        if self._pooled(len(items)):
            results = self._pool_map(steps, items, refs)
        else:
            results = (_apply(_steps_of(steps, k), v, ref) for k, (v, ref) in enumerate(zip(items, refs, strict=True)))
        for k, (view, n) in enumerate(hooks_track(results, description)):
            out.append(self.keep(items[k] if view is None else view))
            notes.append(n)
        return tuple(out), notes

    def _pool_map(self, steps, items, refs):
        """The views through ``steps`` in the pool, yielded in view order; at most 2 x workers views
        in flight (module docstring); the stage table gets the per-view stages' rows (:meth:`_rows`)."""
        from volume.pipeline.pool import apply_steps, peak_rss_mb, reset_peak_rss, start_pool

        if self._pool is None:
            self._pool = start_pool(self.workers)
        rows = steps[0][0] is not None and self.hooks.add is not None
        times, peaks = [[0.0, 0.0] for _ in steps], {}
        if rows:  # a whole-set stage's own row keeps its peak
            reset_peak_rss()
        t0, c0 = time.perf_counter(), time.process_time()
        queue, k = [], 0
        while k < len(items) or queue:
            while k < len(items) and len(queue) < 2 * self.workers:
                out_file = self.spill.reserve() if self.spill is not None else None
                plain = [(fn, cfg) for _, fn, cfg, _ in _steps_of(steps, k)]
                queue.append(self._pool.submit(apply_steps, plain, items[k], refs[k], out_file))
                k += 1
            view, notes, step_times, (pid, peak) = queue.pop(0).result()
            for acc, (wall, cpu) in zip(times, step_times, strict=True):
                acc[0] += wall
                acc[1] += cpu
            peaks[pid] = max(peaks.get(pid, 0.0), peak)
            if self._set_peaks is not None:
                self._set_peaks[pid] = max(self._set_peaks.get(pid, 0.0), peak)
                if not rows:  # a whole-set stage's passes: their CPU joins its row (:meth:`row`)
                    self._set_cpu += sum(cpu for _, cpu in step_times)
            yield view, notes
        if rows:
            self._rows(steps, times, time.perf_counter() - t0, time.process_time() - c0,
                       peak_rss_mb() + sum(peaks.values()))

    def _rows(self, steps, times, wall: float, cpu_main: float, peak_mb: float) -> None:
        """The per-view stages' rows from the workers' times (module docstring): each stage's share
        of their summed wall time, of the pool's ``wall``; CPU: the workers' own plus that share of
        the main process's; peak: the main process's plus each worker's (an upper bound)."""
        total = sum(t[0] for t in times) or 1.0
        for (st, _, _, _), (w, c) in zip(steps, times, strict=True):
            share = w / total
            self.hooks.add(st.row_name(self.cfg), wall * share, c + cpu_main * share, peak_mb)


def run_pipeline(source: Source | ScanSet, cfg: PipelineConfig | None = None, hooks: Hooks | None = None,
                 stages=STAGES) -> Run:
    """Run ``stages`` (default: the whole pipeline) on a capture (a capture.sources.Source) or on
    scans already in memory (a ScanSet: the reading stages are skipped).  Returns the :class:`Run`,
    which holds the spill folder until it is closed (the model's RGBz crops may be read from it)."""
    cfg = cfg or PipelineConfig()
    run = Run(_start(source, cfg), cfg, hooks or Hooks())
    try:
        return run.run(stages)
    except BaseException:
        run.close()
        raise


def read_views(source: Source, refs, cfg: PipelineConfig | None = None, progress=None) -> list:
    """The frames ``refs`` of ``source`` read by the pipeline's reading stages only (the held-out
    references of ``furrow eval``), as Scans in memory."""
    from capture.sources import read_frame

    cfg = cfg or PipelineConfig()
    reading = [st for st in STAGES if st.reads_frame]
    configs = tuple(getattr(cfg, st.key) for st in reading)
    items = progress(refs, "reading references") if progress else refs
    return [read_frame(ref, configs)[0] for ref in items]


def _with_agreement(e: ValueError, work) -> ValueError:
    """``e`` with the depth-agreement stage's warning appended ("before that, ..."), where its verdict was one of
    FAILED_AGREEMENT and the message does not hold it yet: a capture whose poses were written in another
    convention fails in a later stage (the extent stage's up direction) with a message about that stage only."""
    from volume.agreement import FAILED_AGREEMENT

    rec = (getattr(work, "records", None) or {}).get("depth agreement") or {}
    said = e.args[0] if e.args and isinstance(e.args[0], str) else None
    if rec.get("status") in FAILED_AGREEMENT and said is not None and "before that" not in said:
        e.args = (f"{e.args[0]}; before that, {rec['message']}", *e.args[1:])
    return e

"""The runner's worker processes (``--view-workers N``): one pool per run, started on first use.

Kept light on purpose: a spawned worker imports this module first (for :func:`init_worker`), so
the thread caps are in its environment before numpy, OpenCV or numba are imported there.  Each of
N workers gets ``cores // N`` threads (numba, OpenMP / BLAS, OpenCV), so that N workers on a
machine of N cores do not fight over them.

The default (``--view-workers`` not given: ``PipelineConfig.workers`` = ``AUTO_WORKERS``) starts a pool
only where it pays (:func:`pool_pays`): starting the spawned workers and sending each view to
them cost about 6 s on this 2-core machine, more than an 18-view 640x480 capture with its mattes
given spends per view (16 s with two workers against 9-10 s in one process, docs/speed.md).  A
view's work is counted in pixels, a matte that is solved (not given, not off) as
``SOLVED_MATTE_WORK`` times its pixels; the pool starts when a view's work reaches
``POOL_MIN_VIEW_WORK``.  An explicit ``--view-workers N`` always gets N.

A task is :func:`apply_steps`: one view through a list of per-view steps ``fn(view, ref, cfg) ->
(view, note)``.  What it hands back is small when it can be: a view no step changed comes back as
None (the runner keeps the one it has), and a changed view is written to the spill folder in the
worker (``out_file``, capture.scan_store.write_scan) and comes back as its file name.  The time
of each step (wall and CPU seconds) and the worker's peak resident memory in the task come back
too, for the stage table.
"""

from __future__ import annotations

import functools
import os
import time

#: ``PipelineConfig.workers`` value meaning "the machine's cores where a pool pays" (:func:`pool_pays`).
AUTO_WORKERS = 0
#: A view's work (pixels; a solved matte's pixels count SOLVED_MATTE_WORK times) from which the
#: default starts a pool: 640x480 views with their mattes given (0.31 M) stay in one process, the same
#: views with a matte solved (1.2 M) or any 1280x960 view (1.2 M) go to the pool.
POOL_MIN_VIEW_WORK = 1_000_000
#: A matte solved per view (closed form, known background) costs this many times a given matte's
#: per-view work in pixels (measured on the 640x480 conifer: the matte stage 14-26 s for 18 views
#: solved against 0.04 s a view given; the pool won 1.3-1.5x there).
SOLVED_MATTE_WORK = 4.0
#: The C heap keeps what numpy frees for the next arrays (:func:`keep_freed_memory`) in the workers and
#: the main process of a run: glibc's defaults hand every array over 128 kB-32 MB back to the system when
#: it is freed and fault it in again, zeroed, when the next one is made.  72 views at 1280x960 (docs/speed.md,
#: round 13): the matte's workers 834,000 page faults and 8.4 s of system time without it, 97,000 and 1.5 s
#: with it; the whole run 1.64 M page faults and 21.8 s system time, 0.77 M and 13.7 s (with round 13's
#: smaller spill writes); peak +6-9 % (the plate stage).  False: glibc's defaults (the reference; the
#: same models bit for bit).
HEAP_KEEPS_FREED = True
#: glibc's ``M_MMAP_THRESHOLD`` under HEAP_KEEPS_FREED: arrays below this come from the heap, not from
#: their own mapping (a 1920x1440 float32 colour image is 32 MB; a 256^3 float32 volume 64 MB).
HEAP_MMAP_THRESHOLD = 512 << 20
#: glibc's ``M_TRIM_THRESHOLD``: free memory at the heap's top kept up to this much (the stages' own
#: :func:`release_free_memory` still hands it all back between stages).
HEAP_TRIM_THRESHOLD = 1 << 30
#: glibc's ``M_TOP_PAD``: the heap grows by this much more than an allocation asks.
HEAP_TOP_PAD = 64 << 20
#: mallopt's parameter numbers (glibc malloc.h).
_M_TRIM_THRESHOLD, _M_TOP_PAD, _M_MMAP_THRESHOLD = -1, -2, -3
#: BLAS threads of the main process while a run's stages run (:func:`main_blas_threads`; None: the
#: library's own, the reference).  The stages parallelise themselves (the plate's and the fusion's
#: threads, the workers); OpenBLAS's threads beside them spun on the 2 cores here: its thread server
#: took 3.6 % of a 72-view 1280x960 run's CPU samples (perf), most of it in the plate stage, whose
#: threads' camera transforms (``rays @ R.T`` on a million rays) each woke it.  With one, A B B A twice:
#: plate stage 7.26-8.31 -> 5.93-6.01 s, the run 46.2 -> 44.2 s (medians); the same model (305 arrays,
#: 0 differ; docs/speed.md round 20).
MAIN_BLAS_THREADS: int | None = 1
#: Environment variables that set the threads of numba, OpenMP / BLAS libraries in a worker.
THREAD_VARIABLES = ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def cores() -> int:
    """CPU cores this process may run on (the default number of workers; capture.plate_threads.cores)."""
    from capture.plate_threads import cores as _cores

    return _cores()


def reset_peak_rss() -> bool:
    """Reset the kernel's resident-set high-water mark of this process (Linux ``clear_refs`` 5);
    False where that is not possible (then :func:`peak_rss_mb` is the peak since the start)."""
    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")
        return True
    except OSError:
        return False


def peak_rss_mb() -> float:
    """Peak resident memory (MiB) of this process since the start or the last :func:`reset_peak_rss`."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def release_free_memory() -> bool:
    """Hand the C heap's free pages back to the system (glibc ``malloc_trim``); False where there is
    none.  numpy's arrays of a few MB come from the heap once glibc's mmap threshold has grown
    past them, so after a stage that made and freed many (the plate stage's views and plates) the
    process kept them as its own: in the 60-view phone capture the main process entered the matte
    stage at 2012 MiB without it and at 486 MiB with it (docs/speed.md).  Also after the fusion's
    threads (volume.build: +200-350 MiB of peak without it)."""
    libc = _libc()
    try:
        return bool(libc.malloc_trim(0)) if libc is not None else False
    except AttributeError:
        return False


@functools.lru_cache(maxsize=1)
def _libc():
    """The C library (ctypes), looked up once (find_library runs ldconfig), or None."""
    import ctypes
    import ctypes.util

    try:
        return ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
    except OSError:
        return None


def main_blas_threads():
    """A context in which this process's BLAS runs MAIN_BLAS_THREADS threads (threadpoolctl); the
    threads it had come back on leaving.  A null context for None or without threadpoolctl."""
    import contextlib

    if MAIN_BLAS_THREADS is None:
        return contextlib.nullcontext()
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # a speed matter only
        return contextlib.nullcontext()
    return threadpool_limits(limits=MAIN_BLAS_THREADS, user_api="blas")


def pool_pays(pixels_per_view: float, matte_solved: bool) -> bool:
    """Whether the default starts a pool for views of ``pixels_per_view`` (mean) whose matte is
    solved or not (module docstring)."""
    work = pixels_per_view * (SOLVED_MATTE_WORK if matte_solved else 1.0)
    return work >= POOL_MIN_VIEW_WORK


def matte_solved(mode: str, refs) -> bool:
    """Whether the matte stage solves a matte for the views ``refs`` (capture.sources.FrameRef) in
    matte ``mode``: not for 'off' and 'given', nor for 'auto' when every frame names its matte file
    (an RGBA image's own alpha is not known before reading: counted as solved)."""
    if mode in ("off", "given"):
        return False
    return not (mode == "auto" and refs and all(r.mask is not None for r in refs))


def workers_for(workers: int, refs, matte_mode: str) -> int:
    """The processes a run maps its views over: ``workers`` when given (>= 1), for AUTO_WORKERS the
    machine's cores when the pool pays (:func:`pool_pays`) for ``refs``' mean pixels, else 1."""
    if workers != AUTO_WORKERS:
        return workers
    if not refs:
        return 1
    pixels = sum(r.camera.width * r.camera.height for r in refs) / len(refs)
    return cores() if pool_pays(pixels, matte_solved(matte_mode, refs)) else 1


def init_worker(threads: int) -> None:
    """A worker's first act: its thread caps (module docstring) and its heap (:func:`keep_freed_memory`)."""
    for var in THREAD_VARIABLES:
        os.environ[var] = str(threads)
    keep_freed_memory()


def keep_freed_memory() -> bool:
    """With HEAP_KEEPS_FREED: this process's C heap keeps freed arrays for the next ones (glibc
    ``mallopt``: HEAP_MMAP_THRESHOLD, HEAP_TRIM_THRESHOLD, HEAP_TOP_PAD); True when set, False where
    off or not glibc.  What the program computes does not change, only where its memory comes from."""
    libc = _libc()
    if not HEAP_KEEPS_FREED or libc is None or not hasattr(libc, "mallopt"):
        return False
    ok = True
    for param, value in ((_M_MMAP_THRESHOLD, HEAP_MMAP_THRESHOLD), (_M_TRIM_THRESHOLD, HEAP_TRIM_THRESHOLD),
                         (_M_TOP_PAD, HEAP_TOP_PAD)):
        ok = bool(libc.mallopt(param, int(value))) and ok
    return ok


def start_pool(workers: int):
    """A pool of ``workers`` spawned processes (module docstring); the caller shuts it down."""
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor

    return ProcessPoolExecutor(workers, mp_context=mp.get_context("spawn"), initializer=init_worker,
                               initargs=(max(1, cores() // workers),))


#: The steps of this worker's last task (by name): the heap is trimmed when they change.
_LAST_STEPS: tuple = ()


def apply_steps(steps, view, ref, out_file=None):
    """``view`` through ``steps`` [(fn, cfg)] in a worker: (the view: None when no step changed it,
    a capture.scan_store.SpilledScan when written to ``out_file``, else the Scan; the notes; per step
    (wall s, CPU s); (this process's id, its peak resident MiB in the task))."""
    if not os.environ.get("_FURROW_CV_THREADS_SET"):
        import cv2

        cv2.setNumThreads(int(os.environ.get("OMP_NUM_THREADS", "1")))
        os.environ["_FURROW_CV_THREADS_SET"] = "1"
    global _LAST_STEPS
    kind = tuple(getattr(fn, "__qualname__", repr(fn)) for fn, _ in steps)
    if kind != _LAST_STEPS:  # a new stage: the last one's freed pages are not this stage's peak
        release_free_memory()  # (not every task: pages handed back are faulted in again, sys time)
        _LAST_STEPS = kind
    reset_peak_rss()
    start, notes, times = view, [], []
    for fn, cfg in steps:
        t0, c0 = time.perf_counter(), time.process_time()
        out, note = fn(view, ref, cfg)
        view = view if out is None else out
        times.append((time.perf_counter() - t0, time.process_time() - c0))
        notes.append(note)
    from capture.scan_store import SpilledScan, write_scan

    if view is start:
        view = None
    elif out_file is not None and not isinstance(view, SpilledScan):  # a spilled view is on disk already
        view = write_scan(out_file, view)
    return view, notes, times, (os.getpid(), peak_rss_mb())

"""The runner's worker processes (``--view-workers N``): one pool per run, started on first use.

Kept light on purpose: a spawned worker imports this module first (for :func:`init_worker`), so
the thread caps are in its environment before numpy, OpenCV or numba are imported there.  Each of
N workers gets ``cores // N`` threads (numba, OpenMP / BLAS, OpenCV), so that N workers on a
machine of N cores do not fight over them.

A task is :func:`apply_steps`: one view through a list of per-view steps ``fn(view, ref, cfg) ->
(view, note)``.  What it hands back is small when it can be: a view no step changed comes back as
None (the runner keeps the one it has), and a changed view is written to the spill folder in the
worker (``out_file``, capture.scan_store.write_scan) and comes back as its file name.  The time
of each step (wall and CPU seconds) and the worker's peak resident memory in the task come back
too, for the stage table.
"""

from __future__ import annotations

import os
import time

#: Environment variables that set the threads of numba, OpenMP / BLAS libraries in a worker.
THREAD_VARIABLES = ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def cores() -> int:
    """CPU cores this process may run on (the default number of workers)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


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


def init_worker(threads: int) -> None:
    """A worker's first act: its thread caps (module docstring)."""
    for var in THREAD_VARIABLES:
        os.environ[var] = str(threads)


def start_pool(workers: int):
    """A pool of ``workers`` spawned processes (module docstring); the caller shuts it down."""
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor

    return ProcessPoolExecutor(workers, mp_context=mp.get_context("spawn"), initializer=init_worker,
                               initargs=(max(1, cores() // workers),))


def apply_steps(steps, view, ref, out_file=None):
    """``view`` through ``steps`` [(fn, cfg)] in a worker: (the view: None when no step changed it,
    a capture.scan_store.SpilledScan when written to ``out_file``, else the Scan; the notes; per step
    (wall s, CPU s); (this process's id, its peak resident MiB in the task))."""
    if not os.environ.get("_FURROW_CV_THREADS_SET"):
        import cv2

        cv2.setNumThreads(int(os.environ.get("OMP_NUM_THREADS", "1")))
        os.environ["_FURROW_CV_THREADS_SET"] = "1"
    reset_peak_rss()
    start, notes, times = view, [], []
    for fn, cfg in steps:
        t0, c0 = time.perf_counter(), time.process_time()
        out, note = fn(view, ref, cfg)
        view = view if out is None else out
        times.append((time.perf_counter() - t0, time.process_time() - c0))
        notes.append(note)
    if view is start:
        view = None
    elif out_file is not None:
        from capture.scan_store import write_scan

        view = write_scan(out_file, view)
    return view, notes, times, (os.getpid(), peak_rss_mb())

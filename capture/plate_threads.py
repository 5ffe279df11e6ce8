"""The background plate stage on every core: threads over views and over chunks of pixels (issue 32, round 6).

The plate stage runs in the pipeline's main process (it needs every view at once), so on a 2-core
machine one core idled through it (72 views of 1280x960: 35 s wall for 36 CPU s, docs/speed.md).
Its work splits two ways that need no pickling of the views: per view (preparing a view's masks and
weights, predicting its held-back ring, drawing its plate) and per chunk of pixels (the robust mode's
and the frames' lines' chunks).  Both are numpy, OpenCV and numba kernels compiled ``nogil``, which
let go of the GIL, so threads run them side by side.

Every result is the same as one thread's, bit for bit: each item (a view, a chunk) is computed
alone exactly as before and the results are put back in order (:func:`thread_map`).  A map inside
a map's worker runs in that worker (no threads within threads: the cores are already busy).
"""

from __future__ import annotations

import os
import threading
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ThreadPoolExecutor

import numpy as np

#: Threads of the plate stage (None: the cores this process may run on).  1 = one thread, as before.
PLATE_THREADS: int | None = None

_worker = threading.local()


def plate_threads() -> int:
    """Threads :func:`thread_map` uses: PLATE_THREADS, else this process's cores (1 inside a worker)."""
    if getattr(_worker, "busy", False):
        return 1
    if PLATE_THREADS is not None:
        return max(1, int(PLATE_THREADS))
    return cores()


def cores() -> int:
    """CPU cores this process may run on (the one count the plate's and fusion's threads and the
    pipeline's default workers use: volume.pipeline.pool.cores is this)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def _run(fn: Callable, item):
    _worker.busy = True
    try:
        return fn(item)
    finally:
        _worker.busy = False


def thread_map(fn: Callable, items: Iterable, threads: int | None = None) -> Iterator:
    """``map(fn, items)`` on ``threads`` threads (default :func:`plate_threads`), in order, lazily:
    ``items`` is read as the results are taken (at most twice the threads ahead), so a generator of
    views does not wait whole in memory, nor do the results of a generator that yields them."""
    n = plate_threads() if threads is None else max(1, int(threads))
    if n == 1:
        yield from map(fn, items)
        return
    _opencv_alone(True)
    try:
        with ThreadPoolExecutor(n, thread_name_prefix="plate") as pool:
            pending: deque = deque()
            for item in items:
                pending.append(pool.submit(_run, fn, item))
                if len(pending) >= 2 * n:
                    yield pending.popleft().result()
            while pending:
                yield pending.popleft().result()
    finally:
        _opencv_alone(False)


_opencv = {"maps": 0, "threads": None}
_opencv_lock = threading.Lock()


def _opencv_alone(start: bool) -> None:
    """OpenCV's own threads off while any map runs threads (its parallel loops inside each of our threads
    oversubscribed the cores: 72 views of 1280x960, 31 s wall for the plates against 22 s with them
    off, docs/speed.md round 6), its setting back when the last such map ends."""
    import cv2

    with _opencv_lock:
        if start:
            _opencv["maps"] += 1
            if _opencv["maps"] == 1:
                _opencv["threads"] = cv2.getNumThreads()
                cv2.setNumThreads(1)
        else:
            _opencv["maps"] -= 1
            if _opencv["maps"] == 0:
                cv2.setNumThreads(_opencv["threads"])


def chunks(n: int, size: int) -> list[tuple[int, int]]:
    """(lo, hi) of consecutive chunks of ``size`` over ``range(n)`` (the last one shorter)."""
    return [(lo, min(n, lo + size)) for lo in range(0, n, max(1, int(size)))]


def chunked_prediction(predict: Callable, n: int, size: int) -> tuple[np.ndarray, np.ndarray]:
    """((n, 3) float32 colour, NaN where none; (n,) bool bound) of ``predict(lo, hi) -> (colour, bound)``
    over the pixels ``lo:hi`` of :func:`chunks` (``size`` a chunk), the chunks side by side (module docstring:
    each chunk is its own pixels', so the values are one call's)."""
    med = np.full((n, 3), np.nan, np.float32)
    bound = np.zeros(n, bool)

    def one(span):
        lo, hi = span
        med[lo:hi], bound[lo:hi] = predict(lo, hi)

    for _ in thread_map(one, chunks(n, size)):
        pass
    return med, bound


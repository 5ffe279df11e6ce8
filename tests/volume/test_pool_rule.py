"""The default --view-workers' rule (volume/pipeline/pool.py): a pool only where a view's work pays for it."""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from volume.pipeline import pool
from volume.pipeline.config import PipelineConfig
from volume.pipeline.pool import AUTO_WORKERS, POOL_MIN_VIEW_WORK, SOLVED_MATTE_WORK, pool_pays, workers_for


@dataclass(frozen=True)
class _Cam:
    width: int
    height: int


@dataclass(frozen=True)
class _Ref:  # what the rule reads of a capture.sources.FrameRef
    camera: _Cam
    mask: str | None = None


def _refs(n, w, h, mask=None):
    return [_Ref(_Cam(w, h), mask) for _ in range(n)]


def test_pool_pays_by_pixels_and_matte():
    assert not pool_pays(640 * 480, matte_solved=False)  # the 640x480 capture with its mattes given
    assert pool_pays(640 * 480, matte_solved=True)  # ... with its matte solved
    assert pool_pays(1280 * 960, matte_solved=False) and pool_pays(1920 * 1440, matte_solved=True)
    edge = POOL_MIN_VIEW_WORK / SOLVED_MATTE_WORK
    assert pool_pays(edge, True) and not pool_pays(edge - 1, True)


def test_workers_for(monkeypatch):
    monkeypatch.setattr(pool, "cores", lambda: 2)
    given = _refs(18, 640, 480, mask="m.png")
    assert workers_for(AUTO_WORKERS, given, "auto") == 1  # every frame names its matte: given, no pool
    assert workers_for(AUTO_WORKERS, given, "estimate") == 2  # the matte solved although given
    assert workers_for(AUTO_WORKERS, _refs(18, 640, 480), "auto") == 2  # no matte files: solved
    assert workers_for(AUTO_WORKERS, _refs(18, 640, 480), "off") == 1
    assert workers_for(AUTO_WORKERS, _refs(72, 1280, 960), "off") == 2
    assert workers_for(AUTO_WORKERS, [], "auto") == 1
    assert workers_for(3, given, "auto") == 3 and workers_for(1, _refs(9, 1920, 1440), "auto") == 1  # explicit N


def test_config_takes_auto_and_refuses_negative():
    assert PipelineConfig(workers=AUTO_WORKERS).workers == 0
    with pytest.raises(ValueError, match="workers"):
        PipelineConfig(workers=-1)


def test_heap_keeps_freed_memory_only_when_switched_on(monkeypatch):
    """volume.pipeline.pool.keep_freed_memory: glibc's mallopt takes the three settings (True) with
    HEAP_KEEPS_FREED; off, nothing is set (False); the same arrays either way."""
    import numpy as np

    if pool._libc() is None or not hasattr(pool._libc(), "mallopt"):
        pytest.skip("not glibc")
    a = np.arange(10_000_000, dtype=np.float64) * 0.5  # 80 MB: a mapping of its own by glibc's defaults
    monkeypatch.setattr(pool, "HEAP_KEEPS_FREED", False)
    assert pool.keep_freed_memory() is False
    monkeypatch.setattr(pool, "HEAP_KEEPS_FREED", True)
    assert pool.keep_freed_memory() is True
    b = np.arange(10_000_000, dtype=np.float64) * 0.5  # from the heap now
    np.testing.assert_array_equal(a, b)
    del a, b
    assert pool.release_free_memory() in (True, False)

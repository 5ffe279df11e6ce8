"""volume.matte_sources: each view's slope of its photo on its plate in the per-view map, and the capture's coverage
in the matte config (capture.matting_sources; off by default)."""

from __future__ import annotations

from contextlib import nullcontext

import numpy as np

from capture import matting_sources as ms
from capture.matting import MatteConfig
from capture.plate import Plate
from capture.view_map import arg_of
from tests.capture.test_matting_rim import BRANCH_ALPHA, _branches, _scan
from volume.matte_sources import slope_one, sources_coverage

#: The branches' measured transparency must be within this of the truth (1 - BRANCH_ALPHA): their colour varies
#: smoothly across the frame, the room behind them by its own texture, and the photo is 8-bit.
SLOPE_TOL = 0.05


class _Ctx:
    """The pipeline context's two calls sources_coverage makes, in this process."""

    def row(self, name):
        return nullcontext()

    def map_views(self, fn, work, per_view, description):
        notes = [fn(v, None, arg_of(per_view, k))[1] for k, v in enumerate(work.scans)]
        return tuple(work.scans), notes


class _Work:
    def __init__(self, scans):
        self.scans = scans
        self.refs = [type("Ref", (), {"index": k})() for k in range(len(scans))]


def _views(n: int = 3):
    out, plates = [], {}
    for k in range(n):
        C, B, A, _, D = _branches(seed=k)
        out.append(_scan(C, D))
        plates[k] = Plate(B, np.ones(A.shape, bool), 0.004, "panorama", 1.0, 0.0, 0.0)
    return out, plates


def test_a_views_slope_is_its_branches_transparency(monkeypatch):
    monkeypatch.setattr(ms, "ESTIMATE_COVERAGE", True)
    (view,), plates = _views(1)
    _, slope = slope_one(view, None, plates[0])
    assert slope is not None and abs(slope - (1 - BRANCH_ALPHA)) <= SLOPE_TOL, slope
    assert slope_one(view, None, None) == (None, None)  # no plate: nothing to regress on


def test_the_capture_coverage_goes_into_the_matte_config(monkeypatch):
    views, plates = _views(3)
    cfg = MatteConfig()
    assert sources_coverage(cfg, _Work(views), plates, _Ctx()) == (cfg, None)  # off by default
    monkeypatch.setattr(ms, "ESTIMATE_COVERAGE", True)
    out, rec = sources_coverage(cfg, _Work(views), plates, _Ctx())
    slopes = [s for s in rec["slopes"] if s is not None]
    assert len(slopes) == 3 and rec["median_slope"] == np.median(slopes).round(4)
    assert out.source_coverage == rec["coverage"]
    assert abs(out.source_coverage - (1 - ms.SLOPE_SHARE * (1 - BRANCH_ALPHA))) <= SLOPE_TOL
    assert sources_coverage(cfg, _Work(views), {}, _Ctx()) == (cfg, None)  # no plates

"""The capture-to-model pipeline (volume/pipeline): one ordered list of named stages, each with its
config; the runner's view-by-view loop, view selection before any image, process workers; a stage
added in one line; the plan and the docs diagram drawn from the list."""

from __future__ import annotations

import ast
import contextlib
import inspect
import pickle
import re
from dataclasses import dataclass, fields

import numpy as np
import pytest

from capture.io import write_transforms
from capture.scan_store import SpilledScan
from capture.sources import FRAME_STEPS, STEP_CONFIGS, open_source
from tests.capture.test_sources import write_layouts
from tests.conftest import REPO_DIR
from tests.scenes import make_scanset, scan_ring, sphere_scene
from volume.pipeline.config import FuseConfig, PipelineConfig, ViewsConfig
from volume.pipeline.plan import diagram, plan_rows
from volume.pipeline.runner import run_pipeline
from volume.pipeline.stages import CAMERAS, SET, STAGES, VIEW, Stage
from volume.pipeline.work import Hooks
from volume.pyramid import LoptConfig

#: The order issue 29 asks for (the list may hold more stages between them).
ORDER = ("read", "units and confidence", "depth resample", "matte read", "undistort", "view selection",
         "working scale", "depth agreement", "extent", "background plate", "matte", "photometric", "fuse", "pyramid",
         "spheres", "mesh", "RGBz", "save")
#: docs/design.md holds the diagram in the fenced block right after this line.
#: The matte row's CPU seconds with two workers against one process's: the same work, in workers (the
#: workers' start and their own imports add to it; before they were counted it read about 0.1).
WORKER_CPU_SHARE = 0.5
DIAGRAM_MARK = "<!-- drawn by volume/pipeline/plan.diagram(); tests/volume/test_pipeline.py keeps it -->"


@pytest.fixture(scope="module")
def layouts(tmp_path_factory):
    """One capture with mattes as transforms.json, plain folder and COLMAP (tests/capture/test_sources.py)."""
    return write_layouts(tmp_path_factory.mktemp("layouts"))


@pytest.fixture(scope="module")
def capture(tmp_path_factory):
    ss = make_scanset(sphere_scene(), scan_ring(8, 64, 48), noise=0.0005)
    return write_transforms(ss, tmp_path_factory.mktemp("pipe") / "sphere")


def _rows():
    names = []

    def row(name):
        if name not in names:
            names.append(name)
        return contextlib.nullcontext()

    return names, Hooks(row=row)


def test_stages_are_one_ordered_list_with_a_config_each():
    names = [st.name for st in STAGES]
    assert names == list(ORDER)
    cfg = PipelineConfig()
    keys = {f.name for f in fields(PipelineConfig)}
    for st in STAGES:
        assert st.key in keys and st.kind in (VIEW, CAMERAS, SET) and st.does and st.where, st.name
        c = getattr(cfg, st.key)
        assert c is not None and st.on(c), st.name  # every stage is on by default
    assert len({st.key for st in STAGES}) == len(STAGES)


def _documented_fields(cls) -> list[str]:
    """Fields of a config dataclass without a docstring after them or a ``#:`` comment before them."""
    src = inspect.getsource(cls)
    lines = src.splitlines()
    body = ast.parse(src).body[0].body
    bad = []
    for i, node in enumerate(body):
        if isinstance(node, ast.AnnAssign):
            after = body[i + 1] if i + 1 < len(body) else None
            doc = isinstance(after, ast.Expr) and isinstance(getattr(after, "value", None), ast.Constant)
            comment = lines[node.lineno - 2].strip().startswith("#:")
            if not (doc or comment):
                bad.append(node.target.id)
    return bad


def test_every_stage_config_documents_every_field():
    cfg = PipelineConfig()
    for st in STAGES:
        cls = type(getattr(cfg, st.key))
        assert cls.__doc__ and not _documented_fields(cls), (st.name, cls.__name__, _documented_fields(cls))
    assert not _documented_fields(PipelineConfig)


def test_per_view_stages_are_picklable_top_level_functions():
    for st in STAGES:
        if st.kind == VIEW:
            assert "<" not in st.fn.__qualname__ and pickle.loads(pickle.dumps(st.fn)) is st.fn, st.name


def test_view_selection_reads_no_image_of_a_dropped_view(capture, monkeypatch):
    import capture.sources as sources

    read = []
    real = sources.read_color
    monkeypatch.setattr(sources, "read_color", lambda p: read.append(p.name) or real(p))
    names, hooks = _rows()
    upto = STAGES[:ORDER.index("working scale") + 1]
    with run_pipeline(open_source(capture), PipelineConfig(views=ViewsConfig("3")), hooks, upto) as run:
        assert len(run.work.scans) == 3 and run.work.records["view selection"]["kept"] == 3
    assert len(read) == 3  # 3 of 8 frames read
    assert names.index("view selection") < names.index("read")  # the cameras alone, first
    # the bounds from the depth (the capture gives none) have their own row after reading: no time unshown
    assert names.index("read") < names.index("bounds") < names.index("working scale")


def test_process_workers_give_the_same_views(capture):
    upto = STAGES[:ORDER.index("matte") + 1]
    out = {}
    for workers in (1, 2):
        cfg = PipelineConfig(extent=None, workers=workers, spill="always")
        with run_pipeline(open_source(capture), cfg, stages=upto) as run:
            out[workers] = [(np.array(s.rgb), np.array(s.depth), np.array(s.alpha)) for s in run.work.scans]
            assert run.work.records["matte"]["methods"]
    for a, b in zip(out[1], out[2], strict=True):
        for x, y in zip(a, b, strict=True):
            np.testing.assert_array_equal(x, y)


def test_whole_set_rows_count_their_workers_memory(capture):
    """Issue 32's peak: a whole-set stage whose per-view passes ran in the pool (extent, the matte)
    has the workers' peaks added to its row (each worker's own peak in the row: an upper bound); a
    stage that sends nothing to the pool (the plate, the fuse levels) keeps the main process's."""
    from furrow.console import StageTimer

    upto = STAGES[:ORDER.index("matte") + 1]
    timer = StageTimer()
    added = {}

    def add(name, seconds, cpu, peak):
        added[name] = peak
        timer.add(name, seconds, cpu, peak)

    hooks = Hooks(row=timer.stage, add=add)
    with run_pipeline(open_source(capture), PipelineConfig(workers=2), hooks, upto):
        pass
    assert {"extent", "matte"} <= set(added) and "background plate" not in added and "working scale" not in added
    for name in ("extent", "matte"):
        assert timer.peak_mb[name] == added[name] > 0


def test_whole_set_rows_count_their_workers_cpu(capture):
    """A whole-set stage's row counts the CPU seconds of its passes in the pool: the matte's row with
    two workers holds about what one process spends on it (it held the main process's waiting alone,
    0.24 CPU s for 18.7 s on 72 phone views)."""
    from furrow.console import StageTimer

    upto = STAGES[:ORDER.index("matte") + 1]
    cpu = {}
    for workers in (1, 2):
        timer = StageTimer()
        with run_pipeline(open_source(capture), PipelineConfig(workers=workers), Hooks(row=timer.stage,
                                                                                         add=timer.add), upto):
            pass
        cpu[workers] = timer.cpu_seconds["matte"]
    assert cpu[2] >= WORKER_CPU_SHARE * cpu[1], cpu


@dataclass(frozen=True)
class ToyConfig:
    """A toy stage's settings."""

    grey: float = 0.25
    """The toy's grey level."""


def toy_stage(work, cfg, ctx):
    """A whole-set toy stage: records what it would make for each view."""
    return work.record("toy", {"views": len(work.scans), "grey": cfg.grey})


def test_a_stage_is_one_function_one_config_one_line(capture):
    """A new stage is a config field and one line (issue 30's background plate went in so, between
    extent and matte); a toy one goes in after the plate.  The matte reads the plate (``--matte
    plate``): the auto matte of this sphere over black takes the backdrop path and skips the plate."""
    from capture.matting import MatteConfig

    @dataclass(frozen=True)
    class Config(PipelineConfig):
        toy: ToyConfig = ToyConfig()

    at = ORDER.index("matte")
    stages = STAGES[:at] + (Stage("toy", "toy", SET, toy_stage, "toy", "tests"),) + STAGES[at:]
    names, hooks = _rows()
    cfg = Config(fuse=FuseConfig(lopt=LoptConfig(max_res=16)), toy=ToyConfig(0.5), matte=MatteConfig(mode="plate"))
    with run_pipeline(open_source(capture), cfg, hooks, stages) as run:
        assert run.work.records["toy"] == {"views": 8, "grey": 0.5}
        assert run.model is not None and "toy" in run.model.params["stages"]
        assert run.work.records["background plate"]["mode"] in ("fixed", "panorama")
        assert "plate" in run.model.params["surroundings"]
    assert names.index("extent") < names.index("background plate") < names.index("toy") < names.index("matte")
    rows = plan_rows(cfg, stages)
    assert rows[at]["name"] == "toy" and rows[at]["settings"] == "grey=0.5"


def _blas_threads() -> list[int]:
    from threadpoolctl import threadpool_info

    return [d["num_threads"] for d in threadpool_info() if d["user_api"] == "blas"]


def blas_stage(work, cfg, ctx):
    """A whole-set stage that records the BLAS threads it runs with."""
    return work.record("blas", {"threads": _blas_threads()})


def test_the_main_process_blas_runs_one_thread_in_a_run(capture):
    """The stages' own threads and workers are the parallelism: the main process's BLAS runs
    MAIN_BLAS_THREADS threads while they run (its spinning threads cost the plate stage a fifth of
    its time on 2 cores), and has its own number back after the run."""
    from threadpoolctl import threadpool_limits

    from volume.pipeline.pool import MAIN_BLAS_THREADS

    pytest.importorskip("threadpoolctl")
    if not _blas_threads():
        pytest.skip("no BLAS library that threadpoolctl can see")
    at = ORDER.index("extent")
    stages = STAGES[:at] + (Stage("blas", "toy", SET, blas_stage, "toy", "tests"),)

    @dataclass(frozen=True)
    class Config(PipelineConfig):
        toy: ToyConfig = ToyConfig()

    with threadpool_limits(limits=3, user_api="blas"):
        before = _blas_threads()
        with run_pipeline(open_source(capture), Config(extent=None), stages=stages) as run:
            inside = run.work.records["blas"]["threads"]
        after = _blas_threads()
    assert before == after and all(n == 3 for n in before)
    assert inside and all(n == MAIN_BLAS_THREADS for n in inside)


def test_plan_says_what_is_on():
    rows = {r["name"]: r for r in plan_rows(PipelineConfig(extent=None, photometric=None))}
    assert not rows["extent"]["on"] and rows["extent"]["settings"] == "off" and not rows["photometric"]["on"]
    assert rows["matte"]["on"] and "mode='auto'" in rows["matte"]["settings"]
    assert "max_res=256" in rows["fuse"]["settings"]


def test_docs_diagram_is_drawn_from_the_stage_list():
    text = (REPO_DIR / "docs" / "design.md").read_text(encoding="utf-8")
    assert DIAGRAM_MARK in text, "docs/design.md lost the pipeline diagram's marker"
    block = re.search(re.escape(DIAGRAM_MARK) + r"\s*```\n(.*?)\n```", text, re.S)
    assert block, "no fenced block after the diagram marker"
    assert block.group(1) == diagram(), "docs/design.md differs from volume/pipeline/plan.diagram(): paste its output"
    for st in STAGES:
        assert f" {st.name} " in block.group(1)


def test_every_layout_goes_the_same_matte_path(layouts):
    """The pipeline up to its matte stage, views on disk: the capture's own matte for every view
    ('given') in each layout, and the same matted colour and alpha from each."""
    from volume.pipeline.config import PipelineConfig
    from volume.pipeline.runner import run_pipeline
    from volume.pipeline.stages import STAGES

    upto = STAGES[:[s.name for s in STAGES].index("matte") + 1]
    got = {}
    for layout, folder in layouts[1].items():
        with run_pipeline(open_source(folder), PipelineConfig(extent=None, spill="always"), stages=upto) as run:
            assert run.work.records["matte"]["methods"] == {"given": 4}, layout
            assert all(isinstance(s, SpilledScan) and s.alpha is not None for s in run.work.scans)
            got[layout] = [(np.array(s.alpha), np.array(s.rgb)) for s in run.work.scans]
    ref = got["transforms.json"]
    for layout, views in got.items():
        for (a, c), (ra, rc) in zip(views, ref, strict=True):
            np.testing.assert_array_equal(a, ra, err_msg=layout)
            np.testing.assert_allclose(c, rc, atol=1e-6, err_msg=layout)




def test_the_pipeline_reads_with_the_same_steps():
    """The pipeline's reading stages are capture.sources' frame steps, in order, each with its config."""
    from volume.pipeline.config import PipelineConfig
    from volume.pipeline.stages import STAGES

    reading = [st for st in STAGES if st.reads_frame]
    assert [(st.name, st.fn) for st in reading] == list(FRAME_STEPS)
    assert [type(getattr(PipelineConfig(), st.key)) for st in reading] == list(STEP_CONFIGS)


def test_pool_sampled_bounds_equal_the_serial_bounds(capture, tmp_path):
    """Issue 32 round 10: a capture without bounds gets the robust box of its depth; with a pool its
    points are sampled in the workers (capture.extent.mapped_sampled_points): the same box bit for bit."""
    import json
    import shutil

    cap = tmp_path / "nobounds"
    shutil.copytree(capture.parent if capture.is_file() else capture, cap)
    meta = json.loads((cap / "transforms.json").read_text())
    meta.get("furrow", {}).pop("bounds", None)
    (cap / "transforms.json").write_text(json.dumps(meta))
    assert open_source(cap).bounds is None
    reading = [st for st in STAGES if st.reads_frame]
    got = {}
    for workers in (1, 2):
        with run_pipeline(open_source(cap), PipelineConfig(extent=None, workers=workers, spill="always"),
                          stages=reading) as run:
            got[workers] = np.array(run.work.bounds)
            assert (run._sampler(len(run.work.refs)) is not None) == (workers == 2)
    assert got[1].shape == (2, 3) and np.all(got[1][1] > got[1][0])
    np.testing.assert_array_equal(got[1], got[2])

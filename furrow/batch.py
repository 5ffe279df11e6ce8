"""Many captures: :func:`run_capture` (one capture, plain function) and :func:`run_batch` (the Ray layer).

``run_capture(scans, out, steps)`` wires the stages for one capture -- read, ``model`` (the pipeline,
volume/pipeline, as ``furrow model`` with the same flags), ``eval`` (held-out, as ``furrow eval``:
the same function, furrow.cmd_eval.evaluate_capture), ``orbit`` (an MP4
turntable, as ``furrow render --orbit --video``) -- and writes into ``out``:

    out/model/       the model (volume.model.save_model: temporary folder + rename)
    out/eval.json    held-out scores (atomic)
    out/orbit.mp4    the orbit video (render.composite.video.write_mp4: atomic)
    out/done.json    the capture's record, written last: its presence marks the capture complete

``run_batch`` submits one Ray task per capture (``@ray.remote(max_calls=1)``: the worker process
is recycled after each capture, so no GL state or memory leaks into the next); each task creates
its GL context inside the worker and caps llvmpipe's threads to its CPU share (LP_NUM_THREADS)
before any GL library is loaded.  A failing capture becomes a record with status "failed" and
a one-line reason; the others go on.  Complete captures (done.json with every requested step
and its outputs present) are skipped.  ``OUT/batch.json`` is rewritten atomically after every
capture, so it is complete whenever the batch stops.
"""

from __future__ import annotations

import json
import os
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

from capture.atomic import write_json
from volume.pipeline.config import PipelineConfig

#: The steps a capture can run, in order.
STEPS = ("model", "eval", "orbit")
#: The record written last into a capture's output folder.
DONE_FILE = "done.json"
#: The batch summary in the output root.
BATCH_FILE = "batch.json"
#: Output of each step, relative to the capture's output folder.
STEP_OUTPUTS = {"model": "model/model.json", "eval": "eval.json", "orbit": "orbit.mp4"}
#: Longest reason kept in a record (one line).
REASON_CHARS = 300
#: CPUs one capture task reserves; llvmpipe gets as many threads (LP_NUM_THREADS).
TASK_CPUS = 1
#: Object store of a local cluster (bytes): the tasks exchange only small records.
LOCAL_OBJECT_STORE_BYTES = 256 * 1024 * 1024


@dataclass(frozen=True)
class CaptureConfig:
    """What ``furrow batch`` sets for every capture."""

    pipeline: PipelineConfig = field(default_factory=PipelineConfig)
    """The model pipeline's config (the model flags of ``furrow model``, furrow/model_flags.py)."""
    holdout: int = 2
    """eval: keep frames i % holdout == 0 for the held-out model (as ``furrow eval --holdout``)."""
    orbit_frames: int = 36
    """orbit: frames of the turntable video."""
    fps: float = 24.0
    """orbit: frames per second."""
    method: str = "microfacet"
    """Renderer of the orbit (a render.methods name)."""
    allow_flagged: bool = False
    """Model captures whose registration.json flags scans (default: fail them)."""


def parse_steps(text: str) -> tuple[str, ...]:
    """'model,eval,orbit' -> the steps in STEPS order; ValueError naming an unknown one."""
    steps = [s.strip() for s in text.split(",") if s.strip()]
    bad = [s for s in steps if s not in STEPS]
    if bad or not steps:
        raise ValueError(f"--steps: unknown {', '.join(bad) or 'empty list'}; choose from {', '.join(STEPS)}")
    return tuple(s for s in STEPS if s in steps)


def one_line(e: BaseException) -> str:
    """``Type: first line of the message`` (at most REASON_CHARS)."""
    msg = str(e).strip().splitlines()[0] if str(e).strip() else ""
    return f"{type(e).__name__}: {msg}"[:REASON_CHARS] if msg else type(e).__name__


def is_complete(out: Path, steps: Sequence[str]) -> bool:
    """The capture's done.json says "done" for every step in ``steps`` and their outputs exist."""
    try:
        rec = json.loads((Path(out) / DONE_FILE).read_text())
    except (OSError, ValueError):
        return False
    return (isinstance(rec, dict) and rec.get("status") == "done" and set(steps) <= set(rec.get("steps", []))
            and all((Path(out) / STEP_OUTPUTS[s]).is_file() for s in steps))


def _check_registration(scans: Path, allow_flagged: bool) -> None:
    from capture.io import resolve_transforms

    folder = scans if scans.is_dir() else resolve_transforms(scans).parent
    rep = folder / "registration.json"
    if allow_flagged or not rep.is_file():
        return
    try:
        flagged = json.loads(rep.read_text()).get("flagged") or []
    except (OSError, ValueError, AttributeError):
        raise ValueError(f"{rep}: unreadable registration report") from None
    if flagged:
        names = ", ".join(str(f) for f in flagged[:5]) + (" ..." if len(flagged) > 5 else "")
        raise ValueError(f"registration flagged {len(flagged)} scan(s): {names} ({rep}; --allow-flagged to "
                         "model anyway)")


def _orbit(model, cameras, out: Path, cfg: CaptureConfig) -> int:
    """Render the orbit of ``model`` into out/orbit.mp4 (GL context created here, in the worker)."""
    import numpy as np

    from capture.orbit import orbit_cameras
    from capture.scan import to_uint8_srgb
    from render.composite.video import write_mp4
    from render.gl import gl_context
    from render.methods import create_renderer

    cams = orbit_cameras(cameras, cfg.orbit_frames, center=np.asarray(model.bounds).mean(axis=0))
    with gl_context() as ctx, create_renderer(cfg.method, ctx, model) as r:
        return write_mp4((to_uint8_srgb(r.render(c).rgb) for c in cams), out / "orbit.mp4", cfg.fps)


def _model(source, out: Path, cfg: CaptureConfig) -> dict:
    """The model (as ``furrow model``) into out/model; the summary keys of the record."""
    from volume.pipeline.config import SaveConfig
    from volume.pipeline.runner import run_pipeline

    with run_pipeline(source, replace(cfg.pipeline, save=SaveConfig(out=out / "model"))) as run:
        summary = run.summary()
    return {k: summary[k] for k in ("l_opt", "levels", "spheres", "mesh")}


def _evaluate(scans: Path, out: Path, cfg: CaptureConfig) -> dict:
    """Held-out scores (as ``furrow eval``, the same pipeline config) into out/eval.json; returns the
    means per method."""
    from furrow.cmd_eval import evaluate_capture

    res = evaluate_capture(scans, cfg.pipeline, cfg.holdout)
    write_json(out / "eval.json", res)
    return {k: {m: round(v[m], 4) for m in ("psnr", "ssim", "psnr_masked")} for k, v in res.items()
            if isinstance(v, dict) and "psnr_masked" in v}


def run_capture(scans, out, steps: Sequence[str] = STEPS, config: CaptureConfig | None = None,
                on_stage: Callable[[str], None] | None = None, record: dict | None = None) -> dict:
    """Run ``steps`` for one capture into ``out`` (module docstring); returns its record.

    Raises whatever a stage raises (the caller reports it); nothing is marked complete unless
    every step succeeded (done.json is written last).  ``record``: a dict filled as the stages run
    (their times survive a failure)."""
    from capture.atomic import jsonable
    from capture.sources import open_source
    from volume.model import load_model

    cfg = config or CaptureConfig()
    scans, out = Path(scans), Path(out)
    steps = tuple(s for s in STEPS if s in steps)
    rec = record if record is not None else {}
    rec.update({"capture": out.name, "scans": str(scans), "steps": list(steps), "stages": {}, "scores": {},
                "config": jsonable(asdict(cfg)), "pid": os.getpid()})

    def stage(name):
        if on_stage:
            on_stage(name)
        return _Timed(rec["stages"], name)

    out.mkdir(parents=True, exist_ok=True)
    with stage("read"):
        _check_registration(scans, cfg.allow_flagged)
        source = open_source(scans, cfg.pipeline.undistort.mode)
    if "model" in steps:
        with stage("model"):
            rec["model"] = _model(source, out, cfg)
    if "eval" in steps:
        with stage("eval"):
            rec["scores"] = _evaluate(scans, out, cfg)
    if "orbit" in steps:
        with stage("orbit"):
            rec["orbit_frames"] = _orbit(load_model(out / "model"), source.cameras, out, cfg)
    rec["status"] = "done"
    write_json(out / DONE_FILE, rec)
    return rec


class _Timed:
    """Context manager adding the seconds of its body to ``table[name]``."""

    def __init__(self, table: dict, name: str):
        self.table, self.name = table, name

    def __enter__(self):
        self.t0 = time.perf_counter()

    def __exit__(self, *exc):
        self.table[self.name] = round(self.table.get(self.name, 0.0) + time.perf_counter() - self.t0, 3)
        return False


def capture_task(scans: str, out: str, steps: tuple[str, ...], config: CaptureConfig, lp_threads: int) -> dict:
    """One capture in a worker process: cap llvmpipe's threads before GL loads, run, never raise."""
    os.environ["LP_NUM_THREADS"] = str(lp_threads)
    os.environ.setdefault("OMP_NUM_THREADS", str(lp_threads))
    os.environ.setdefault("OMP_WAIT_POLICY", "passive")
    t0 = time.perf_counter()
    rec: dict = {"capture": Path(out).name, "scans": str(scans), "steps": list(steps)}
    try:
        run_capture(scans, out, steps, config, record=rec)
    except BaseException as e:  # reported by name with its one-line reason; the batch goes on
        rec.update(status="failed", reason=one_line(e), traceback=traceback.format_exc(limit=8)[-4000:])
    rec["seconds"] = round(time.perf_counter() - t0, 3)
    return rec


# ----------------------------------------------------------------------------------- the Ray layer
def _failed(name: str, scans: str, steps, reason: str) -> dict:
    return {"capture": name, "scans": scans, "steps": list(steps), "status": "failed", "reason": reason[:REASON_CHARS]}


def start_ray(address: str | None, workers: int) -> bool:
    """Connect to the cluster at ``address``, or start a local one with ``workers`` CPUs (no dashboard).
    Returns True when this call started Ray (the caller shuts it down)."""
    import logging

    import ray

    if ray.is_initialized():
        return False
    if address:
        ray.init(address=address, logging_level=logging.ERROR, log_to_driver=False)
    else:
        ray.init(num_cpus=workers, include_dashboard=False, object_store_memory=LOCAL_OBJECT_STORE_BYTES,
                 logging_level=logging.ERROR, log_to_driver=False)
    return True


def run_batch(captures: Sequence[Path], out_root: Path, steps: Sequence[str] = STEPS,
              config: CaptureConfig | None = None, address: str | None = None, workers: int = 2,
              on_update: Callable[[dict], None] | None = None) -> dict:
    """Every capture as one Ray task (module docstring); returns the batch record (also OUT/batch.json).

    ``on_update(record)`` is called with each capture's record when it is queued, skipped, done or failed."""
    import ray

    cfg = config or CaptureConfig()
    out_root = Path(out_root)
    names = [Path(c).name if Path(c).is_dir() else Path(c).parent.name for c in captures]
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise ValueError(f"captures share folder names ({', '.join(dupes)}): their outputs would clash")
    out_root.mkdir(parents=True, exist_ok=True)
    t0 = time.time()
    batch = {"steps": list(steps), "config": asdict(cfg), "address": address, "workers": workers,
             "started": time.strftime("%Y-%m-%dT%H:%M:%S"), "captures": {}}

    def update(rec: dict) -> None:
        batch["captures"][rec["capture"]] = rec
        batch["seconds"] = round(time.time() - t0, 3)
        batch["summary"] = {s: sum(r["status"] == s for r in batch["captures"].values())
                            for s in ("done", "failed", "skipped", "queued")}
        write_json(out_root / BATCH_FILE, batch)
        if on_update:
            on_update(rec)

    started = start_ray(address, workers)
    try:
        # max_calls=1: a fresh worker process per capture; max_retries=0: a capture that kills its worker
        # (out of memory, a crash) is reported, not run again behind the user's back
        task = ray.remote(max_calls=1, num_cpus=TASK_CPUS, max_retries=0)(capture_task)
        pending = {}
        for scans, name in zip(captures, names):
            out = out_root / name
            if is_complete(out, steps):
                prev = json.loads((out / DONE_FILE).read_text())
                update({**prev, "capture": name, "status": "skipped", "reason": "complete (done.json)"})
                continue
            pending[task.remote(str(scans), str(out), tuple(steps), cfg, TASK_CPUS)] = (name, scans)
            update({"capture": name, "scans": str(scans), "steps": list(steps), "status": "queued"})
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            name, scans = pending.pop(done[0])
            try:
                rec = ray.get(done[0])
            except Exception as e:  # the worker died: out of memory, killed, crashed
                rec = _failed(name, str(scans), steps, f"worker lost ({one_line(e)})")
            update(rec)
    finally:
        if started:
            ray.shutdown()
    return batch

"""The stage list as text: the plan of one configuration (``furrow model --plan``) and the
diagram docs/design.md holds (tests/volume/test_pipeline.py fails when the page differs)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

from volume.pipeline.config import PipelineConfig
from volume.pipeline.stages import STAGES, VIEW

#: Width of the stage-name column of the diagram and the plan.
NAME_WIDTH = 21
#: Width of the "what it does" column of the diagram.
DOES_WIDTH = 52
#: A nested config with at most this many fields is shown whole; a larger one shows what differs from its defaults.
NESTED_SHOWN_WHOLE = 4
#: The diagram's first and last lines (what goes in, what comes out).
DIAGRAM_IN = " capture: transforms.json | COLMAP | plain folder  (capture/sources.py: cameras first, then each frame)"
DIAGRAM_OUT = " model folder: model.json, pyramid.npz, rgbz.npz, spheres.npz, mesh.npz  (written atomically)"


def _value(v) -> str:
    """A setting as the plan shows it."""
    if isinstance(v, float):
        return f"{v:.4g}"
    if v is None or isinstance(v, (bool, int, str)):
        return repr(v) if isinstance(v, str) else str(v)
    if isinstance(v, Path):
        return str(v)
    if isinstance(v, tuple):
        return "x".join(map(str, v)) if len(v) == 2 and all(isinstance(x, int) for x in v) else str(tuple(v))
    if dataclasses.is_dataclass(v):
        whole = len(dataclasses.fields(v)) <= NESTED_SHOWN_WHOLE
        return f"{type(v).__name__}({_changed(v, whole) or 'defaults'})"
    return type(v).__name__


def _changed(cfg, whole: bool = False) -> str:
    """The fields of a nested config that differ from its class's defaults (``whole``: every field), 'a=1, b=2'."""
    try:
        base = None if whole else type(cfg)()
    except TypeError:
        base = None
    return ", ".join(f"{f.name}={_value(getattr(cfg, f.name))}" for f in dataclasses.fields(cfg)
                     if base is None or getattr(cfg, f.name) != getattr(base, f.name))


def settings(cfg) -> str:
    """One stage's settings: every field of its config (nested configs: what differs from their defaults)."""
    if cfg is None:
        return "off"
    fields = dataclasses.fields(cfg)
    if not fields:
        return "(nothing to set)"
    out = []
    for f in fields:
        v = getattr(cfg, f.name)
        if f.name == "capture_env":
            v = None if v is None else "set"
        out.append(f"{f.name}={_value(v)}")
    return ", ".join(out)


def plan_rows(cfg: PipelineConfig | None = None, stages=STAGES) -> list[dict]:
    """Per stage, in order: name, kind, on (with this config), settings, what it does, where."""
    cfg = cfg or PipelineConfig()
    rows = []
    for i, st in enumerate(stages, 1):
        c = getattr(cfg, st.key)
        rows.append({"n": i, "name": st.name, "kind": st.kind, "on": bool(st.on(c)), "settings": settings(c),
                     "does": st.does, "where": st.where})
    return rows


def plan_text(cfg: PipelineConfig | None = None, stages=STAGES) -> str:
    """The plan as plain text: one line per stage (on/off, kind, settings), then the runner's settings."""
    cfg = cfg or PipelineConfig()
    lines = []
    for r in plan_rows(cfg, stages):
        lines.append(f"{r['n']:2d}. {r['name']:<{NAME_WIDTH}} {'on ' if r['on'] else 'off'}  {r['kind']:<9}  "
                     f"{r['settings']}")
    lines.append(f"runner: spill={cfg.spill!r}, workers={cfg.workers or 'auto (pool rule)'}")
    return "\n".join(lines)


def diagram(stages=STAGES) -> str:
    """The pipeline as the text diagram of docs/design.md: the capture, every stage in order (its
    kind, what it does, where the work is; per-view runs marked), the model folder."""
    lines = [DIAGRAM_IN, "   │"]
    for i, st in enumerate(stages, 1):
        run = "┃" if st.kind == VIEW else "│"
        lines.append(f"   {run}{i:>3}. {st.name:<{NAME_WIDTH}} {st.kind:<9}  {st.does:<{DOES_WIDTH}}  {st.where}")
    lines += ["   ▼", DIAGRAM_OUT, "",
              " ┃ per view: view by view, each view through the consecutive per-view stages before the next is read",
              " │ cameras: the cameras alone, before any image;  whole set: every view (or what came before) at once"]
    return "\n".join(line.rstrip() for line in lines)

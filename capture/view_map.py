"""A per-view function over a capture's views, in this process or a pool's (issue 32).

Whole-set steps (extent, photometric, RGBz) do most of their work one view at a time.  Each such
pass is a plain top-level function ``fn(view, position, arg) -> (view or None, note)`` handed to a
``map_views(fn, scans, arg, description) -> (views, notes)``: :func:`serial_map` here, or the
pipeline runner's map over its worker processes (volume/pipeline/runner.py), which gives the
same views and notes in the same order.  A view the function leaves unchanged comes back as None
(nothing is written or sent back); a changed view goes through ``keep`` (capture.scan_store).

``arg`` is given to every view, or, as a :class:`PerView`, one item per view (what only that view
needs: its neighbours' scans, its plate), so that a worker is sent no more than its view needs.
"""

from __future__ import annotations

from dataclasses import dataclass

from capture.scan_store import keep_in_memory


@dataclass(frozen=True)
class PerView:
    """A map's argument given view by view: ``items[k]`` goes to view k."""

    items: tuple

    def __post_init__(self) -> None:
        object.__setattr__(self, "items", tuple(self.items))


def arg_of(arg, k: int):
    """The argument view ``k`` gets (module docstring)."""
    return arg.items[k] if isinstance(arg, PerView) else arg


def serial_map(fn, scans, arg, description: str = "", keep=None, refs=None, progress=None):
    """``fn(view, ref, arg) -> (view or None, note)`` over ``scans`` in this process, each changed
    view through ``keep`` (default: kept in memory); ``refs`` default the positions; ``progress(items,
    description)`` a progress bar or None; (views, notes)."""
    keep = keep or keep_in_memory
    out, notes = [], []
    for k, s in enumerate(progress(scans, description) if progress else scans):
        v, n = fn(s, k if refs is None else refs[k], arg_of(arg, k))
        out.append(s if v is None else keep(v))
        notes.append(n)
    return tuple(out), notes


def or_serial(map_views, keep=None, progress=None):
    """``map_views``, or :func:`serial_map` with ``keep`` and ``progress`` when None."""
    if map_views is not None:
        return map_views
    return lambda fn, scans, arg, description="": serial_map(fn, scans, arg, description, keep, progress=progress)

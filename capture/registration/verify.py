"""Never worse than the input (issues 22, 31): a view keeps its registered pose only when that
explains the data significantly better than its input pose, by the independent check's evidence
(``check``); else it keeps its input pose, and the report says why with the numbers.

Agreement with placed neighbours is not proof: a group of views placed wrong together agrees with
itself (issue 31: a uniform fur ball, 8 views at other views' angles, all "consistent").  So the
comparison is always relative to the input pose, against the same neighbours:

1. Every view is scored at its registered pose and at its input pose against its neighbours
   where the result puts them (``check.view_tiles``), tile by tile.
2. It takes the registered pose when the tile differences' paired t is at least ``T_BETTER``
   (the margin is the capture's own noise: fur and leaves differ by orders of magnitude), and
   the co-visible evidence is enough (``check.MIN_COVISIBLE``).
3. A view going back to its input pose moves its neighbours' reference: the result is judged
   again until no view changes (``MAX_ROUNDS``).

Views the registration did not place (flagged by their solver, with its reason) keep their input
pose.  Exact input poses come back unchanged: a registered pose has to *win*.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from capture.registration import check as C
from capture.registration.angles import paired_t

REGISTERED = "registered"
KEPT = "kept at input"
FLAGGED = "flagged"
#: The registered pose replaces the input pose when it scores better by this many standard errors
#: (paired t over the image tiles of the view's pairs, both directions).
T_BETTER = 3.0
#: Rounds of re-judging the result.
MAX_ROUNDS = 3


@dataclass
class Comparison:
    """The check's comparison of one view's registered and input poses (same neighbours)."""

    registered_score: float
    """Mean pair score at the registered pose (agreement fraction + ``COLOUR_WEIGHT`` * NCC)."""
    input_score: float
    """... and at the input pose."""
    t: float
    """Paired t of the tile scores, registered minus input (positive: the registered pose is better)."""
    tiles: int
    """Tiles with evidence at either pose."""
    covisible: int
    """Agreeing samples at the registered pose over all neighbours."""

    @property
    def better(self) -> bool:
        return self.covisible >= C.MIN_COVISIBLE and self.t >= T_BETTER

    def to_json(self) -> dict:
        t = self.t if math.isfinite(self.t) else (1e9 if self.t > 0 else -1e9)
        return {"registered_score": round(self.registered_score, 5), "input_score": round(self.input_score, 5),
                "t": round(t, 2), "tiles": self.tiles, "covisible": self.covisible, "better": self.better}


@dataclass
class ViewVerdict:
    """What the check decided for one view."""

    status: str
    """``REGISTERED``, ``KEPT`` or ``FLAGGED``."""
    reason: str
    comparison: Comparison | None = None

    def to_json(self) -> dict:
        return {"status": self.status, "reason": self.reason,
                **({"comparison": self.comparison.to_json()} if self.comparison else {})}


@dataclass
class Verification:
    """Result of :func:`verify`."""

    poses: list[np.ndarray]
    """cam_from_world per view (views not registered: their input pose)."""
    verdicts: list[ViewVerdict]
    notes: list[str] = field(default_factory=list)

    @property
    def placed(self) -> list[bool]:
        return [v.status != FLAGGED for v in self.verdicts]

    @property
    def improved(self) -> bool:
        """True when at least one view took its registered pose."""
        return any(v.status == REGISTERED for v in self.verdicts)


def compare(views, k: int, registered: np.ndarray, nominal: np.ndarray, poses: list, nbrs: list[int],
            size: float) -> Comparison:
    """View k at its ``registered`` and ``nominal`` pose against ``nbrs`` at ``poses``."""
    a = C.view_tiles(views, k, registered, poses, nbrs, size)
    b = C.view_tiles(views, k, nominal, poses, nbrs, size)
    live = (a != 0) | (b != 0)
    sa, m = C.view_score(views, k, registered, poses, nbrs, size)
    sb, _ = C.view_score(views, k, nominal, poses, nbrs, size)
    return Comparison(sa, sb, paired_t(a[live], b[live]), int(live.sum()), m)


def _reason(c: Comparison) -> str:
    if c.covisible < C.MIN_COVISIBLE:
        return f"too little co-visible surface to judge it ({c.covisible} samples): kept at its input pose"
    return (f"the registered pose does not explain the data significantly better than the input pose "
            f"(t = {c.t:.1f} < {T_BETTER:g}; scores {c.registered_score:.3f} vs {c.input_score:.3f})")


def verify(views: list[C.CheckView], nominal: list[np.ndarray], registered: list[np.ndarray], placed: list[bool],
           centre: np.ndarray, size: float) -> Verification:
    """Decide per view between its input (``nominal``) and ``registered`` pose (module docstring)."""
    n = len(nominal)
    use = [k for k in range(n) if placed[k] and not np.allclose(registered[k], nominal[k], atol=1e-12)]
    status = {k: REGISTERED for k in use}
    comp: dict = {}
    for _ in range(MAX_ROUNDS):
        poses = [registered[k] if status.get(k) == REGISTERED else nominal[k] for k in range(n)]
        nb = C.neighbours(poses, centre)
        changed = False
        for k in [k for k in use if status[k] == REGISTERED]:
            comp[k] = compare(views, k, registered[k], nominal[k], poses, nb[k], size)
            if not comp[k].better:
                status[k] = KEPT
                changed = True
        if not changed:
            break
    poses = [registered[k] if status.get(k) == REGISTERED else nominal[k] for k in range(n)]
    verdicts = []
    for k in range(n):
        if not placed[k]:
            verdicts.append(ViewVerdict(FLAGGED, "the registration did not place it: kept at its input pose"))
        elif k not in status:
            verdicts.append(ViewVerdict(KEPT, "the registration left it at its input pose"))
        elif status[k] == REGISTERED:
            c = comp[k]
            verdicts.append(ViewVerdict(REGISTERED, f"explains the data better than the input pose (t = {c.t:.1f}; "
                                        f"scores {c.registered_score:.3f} vs {c.input_score:.3f})", c))
        else:
            verdicts.append(ViewVerdict(KEPT, _reason(comp[k]), comp[k]))
    notes = [f"independent check: {sum(v.status == REGISTERED for v in verdicts)} views explain the data "
             f"better than at their input pose (t >= {T_BETTER:g})"]
    return Verification(poses, verdicts, notes)

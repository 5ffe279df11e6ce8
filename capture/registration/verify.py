"""Never worse than the input (issue 22): every view keeps the pose that the independent check
(``check``) finds consistent, the registered one or the nominal (input) one, or is flagged.

1. Every view is judged at its nominal pose among the nominal poses, and (when the registration
   placed it) at its registered pose among the registered poses.
2. A view takes its registered pose when that is consistent and the nominal one is not, or scores
   better by ``PREFER_MARGIN``; else its nominal pose when that is consistent; else it is flagged.
   (Exact input poses therefore come back unchanged: the registered pose has to *win*.)
3. The mixed result is judged again, each placed view against its placed neighbours, until no
   view changes (``MAX_ROUNDS``): a view that is not consistent there (or scores below
   ``MIN_RELATIVE_SCORE`` of the consistent views' median) tries its other pose, else is flagged.
4. Across the capture the result is never worse than the input on that evidence: when fewer
   views are consistent in the result than among the nominal poses, every view goes back to its
   nominal judgement.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from capture.registration import check as C

REGISTERED = "registered"
KEPT = "kept nominal"
FLAGGED = "flagged"
#: The registered pose replaces a consistent nominal one only when it scores better by this much.
PREFER_MARGIN = 0.01
#: Rounds of re-judging the mixed result.
MAX_ROUNDS = 3
#: In the mixed result a placed view must also score at least this fraction of the median score
#: of the consistent views: a pose far off can sit on a flat stretch of the score (fur, 3 degrees
#: out: 0.26-0.30 against 0.39-0.56 at the true poses), where no probe beats it.
MIN_RELATIVE_SCORE = 0.7


@dataclass
class ViewVerdict:
    """What the check decided for one view."""

    status: str
    """``REGISTERED``, ``KEPT`` or ``FLAGGED``."""
    reason: str
    nominal: C.Judgement | None = None
    registered: C.Judgement | None = None
    final: C.Judgement | None = None
    """The judgement of the kept pose among the final poses."""

    def to_json(self) -> dict:
        return {"status": self.status, "reason": self.reason,
                **{k: getattr(self, k).to_json() for k in ("nominal", "registered", "final") if getattr(self, k)}}


@dataclass
class Verification:
    """Result of :func:`verify`."""

    poses: list[np.ndarray]
    """cam_from_world per view (flagged views: their nominal pose)."""
    verdicts: list[ViewVerdict]
    consistent_nominal: int
    """Views consistent among the nominal poses."""
    consistent_final: int
    """Views consistent (and placed) in the result."""
    notes: list[str] = field(default_factory=list)

    @property
    def placed(self) -> list[bool]:
        return [v.status != FLAGGED for v in self.verdicts]

    @property
    def improved(self) -> bool:
        """True when at least one view took its registered pose."""
        return any(v.status == REGISTERED for v in self.verdicts)


def _judge_all(views, poses, mask, centre, size, which=None) -> list[C.Judgement | None]:
    use = [k for k in range(len(poses)) if mask[k]]
    nb_all = C.neighbours([poses[k] for k in use], centre)
    out: list = [None] * len(poses)
    for a, k in enumerate(use):
        if which is not None and k not in which:
            continue
        out[k] = C.judge(views, k, poses[k], poses, [use[b] for b in nb_all[a]], centre, size)
    return out


def _first_choice(jn: C.Judgement, jr: C.Judgement | None) -> tuple[str, str]:
    if jr is not None and jr.consistent and (not jn.consistent or jr.score > jn.score + PREFER_MARGIN):
        why = "the nominal pose is not consistent" if not jn.consistent else \
            f"consistent, scores {jr.score - jn.score:+.3f} over the nominal pose"
        return REGISTERED, why
    if jn.consistent:
        why = "the registration did not place it" if jr is None else (
            "the registered pose is not consistent with its neighbours" if not jr.consistent else
            f"the registered pose scores no better ({jr.score - jn.score:+.3f})")
        return KEPT, why
    return FLAGGED, _flag_reason(jn, jr)


def _flag_reason(jn: C.Judgement, jr: C.Judgement | None) -> str:
    def one(j: C.Judgement) -> str:
        if j.covisible < C.MIN_COVISIBLE:
            return f"too little co-visible surface ({j.covisible} samples)"
        return (f"a pose {C.PROBE_DEG:g} deg / {100 * C.PROBE_FRAC:g} % away fits better "
                f"({j.best_probe:.3f} > {j.score:.3f})")
    text = "neither pose is consistent with its neighbours: nominal: " + one(jn)
    return text + ("; registered: " + one(jr) if jr is not None else "; the registration did not place it")


def verify(views: list[C.CheckView], nominal: list[np.ndarray], registered: list[np.ndarray], placed: list[bool],
           centre: np.ndarray, size: float) -> Verification:
    """Decide per view between its nominal and registered pose (see the module docstring)."""
    n = len(nominal)
    jn = _judge_all(views, nominal, [True] * n, centre, size)
    jr = _judge_all(views, registered, placed, centre, size)
    choice = [_first_choice(jn[k], jr[k]) for k in range(n)]
    status = [c[0] for c in choice]
    reason = [c[1] for c in choice]
    final: list = [None] * n
    for _ in range(MAX_ROUNDS):
        poses = [registered[k] if status[k] == REGISTERED else nominal[k] for k in range(n)]
        final = _judge_all(views, poses, [s != FLAGGED for s in status], centre, size)
        good = [final[k].score for k in range(n) if status[k] != FLAGGED and final[k].consistent]
        floor = MIN_RELATIVE_SCORE * float(np.median(good)) if good else 0.0
        changed = False
        for k in range(n):
            if status[k] == FLAGGED or (final[k].consistent and final[k].score >= floor):
                continue
            changed = True
            other = nominal[k] if status[k] == REGISTERED else (registered[k] if placed[k] else None)
            if other is not None:
                alt = _judge_all(views, [other if b == k else poses[b] for b in range(n)],
                                 [s != FLAGGED for s in status], centre, size, which={k})[k]
                if alt.consistent and alt.score >= floor:
                    status[k] = KEPT if status[k] == REGISTERED else REGISTERED
                    reason[k] = "the other pose is not consistent with its placed neighbours"
                    continue
            status[k] = FLAGGED
            reason[k] = (f"not consistent with its placed neighbours (a pose {C.PROBE_DEG:g} deg away fits better: "
                         f"{final[k].best_probe:.3f} > {final[k].score:.3f})" if not final[k].consistent else
                         f"scores {final[k].score:.3f} against its placed neighbours, below {MIN_RELATIVE_SCORE:g} "
                         f"of the consistent views' median")
        if not changed:
            break
    poses = [registered[k] if status[k] == REGISTERED else nominal[k] for k in range(n)]
    if changed:  # the last round changed something: judge the result as it stands
        final = _judge_all(views, poses, [s != FLAGGED for s in status], centre, size)
    n_nom = sum(j.consistent for j in jn)
    n_fin = sum(status[k] != FLAGGED and final[k] is not None and final[k].consistent for k in range(n))
    notes = []
    if n_fin < n_nom:
        notes.append(f"fewer views consistent after registration ({n_fin}) than at the input poses ({n_nom}): "
                     "every view keeps its nominal judgement")
        status = [KEPT if j.consistent else FLAGGED for j in jn]
        reason = ["the registration as a whole is less consistent than the input" if j.consistent else
                  _flag_reason(j, None) for j in jn]
        poses, final, n_fin = list(nominal), jn, n_nom
    verdicts = [ViewVerdict(status[k], reason[k], jn[k], jr[k], final[k]) for k in range(n)]
    return Verification(poses, verdicts, n_nom, n_fin, notes)

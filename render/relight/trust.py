"""Whether the transfer fitted to the capture can be trusted for a new light (issue 31), and what to
relight with when it cannot: the fitted transfer, the physical default, or the single global gain.

The fit (render.relight.calibrate) sees the object under one light A only.  Several transfers explain
the capture views equally well (``TransferFit.plausible``: within noise of the best on views they did
not see); a new light B that resembles A relights them all alike, one that asks for what A never
showed -- light from directions A left dark, a sun where A was a sky -- can tell them apart, and the
capture cannot say which is right.  So for B:

1. **What B asks beyond the evidence** (:func:`dark_shares`): per orientation region of the object
   (top, bottom, four sides), the share of B's light on it (weighted by the wrap kernel) that comes from
   directions where A's radiance is below :data:`DARK_FRACTION` of its mean -- light the capture never
   showed the object in.
2. **How far the equally good transfers disagree about B** (:func:`choose_transfer`): each plausible
   transfer's relit luminance gain at the capture's points and views; the spread is the largest RMS
   log difference between the taken transfer and another plausible one.
3. **Decision** (minimax).  Of the fitted transfer, the default and the single global gain, the one
   whose largest RMS log difference to the transfers the capture cannot rule out is smallest (for
   the fitted one that is the spread); the fitted one whenever its spread is within
   :data:`SPREAD_MAX`; a tie goes to the fallback.  So the fit is kept while it is the safest guess the
   evidence allows, and
   replaced by the prior (the default) or by doing nothing (the gain) when one of those is nearer to
   everything the capture leaves possible -- when B asks what the capture could not show.

Luminance only, like the fit; the per-channel gains of the pass follow the chosen transfer.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from render.relight import calibrate as cb
from render.shading import transfer as rl

#: Capture-map radiance below this fraction of its mean (at DARK_ROWS rows) counts as dark.
DARK_FRACTION = 0.1
#: Rows of the coarse maps the dark directions are judged on (pixels of 180 / DARK_ROWS degrees).
DARK_ROWS = 16
#: The fitted transfer is trusted while every plausible transfer relights within this RMS log
#: luminance of it (about 10 %).
SPREAD_MAX = 0.1
#: Capture points the spread is evaluated at (a seeded subsample).
SPREAD_POINTS = 4000
#: Plausible transfers compared at most (the nearest the default first).
MAX_COMPARED = 40
SEED = 1
#: Orientation regions of the object in the maps' frame (up = +z): name -> test on unit normals (P, 3).
REGIONS = {
    "top": lambda n: n[:, 2] > 0.5,
    "bottom": lambda n: n[:, 2] < -0.5,
    "side +x": lambda n: (np.abs(n[:, 2]) <= 0.5) & (np.abs(n[:, 0]) >= np.abs(n[:, 1])) & (n[:, 0] > 0),
    "side -x": lambda n: (np.abs(n[:, 2]) <= 0.5) & (np.abs(n[:, 0]) >= np.abs(n[:, 1])) & (n[:, 0] <= 0),
    "side +y": lambda n: (np.abs(n[:, 2]) <= 0.5) & (np.abs(n[:, 0]) < np.abs(n[:, 1])) & (n[:, 1] > 0),
    "side -y": lambda n: (np.abs(n[:, 2]) <= 0.5) & (np.abs(n[:, 0]) < np.abs(n[:, 1])) & (n[:, 1] <= 0),
}
#: Where the chosen transfer came from.
SOURCES = ("fitted", "default", "gain")


@dataclass(frozen=True)
class RelightChoice:
    """The transfer to relight with: ``kernel``, ``forward`` (beta), ``forward_g``; ``source`` one of
    :data:`SOURCES`; ``reason`` one line saying why; ``spread`` the plausible transfers' largest RMS log
    disagreement with the fitted one under the new light; ``worst`` per fallback ("default", "gain") its
    largest RMS log difference to the plausible transfers; ``dark`` per region of the object the share of
    the new light from directions the capture light left dark (regions the capture did not see omitted)."""

    kernel: str
    forward: float
    forward_g: float
    source: str
    reason: str
    spread: float = 0.0
    worst: dict = field(default_factory=dict)
    dark: dict = field(default_factory=dict)

    def record(self) -> dict:
        return {"kernel": self.kernel, "forward": self.forward, "forward_g": self.forward_g, "source": self.source,
                "reason": self.reason, "spread": round(self.spread, 4),
                "worst": {k: round(v, 4) for k, v in self.worst.items()},
                "dark": {k: round(v, 3) for k, v in self.dark.items()}}


def _luminance_map(env, rows: int):
    """(directions (R, 3) in the map's frame, luminance radiance x solid angle (R,)) of ``env`` at ``rows``."""
    small = env.resized(rows)
    d = small.pixel_directions().reshape(-1, 3)
    return d, (small.data.astype(np.float64) @ cb.LUMA).reshape(-1) * small.pixel_solid_angles().reshape(-1)


def dark_shares(capture_env, new_env, up, normals) -> dict:
    """Per region of :data:`REGIONS` (world unit ``normals`` (P, 3) of the object's points, turned into the
    maps' frame by ``up``): the share of the new map's wrap-weighted light on those points from directions
    where the capture map's radiance is below DARK_FRACTION of its mean (module doc, step 1)."""
    da, pa = _luminance_map(capture_env, DARK_ROWS)
    db, pb = _luminance_map(new_env, DARK_ROWS)
    omega = capture_env.resized(DARK_ROWS).pixel_solid_angles().reshape(-1)
    dark = pa / omega < DARK_FRACTION * pa.sum() / omega.sum()
    n = np.asarray(normals, np.float64) @ rl.world_to_env(up).T
    k = np.maximum(n @ db.T + 0.5, 0.0) / 1.5
    share = (k[:, dark] @ pb[dark]) / np.maximum(k @ pb, 1e-30)
    return {name: float(share[test(n)].mean()) for name, test in REGIONS.items() if test(n).any()}


def _log_gains(cands, a, b, regularise: float) -> np.ndarray:
    """(C, P) luminance log gain B / A of each candidate (kernel, beta, g) from per-basis transfers ``a``,
    ``b`` (calibrate.basis_transfers' (E, F, refs))."""
    out = []
    for kernel, beta, g in cands:
        w = rl.mix_weights(kernel)
        gi = cb.FORWARD_GS.index(g)
        t = []
        for e, f, refs in (a, b):
            fw = np.einsum("j,jp->p", w, f[:, gi]) if beta else 0.0
            t.append(w @ e + beta * fw + regularise * (1 + beta) * float(w @ refs))
        out.append(np.log(np.maximum(t[1], 1e-30)) - np.log(np.maximum(t[0], 1e-30)))
    return np.asarray(out)


def _subsample(samples: cb.CaptureSamples, n: int) -> cb.CaptureSamples:
    ok = np.flatnonzero(np.linalg.norm(samples.normals, axis=1) > 0.5)
    if len(ok) > n:
        ok = np.sort(np.random.default_rng(SEED).choice(ok, n, replace=False))
    return cb.CaptureSamples(samples.points[ok], samples.views[ok], samples.normals[ok], samples.luminance[ok],
                             samples.view_index[ok])


def choose_transfer(fit: cb.TransferFit, samples: cb.CaptureSamples, capture_env, new_env, up, capture_sg=None,
                    new_sg=None, regularise: float = rl.REGULARISE) -> RelightChoice:
    """The transfer to relight ``samples``' object from ``capture_env`` to ``new_env`` with (module doc):
    ``fit`` the capture's TransferFit; ``capture_sg`` / ``new_sg`` the maps' SG fits when already made."""
    from render.shading.sg_fit import fit_env_sg

    sub = _subsample(samples, SPREAD_POINTS)
    if not len(sub.points):
        return RelightChoice(*fit.candidate, "fitted", "no capture point with an orientation to compare at")
    capture_sg = fit_env_sg(capture_env, rl.RELIGHT_SG_K) if capture_sg is None else capture_sg
    new_sg = fit_env_sg(new_env, rl.RELIGHT_SG_K) if new_sg is None else new_sg
    basis = tuple(rl.MIX_BASIS)
    a = cb.basis_transfers(sub, capture_env, up, capture_sg, basis)[:3]
    b = cb.basis_transfers(sub, new_env, up, new_sg, basis)[:3]
    plaus = [c for c in fit.plausible[:MAX_COMPARED]]
    extra = [cb.key(*cb.DEFAULT_TRANSFER), cb.key(*cb.GAIN_TRANSFER)]
    lg = _log_gains(plaus + extra, a, b, regularise)
    rms = lambda x, y: float(np.sqrt(np.mean((x - y) ** 2)))
    chosen = lg[plaus.index(fit.candidate)] if fit.candidate in plaus else _log_gains([fit.candidate], a, b,
                                                                                      regularise)[0]
    spread = max(rms(chosen, p) for p in lg[:len(plaus)])
    worst = {name: max(rms(q, p) for p in lg[:len(plaus)]) for name, q in zip(("default", "gain"), lg[len(plaus):])}
    dark = dark_shares(capture_env, new_env, up, sub.normals)
    return _decide(fit, spread, worst, dark)


def _decide(fit: cb.TransferFit, spread: float, worst: dict, dark: dict) -> RelightChoice:
    """Module doc, step 3."""
    beyond = max(dark.values()) if dark else 0.0
    where = max(dark, key=dark.get) if dark else ""
    lit = f"(up to {beyond:.0%} of the new light, on the {where}, from directions the capture light left dark)"
    n = len(fit.plausible)
    what = "the default transfer" if fit.is_default else f"the fitted transfer ({fit.kernel}, beta {fit.forward:g})"
    fall = min(worst, key=worst.get)
    if fit.is_default and fall == "default":   # the fit already is the default: nothing to fall back to
        return RelightChoice(*fit.candidate, "default", f"the default transfer: the capture shows none better within "
                             f"noise; the {n} transfers it cannot tell apart relight within {spread:.0%} of it, nearer "
                             f"than the gain (within {worst['gain']:.0%}) {lit}", spread, worst, dark)
    if spread <= SPREAD_MAX or spread < worst[fall]:
        agree = "relight within" if spread <= SPREAD_MAX else "are nearer it than the default or the gain: within"
        return RelightChoice(*fit.candidate, "default" if fit.is_default else "fitted",
                             f"{what}: the {n} transfers the capture cannot tell apart {agree} {spread:.0%} of it "
                             f"{lit}", spread, worst, dark)
    cand = cb.DEFAULT_TRANSFER if fall == "default" else cb.GAIN_TRANSFER
    return RelightChoice(*cand, fall, f"{'the default transfer' if fall == 'default' else 'the single global gain'} "
                         f"instead of {what}: the {n} transfers the capture cannot tell apart disagree with it by up "
                         f"to {spread:.0%} under the new light {lit}; the {fall} is within {worst[fall]:.0%} of all "
                         "of them", spread, worst, dark)

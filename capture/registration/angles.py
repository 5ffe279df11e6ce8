"""Angle hypotheses of the turntable views (issue 31): a view takes the angle its evidence
gives only when that angle is the one clear answer, and it beats the input angle.

A near-symmetric object (one uniform fur coat on a sphere) looks nearly the same from every side:
its evidence fits many angles about as well, and the best of them by a hair can be any of them
(a view placed at another view's angle, 18-57 degrees off, issue 31).  So, per view, with every
other view held where the joint solve put it:

1. the *profile*: the evidence's cost (the solver's own: range surface, chromaticity, SIFT
   matches against the view's ring neighbours) at angles on a grid about the view's input angle,
   within the input's bound (``prior.PosePrior``) and ``ALT_BEYOND_DEG`` beyond it, where the
   other angles that fit as well would be;
2. the *hypotheses*: the profile's local minima (and the solve's own angle);
3. *noise*: two angles are told apart only when one fits better by ``T_SIGNIFICANT`` standard
   errors, a paired t over image tiles (``TILE_PX``): the cost difference of each tile of each
   pair is one sample, so the margin is calibrated on the capture's own noise (fur and leaves
   differ by orders of magnitude);
4. the decision: the angles that fit within noise of the best (hypotheses and grid points alike)
   must form one cluster inside the bound (the prior rules out those beyond it), and the evidence
   must know more than the input: the input angle fits significantly worse than the best, or the
   cluster is narrower than the input angle's own uncertainty (the prior's sigma; then the input
   angle lies within the evidence's band, but the band is the sharper statement).  Otherwise the
   view keeps its input angle, and the record says why with the numbers: several angles fit as
   well, the best fits lie beyond the input's uncertainty, or the evidence is no sharper than the
   input.

A group that agrees with itself is not proof (issue 31): evidence that is biased the same way
between every pair of neighbours (view-dependent sheen on a uniform coat) places each view
consistently with its neighbours, yet the ring as a whole drifts from the truth.  The input errors
of different views are independent (the prior), so before any decision :func:`drift` tests the
solve: a run of ``DRIFT_RUN_FRAC`` of the ring whose angles moved together from their input angles
by more than ``T_DRIFT`` standard errors of independent input errors (sigma / sqrt(run)) shows the
evidence biased, and then every view keeps its input angle.

Costs are truncated squares (``TRUNCATE`` sigmas; an unmatched sample costs the truncation), so
that a sample that finds nothing weighs the same at every angle.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from capture.registration import projective as PR
from capture.sampling import sample_image

#: A residual counts up to this many of its sigmas (squared); an unmatched sample counts that much.
TRUNCATE = 2.5
#: Profile grid step inside the input's bound and beyond it (degrees); the ``MAX_REFINED`` lowest
#: local minima are refined by halving the step down to ``REFINE_DEG``.
STEP_IN_DEG = 0.5
STEP_OUT_DEG = 2.0
REFINE_DEG = 0.25
MAX_REFINED = 5
#: The profile looks this far beyond the input's bound for other angles that fit as well
#: (degrees), and at least ``ALT_RING_STEPS`` ring steps (a view aliased onto a neighbour's angle).
ALT_BEYOND_DEG = 12.0
ALT_RING_STEPS = 1.2
#: ... and never further than this from the input angle (degrees).
MAX_WINDOW_DEG = 45.0
#: Hypotheses closer than this are one (degrees).
SAME_DEG = 0.75
#: One angle fits better than another when its cost is lower by this many standard errors
#: (paired t over the image tiles of the view's pairs).
T_SIGNIFICANT = 3.0
#: Image tile (pixels at 640 across) of the paired test: one cost-difference sample per tile.
TILE_PX = 40
#: Ring neighbours on each side whose pairs enter the profile.
PROFILE_NEIGHBOURS = 2
#: Most source samples per pair in the profile (a regular subsample).
PROFILE_SAMPLES = 3000
#: Feature residual sigma (pixels) of the profile.
FEATURE_SIGMA_PX = 2.0
#: Robust scale (normal sigma per median absolute deviation).
MAD_SIGMA = 1.4826

#: Views in a run of the drift test: this fraction of the ring's views, at least ``DRIFT_RUN_MIN``.
DRIFT_RUN_FRAC = 1 / 6
DRIFT_RUN_MIN = 3
#: A run's mean offset from the input angles beyond this many standard errors is a drift.
T_DRIFT = 5.0

EVIDENCE = "evidence"
INPUT = "input"


@dataclass
class AngleDecision:
    """Where one view's angle comes from.

    Attributes:
        source: ``EVIDENCE`` (the evidence places it) or ``INPUT`` (it keeps its input angle).
        offset_deg: the chosen angle minus the input angle (degrees, after the gauge shift).
        reason: one line with the numbers.
        hypotheses: per hypothesis ``{"offset_deg", "cost_above_best", "t"}`` (t of its cost above the best's).
        input_t: t of the input angle's cost above the best hypothesis'.
    """

    source: str
    offset_deg: float
    reason: str
    hypotheses: list = field(default_factory=list)
    input_t: float = float("nan")

    def to_json(self) -> dict:
        return {"source": self.source, "offset_deg": round(self.offset_deg, 4), "reason": self.reason,
                "input_t": None if not math.isfinite(self.input_t) else round(self.input_t, 2),
                "hypotheses": self.hypotheses}


@dataclass(frozen=True)
class _Direction:
    """One ordered pair of the profile: source samples, their tile, the target frame."""

    src: int
    tgt: int
    samples: PR.Samples
    tiles: np.ndarray
    n_tiles: int


def paired_t(a: np.ndarray, b: np.ndarray) -> float:
    """t of mean(a - b) over the tiles (positive: ``a`` costs more), inf when the tiles agree exactly."""
    d = np.asarray(a, np.float64) - np.asarray(b, np.float64)
    if len(d) < 2:
        return 0.0
    s = float(d.std(ddof=1))
    m = float(d.mean())
    if s == 0:
        return 0.0 if m == 0 else math.copysign(math.inf, m)
    return m / (s / math.sqrt(len(d)))


def _tiles(points: np.ndarray, K: np.ndarray, width: int, height: int) -> tuple[np.ndarray, int]:
    t = max(4, int(round(TILE_PX * width / 640)))
    nx, ny = -(-width // t), -(-height // t)
    z = np.maximum(points[:, 2], 1e-9)
    u = np.clip((K[0, 0] * points[:, 0] / z + K[0, 2]) // t, 0, nx - 1).astype(np.int64)
    v = np.clip((K[1, 1] * points[:, 1] / z + K[1, 2]) // t, 0, ny - 1).astype(np.int64)
    return v * nx + u, nx * ny


def _subsample(s: PR.Samples, n: int) -> PR.Samples:
    if len(s.points) <= n:
        return s
    keep = np.linspace(0, len(s.points) - 1, n).astype(np.int64)
    return PR.Samples(s.points[keep], s.normals[keep], s.intensity[keep], s.color_valid[keep])


def neighbours(model, active: list[int], k: int, per_side: int = PROFILE_NEIGHBOURS,
               max_deg: float = 75.0) -> list[int]:
    """The nearest ``per_side`` active views on either side of view ``k`` about the axis."""
    def signed(j):
        return (model.angles[j] - model.angles[k] + math.pi) % (2 * math.pi) - math.pi

    others = [j for j in active if j != k and abs(math.degrees(signed(j))) <= max_deg]
    left = sorted([j for j in others if signed(j) < 0], key=lambda j: -signed(j))[:per_side]
    right = sorted([j for j in others if signed(j) >= 0], key=signed)[:per_side]
    return left + right


class Profile:
    """The evidence cost of view ``k`` over its angle, every other view fixed (see the module
    docstring); :meth:`blocks` gives the per-tile costs at an angle offset."""

    def __init__(self, model, views, matches, k: int, nbrs: list[int], gate: float, sigma_g: float):
        self.model, self.views, self.matches, self.k, self.gate, self.sigma_g = model, views, matches, k, gate, sigma_g
        self.dirs = []
        for j in nbrs:
            for s, t in ((j, k), (k, j)):
                smp = _subsample(views[s].samples[-1], PROFILE_SAMPLES)
                cam = views[s].frame.camera
                tiles, n = _tiles(smp.points, cam.K, cam.width, cam.height)
                self.dirs.append(_Direction(s, t, smp, tiles, n))
        self.sigma_c = self._colour_sigma()

    def _model_at(self, offset_rad: float):
        ang = self.model.angles.copy()
        ang[self.k] += offset_rad
        return replace(self.model, angles=ang)

    def _colour_sigma(self) -> float:
        """Robust scale of the chromaticity residual at the solve's angle (MAD), floored."""
        res = []
        for d in self.dirs:
            T = self.model.relative(d.tgt, d.src)
            good, q, t, n, uv = PR.associate(d.samples.points, d.samples.normals, self.views[d.tgt].frame, T, self.gate)
            ok = good & d.samples.color_valid
            if ok.any():
                f = self.views[d.tgt].frame
                res.append(sample_image(f.intensity, uv[ok, 0], uv[ok, 1], "linear", "clamp") - d.samples.intensity[ok])
        r = np.concatenate(res) if res else np.zeros(0)
        return max(MAD_SIGMA * float(np.median(np.abs(r - np.median(r)))) if len(r) else 0.0, PR.COLOR_HUBER / 4)

    def blocks(self, offset_rad: float) -> np.ndarray:
        """(tiles of all the directions,) truncated cost per image tile at the angle offset."""
        m = self._model_at(offset_rad)
        out = []
        cap = TRUNCATE ** 2
        for d in self.dirs:
            tgt = self.views[d.tgt]
            T = m.relative(d.tgt, d.src)
            good, q, t, n, uv = PR.associate(d.samples.points, d.samples.normals, tgt.frame, T, self.gate)
            r = np.sum(n * (q - t), axis=1) / self.sigma_g
            cost = np.where(good, np.minimum(r * r, cap), cap)
            cv = d.samples.color_valid
            rc = np.full(len(cv), np.inf)
            ok = good & cv
            if ok.any():
                seen = sample_image(tgt.frame.intensity, uv[ok, 0], uv[ok, 1], "linear", "clamp")
                rc[ok] = (seen - d.samples.intensity[ok]) / self.sigma_c
            cost = cost + np.where(cv, np.minimum(rc * rc, cap), 0.0)
            acc = np.bincount(d.tiles, weights=cost, minlength=d.n_tiles)
            acc += self._feature_blocks(d, T)
            out.append(acc)
        return np.concatenate(out) if out else np.zeros(0)

    def _feature_blocks(self, d: _Direction, T: np.ndarray) -> np.ndarray:
        out = np.zeros(d.n_tiles)
        mt = self.matches.get((d.tgt, d.src))
        fs, ft = self.views[d.src].features, self.views[d.tgt].features
        if mt is None or not len(mt) or fs is None or ft is None:
            return out
        p = fs.points[mt[:, 1]]
        x = ft.pixels[mt[:, 0]]
        ok = np.isfinite(p).all(axis=1)
        p, x = p[ok], x[ok]
        q = p @ T[:3, :3].T + T[:3, 3]
        K = self.views[d.tgt].frame.camera.K
        z = np.maximum(q[:, 2], 1e-9)
        uv = np.stack([K[0, 0] * q[:, 0] / z + K[0, 2], K[1, 1] * q[:, 1] / z + K[1, 2]], axis=1)
        r2 = np.sum((uv - x) ** 2, axis=1) / FEATURE_SIGMA_PX ** 2
        cost = np.where(q[:, 2] > 1e-6, np.minimum(r2, TRUNCATE ** 2), TRUNCATE ** 2)
        cam = self.views[d.src].frame.camera
        tiles, _ = _tiles(p, cam.K, cam.width, cam.height)
        return out + np.bincount(tiles, weights=cost, minlength=d.n_tiles)


def grid(bound_deg: float, window_deg: float) -> np.ndarray:
    """Angle offsets (degrees): ``STEP_IN_DEG`` within the bound, ``STEP_OUT_DEG`` beyond it."""
    inner = np.arange(0.0, bound_deg + 1e-9, STEP_IN_DEG)
    outer = np.arange(inner[-1] + STEP_OUT_DEG, window_deg + 1e-9, STEP_OUT_DEG)
    half = np.concatenate([inner, outer])
    return np.unique(np.round(np.concatenate([-half[::-1], half]), 6))


def window(bound_deg: float, ring_step_deg: float) -> float:
    """How far from the input angle the profile looks (degrees; see ``ALT_BEYOND_DEG``)."""
    return min(MAX_WINDOW_DEG, max(bound_deg + ALT_BEYOND_DEG, ALT_RING_STEPS * ring_step_deg))


def _local_minima(x: np.ndarray, c: np.ndarray) -> list[int]:
    idx = []
    for i in range(len(c)):
        left = c[i - 1] if i > 0 else np.inf
        right = c[i + 1] if i + 1 < len(c) else np.inf
        if c[i] <= left and c[i] <= right:
            idx.append(i)
    return idx


def _clusters(offsets: list[float], bound_deg: float) -> list[list[float]]:
    """Runs of offsets no further apart than the grid step where they are (``SAME_DEG`` inside
    the bound, ``STEP_OUT_DEG`` beyond it)."""
    out: list[list[float]] = []
    for o in sorted(offsets):
        gap = SAME_DEG if min(abs(o), abs(out[-1][-1]) if out else abs(o)) <= bound_deg else STEP_OUT_DEG + 1e-6
        if out and o - out[-1][-1] <= gap:
            out[-1].append(o)
        else:
            out.append([o])
    return out


def _profile(profile: Profile, solved_deg: float, bound_deg: float, window_deg: float):
    """(grid offsets, their tile costs, candidate offset -> tile costs): the grid, its local minima
    refined (the lowest ``MAX_REFINED``) and the solve's own angle."""
    base = math.radians(solved_deg)
    xs = grid(bound_deg, window_deg)
    B = np.array([profile.blocks(math.radians(x) - base) for x in xs])
    Bs = profile.blocks(0.0)
    live = (np.ptp(np.vstack([B, Bs[None]]), axis=0) > 0) if len(B) else np.zeros(0, bool)
    B, Bs = B[:, live], Bs[live]
    cost = B.sum(axis=1)
    minima = sorted(_local_minima(xs, cost), key=lambda i: cost[i])
    cand = {float(xs[i]): B[i] for i in minima}
    for i in minima[:MAX_REFINED]:
        x, b = float(xs[i]), B[i]
        h = (STEP_IN_DEG if abs(x) <= bound_deg else STEP_OUT_DEG) / 2
        while h >= REFINE_DEG - 1e-9:
            for y in (x - h, x + h):
                by = profile.blocks(math.radians(y) - base)[live]
                if by.sum() < b.sum():
                    x, b = y, by
            h /= 2
        cand[x] = b
    cand[float(solved_deg)] = Bs
    return xs, B, cand


def decide(profile: Profile, solved_deg: float, bound_deg: float, window_deg: float,
           sigma_deg: float) -> AngleDecision:
    """Where view ``profile.k``'s angle comes from (the module docstring's step 4).

    ``solved_deg``: the joint solve's angle minus the input angle; offsets are relative to the
    input angle (the profile's model holds the solved angle, so it is shifted by ``-solved_deg``).
    ``sigma_deg``: the input angle's own uncertainty (the prior's sigma): evidence that fits a band
    of angles no narrower than that, the input angle among them, cannot beat the input.
    """
    xs, B, cand = _profile(profile, solved_deg, bound_deg, window_deg)
    best = min(cand, key=lambda o: cand[o].sum())
    t_in = paired_t(B[int(np.argmin(np.abs(xs)))], cand[best])  # the input angle (the grid holds 0)
    hyp = sorted(({"offset_deg": round(o, 3), "cost_above_best": round(float(b.sum() - cand[best].sum()), 2),
                   "t": round(paired_t(b, cand[best]), 2) if o != best else 0.0} for o, b in cand.items()),
                 key=lambda h: h["cost_above_best"])[:6]
    close = [o for o, b in cand.items() if o == best or paired_t(b, cand[best]) < T_SIGNIFICANT]
    close += [float(x) for x, b in zip(xs, B) if paired_t(b, cand[best]) < T_SIGNIFICANT]
    groups = _clusters(close, bound_deg)
    inside = [g for g in groups if any(abs(o) <= bound_deg for o in g)]
    listed = ", ".join(f"{g[0]:+.2f}" if len(g) == 1 else f"{g[0]:+.2f}..{g[-1]:+.2f}" for g in groups[:6])
    if not inside:
        why = f"the angles that fit best ({listed} deg) lie beyond the input's uncertainty ({bound_deg:.2f} deg)"
        return AngleDecision(INPUT, 0.0, why, hyp, t_in)
    if len(inside) > 1:
        why = f"{len(inside)} angles within the input's uncertainty fit within noise of each other ({listed} deg)"
        return AngleDecision(INPUT, 0.0, why, hyp, t_in)
    group = inside[0]
    chosen = solved_deg if any(abs(o - solved_deg) <= SAME_DEG for o in group) else \
        min((o for o in group if o in cand), key=lambda o: cand[o].sum(), default=best)
    width = max(abs(o - chosen) for o in group)
    if t_in < T_SIGNIFICANT and width >= sigma_deg:
        why = (f"the input angle fits within noise of the best ({best:+.2f} deg, t = {t_in:.1f} < {T_SIGNIFICANT:g}), "
               f"and the evidence fits a band of +-{width:.2f} deg, no sharper than the input's {sigma_deg:.2f} deg")
        return AngleDecision(INPUT, 0.0, why, hyp, t_in)
    why = (f"one angle fits: {chosen:+.2f} deg from the input (to +-{width:.2f} deg), the input angle "
           + (f"worse by t = {t_in:.1f}" if t_in >= T_SIGNIFICANT else
              f"within that band (t = {t_in:.1f}) but the input is only good to {sigma_deg:.2f} deg")
           + (f"; beyond the input's uncertainty also {listed} deg (ruled out by it)" if len(groups) > 1 else ""))
    return AngleDecision(EVIDENCE, float(chosen), why, hyp, t_in)


def drift(offsets_deg: np.ndarray, order: list[int], sigma_deg: float) -> tuple[float, list[int], float]:
    """The run of consecutive views (in ring ``order``) whose mean offset from the input angles is the
    largest in standard errors of independent input errors of ``sigma_deg``: (z, its views, its
    mean offset in degrees).  ``offsets_deg`` is indexed by view and has the common shift removed."""
    n = len(order)
    w = min(n, max(DRIFT_RUN_MIN, int(round(DRIFT_RUN_FRAC * n))))
    if n < DRIFT_RUN_MIN or not sigma_deg > 0:
        return 0.0, [], 0.0
    best = (0.0, [], 0.0)
    for start in range(n if w < n else 1):
        run = [order[(start + i) % n] for i in range(w)]
        m = float(np.mean(offsets_deg[run]))
        z = abs(m) / (sigma_deg / math.sqrt(w))
        if z > best[0]:
            best = (z, run, m)
    return best

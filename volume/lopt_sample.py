"""Eq. 1 on a sparse sample of a fine level: decide L_opt without fusing that level (issue 24).

Eq. 1 (volume.pyramid) asks, from L_max down, whether the flagged fraction N_i / L^3 of a level
is <= t.  On fur and needles the answer at L_max = 256 is "no" (L_opt = 8 on every such capture
measured), yet the full 256^3 fusion was run only to read that answer.  Here the finest level's
question is answered from a uniform sample of its candidate voxels instead:

* the candidates are the fine voxels the coarse-to-fine fusion evaluates at all (near the
  coarser level's surface or its near samples, volume.fusion.carve_field): a measured voxel, and
  so a flagged one, is always among them;
* for each sampled voxel and its six face neighbours, pass 1 (near samples) and pass 2 (the
  nearest-surface cluster, without quorum) are run exactly as the full fusion runs them: a
  voxel's measured value depends on that voxel alone, so "flagged" is exact per sampled voxel;
* the sample is drawn as whole BRICK^3 bricks of voxels (bricks holding a candidate, uniformly
  without replacement), evaluated with a one-voxel shell, brick by brick: the fusion's lookups
  stay coherent in the images (scattered single voxels cost a cache miss per scan each, as much
  as the full fusion of the level).  The flagged voxels per brick, k_b, estimate
  N_i = (bricks) x mean(k_b); the interval is mean +- Z_SCORE standard errors of the brick means
  (the brick is the sampling unit, so the correlation of neighbouring voxels is accounted for;
  without replacement only narrows it).  It either lies wholly on one side of t, and the level is decided,
  or, when the estimate is above t (the level would be skipped), the sample grows (EQ1_GROWTH,
  up to EQ1_MAX_SAMPLES) and is drawn again; still undecided (or the estimate is <= t: the level
  will probably be kept, and then it is fused anyway), the level is fused in full and decided
  exactly.

So the decision differs from the full fusion's only with the probability of a Z_SCORE-sigma
event (below 1e-6 at 5 sigma); tests/volume/test_lopt_sample.py compares the two on scenes with
L_opt = 8, 64 and 256.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from volume.fusion import (
    COARSE_MARGIN_VOXELS,
    PROJ_FACTOR,
    FusedSdf,
    FusionConfig,
    _centers_of,
    carve_votes,
    consensus_band,
    prepare_maps,
    upsample2,
)

#: Candidate voxels sampled first (with their six neighbours: 7x as many voxels evaluated)...
EQ1_SAMPLES = 20000
#: ...then EQ1_GROWTH times more while undecided, up to EQ1_MAX_SAMPLES (a fraction close to t
#: needs more samples; past that the full fusion decides).
EQ1_GROWTH = 4
EQ1_MAX_SAMPLES = 320000
#: Standard deviations of the Wilson interval that must clear the threshold to decide.
Z_SCORE = 5.0
#: Side (voxels) of the bricks sampled: whole bricks keep the fusion's image lookups coherent.
BRICK = 4
#: Seed of the sample (the decision is reproducible).
SAMPLE_SEED = 0
_OFFSETS = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], np.int64)


@dataclass(frozen=True)
class SampledEq1:
    """Eq. 1 on a sample of one level.

    Attributes:
        resolution: L.
        fraction: estimated N_i / L^3; low, high: its Z_SCORE-sigma interval.
        candidates: C, voxels the fusion would evaluate; samples: m; flagged: k.
        decided: True when the interval lies on one side of t (then ``passes`` is exact with
            probability 1 - P(Z_SCORE sigma)); passes: fraction <= t.
    """

    resolution: int
    fraction: float
    low: float
    high: float
    candidates: int
    samples: int
    flagged: int
    decided: bool
    passes: bool

    def record(self) -> dict:
        return {"fraction": float(self.fraction), "low": float(self.low), "high": float(self.high),
                "candidates": int(self.candidates), "samples": int(self.samples), "flagged": int(self.flagged),
                "decided": bool(self.decided), "passes": bool(self.passes)}


def candidates(coarse: FusedSdf, trunc: float) -> np.ndarray:
    """Flat indices of the fine voxels volume.fusion.carve_field evaluates below ``coarse``."""
    keep = (np.abs(coarse.values) <= COARSE_MARGIN_VOXELS * coarse.voxel_size + trunc) | coarse.near_mask
    return np.nonzero(upsample2(keep).reshape(-1))[0]


def measured_at(maps, origin, w: float, L: int, cfg: FusionConfig, flat: np.ndarray, cand_mask) -> tuple:
    """(measured (M,) bool, value (M,) float32) of the fused level at voxels ``flat``, as
    volume.fusion.fuse_consensus computes FusedSdf.measured / measured_mask there."""
    trunc = cfg.trunc(w)
    ok = cand_mask(flat)
    meas = np.zeros(len(flat), bool)
    val = np.zeros(len(flat), np.float32)
    idx = np.nonzero(ok)[0]
    if not len(idx):
        return meas, val
    _, _, _, seen, near = carve_votes(maps, origin, w, L, trunc, cfg.agree(w), flat[idx], None, cfg.backend)
    sel = idx[near > 0]
    if not len(sel):
        return meas, val
    n_obs = seen[near > 0].astype(np.int32)
    if cfg.backend == "numba":
        from volume.fusion_jit import consensus_jit

        _, _, _, has1, val1 = consensus_jit(maps, flat[sel], origin, w, L, n_obs, trunc, PROJ_FACTOR, cfg.agree(w),
                                            cfg.agree_normal_deg, cfg.quorum)
    else:
        _, _, _, has1, val1 = consensus_band(maps, _centers_of(flat[sel], origin, w, L), trunc, cfg, w, n_obs)
    meas[sel] = has1
    val[sel] = val1
    return meas, val


def sampled_eq1(maps, coarse: FusedSdf, origin, extent: float, L: int, cfg: FusionConfig, alpha: float, t: float,
                n_samples: int = EQ1_SAMPLES, z: float = Z_SCORE, seed: int = SAMPLE_SEED,
                max_samples: int = EQ1_MAX_SAMPLES) -> SampledEq1:
    """Eq. 1 of level L (on the cube origin + [0, extent]^3) from samples of ``n_samples``
    growing to ``max_samples`` while undecided (module docstring); ``coarse`` is the completed level L/2."""
    if coarse.resolution * 2 != L or coarse.values is None:
        raise ValueError("sampled_eq1 needs the completed level L/2 below L")
    maps = prepare_maps(maps, cfg.backend)
    origin = np.asarray(origin, np.float64)
    w = extent / L
    cand = candidates(coarse, cfg.trunc(w))
    in_cand = np.zeros(L ** 3, bool)
    in_cand[cand] = True
    m = int(n_samples)
    while True:
        s = _sample_once(maps, cand, in_cand, origin, w, L, cfg, alpha, t, m, z, seed)
        # grow only while the sample points to skipping the level: a level Eq. 1 may keep is
        # fused in full anyway, so more samples would only add to its cost
        if s.decided or s.fraction <= t or s.samples >= len(cand) or m >= max_samples:
            return s
        m = min(m * EQ1_GROWTH, int(max_samples))


def _sample_once(maps, cand, in_cand, origin, w: float, L: int, cfg: FusionConfig, alpha: float, t: float,
                 n_samples: int, z: float, seed: int) -> SampledEq1:
    """One draw of about ``n_samples`` candidate voxels, as whole BRICK^3 bricks (``sampled_eq1``)."""
    C = len(cand)
    B = BRICK
    nb = -(-L // B)
    ijk = np.stack([cand // (L * L), (cand // L) % L, cand % L], 1)
    bid = ((ijk[:, 0] // B) * nb + ijk[:, 1] // B) * nb + ijk[:, 2] // B
    bricks = np.unique(bid)
    nbr = len(bricks)
    want = max(int(np.ceil(n_samples / B ** 3)), 1)
    rng = np.random.default_rng(seed)
    pick = bricks if nbr <= want else np.sort(rng.choice(bricks, want, replace=False))
    m = len(pick)
    # every voxel of each picked brick and a one-voxel shell, brick by brick (coherent lookups)
    g = np.arange(-1, B + 1)
    shell = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)  # ((B+2)^3, 3)
    base = np.stack([pick // (nb * nb), (pick // nb) % nb, pick % nb], 1) * B
    vox = base[:, None, :] + shell[None]  # (m, (B+2)^3, 3)
    ok = np.all((vox >= 0) & (vox < L), axis=2)
    flat = np.where(ok, (vox[..., 0] * L + vox[..., 1]) * L + vox[..., 2], 0)
    meas, val = measured_at(maps, origin, w, L, cfg, flat.reshape(-1), lambda f: in_cand[f])
    S = B + 2
    meas = (meas.reshape(m, S, S, S) & ok.reshape(m, S, S, S))
    val = val.reshape(m, S, S, S)
    lim = np.float32(alpha * w)
    inner = (slice(None), slice(1, -1), slice(1, -1), slice(1, -1))
    flag = np.zeros((m, B, B, B), bool)
    for ax in (1, 2, 3):
        for step in (-1, 1):
            nbm = np.roll(meas, -step, axis=ax)[inner]
            nbv = np.roll(val, -step, axis=ax)[inner]
            flag |= nbm & (np.abs(nbv - val[inner]) > lim)
    flag &= meas[inner]
    per = flag.reshape(m, -1).sum(1).astype(np.float64)  # flagged voxels per brick
    scale = nbr / float(L) ** 3
    frac = scale * float(per.mean()) if m else 0.0
    if m >= nbr:  # every brick evaluated: exact
        lo = hi = frac
    else:
        half = z * float(per.std(ddof=1)) / np.sqrt(m) if m > 1 else float(B ** 3)
        lo, hi = max(0.0, frac - scale * half), frac + scale * half
    return SampledEq1(L, float(frac), float(lo), float(hi), C, int(m * B ** 3), int(per.sum()),
                      bool(hi <= t or lo > t), bool(hi <= t))

"""The slow, obviously-correct twin of the consensus fusion's pass 2 (volume.fusion, docs/methods.md §1.1):
one voxel and one pair of samples at a time, in float64.  The vectorised numpy pass
(volume.fusion.consensus_from_samples) and the numba pass (volume.fusion_jit) are tested
against it (tests/volume/test_fusion.py, tests/volume/test_fusion_jit.py)."""

from __future__ import annotations

import numpy as np

from volume.fusion import FusionConfig


def consensus_reference(d, nrm, cw, ok, fr, n_see, cfg: FusionConfig, w: float):
    """Slow, obviously-correct per-voxel version of :func:`consensus_from_samples` (float64)."""
    M, S = d.shape
    cos_n = np.cos(np.radians(cfg.agree_normal_deg))
    out = (np.zeros(M, bool), np.zeros(M, np.float32), np.zeros(M, np.int64), np.zeros(M, bool),
           np.zeros(M, np.float32))
    for m in range(M):
        def agrees(i, j, m=m):  # bind this voxel (B023); only called within this iteration
            if not (ok[m, i] and ok[m, j]):
                return False
            pi = -float(d[m, i]) * nrm[m, i].astype(np.float64)  # nearest points relative to x
            pj = -float(d[m, j]) * nrm[m, j].astype(np.float64)
            return float(np.dot(nrm[m, i], nrm[m, j])) > cos_n and float(np.sum((pi - pj) ** 2)) < cfg.agree(w) ** 2
        q = max(1, min(cfg.quorum, int(n_see[m])))
        best = best1 = None
        for i in range(S):
            if not ok[m, i]:
                continue
            n_agree = sum(agrees(i, j) for j in range(S))
            if n_agree >= q and (best is None or abs(d[m, i]) < abs(d[m, best])):
                best = i
            if best1 is None or abs(d[m, i]) < abs(d[m, best1]):
                best1 = i
        for k, choice in ((0, best), (3, best1)):
            if choice is None:
                continue
            mem = [j for j in range(S) if agrees(choice, j)]
            ws = sum(float(cw[m, j]) for j in mem)
            val = sum(float(cw[m, j]) * float(d[m, j]) for j in mem) / ws if ws > 0 else 0.0
            if k == 0:
                out[0][m] = fr[m] <= len(mem)
                out[1][m] = val
                out[2][m] = len(mem)
            else:
                out[3][m] = True
                out[4][m] = val
    return out

"""The relighting transfer fitted to the capture itself (issue 23): ``kernel="auto"`` of
``render.relight.gl.RelightConfig``.

The transfer T(x, v) = E_K(n) + beta F_K,g(n, v) of ``render.shading.transfer`` has free parameters --
the zonal kernel K (how softly a fur shell or a crown falls off towards its horizon), the weight beta and
the asymmetry g of the forward-scattered light -- and the right ones depend on the material: the plant
and the fur ball of our own generator disagree, and so may any capture we have not seen.  The capture
itself says which fit: it saw every point x of the object from several views under the known capture
lighting A, and a transfer that is right must explain those colours up to the point's own colour,

    C_A(x, v) = rho(x) T_A(x, v)    for all the views v that saw x.

So for each candidate (K, beta, g) the residual log C - log T is taken over the capture pixels, its mean
per voxel of a :data:`GROUP_RES` cube is removed (that is log rho: the albedo, texture, exposure), and
the candidate with the least remaining variance wins.  What is left to explain is how the colour of a
point changes with the view (the forward scattering: backlit fur glows) and, within a voxel, with the
orientation (the kernel).  The kernel is a mixture sum w_j K_j over ``transfer.MIX_BASIS`` (lambert,
wrap, half-lambert, uniform) with weights on a simplex grid of step 1 / :data:`WEIGHT_STEPS`; since
transfers are linear in the kernel, each candidate costs a weighted sum of precomputed per-basis
transfers.  Luminance only (the colour of the light is the maps' business, not the material's).

Measured in docs/relight.md (``furrow bench relight``: the fitted transfer against every fixed one).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from render.shading import transfer as rl

#: Voxels per side of the cube whose per-voxel mean log colour is the point's own colour (rho).
GROUP_RES = 32
#: Basis kernels the fit may use (of transfer.MIX_BASIS).  Not "lambert": the orientation is the SDF
#: gradient smoothed over a tenth of the object, and the true normals spread around it, so the effective
#: kernel is lambert blurred -- a wrapped one; and the per-voxel colour absorbs most of what tells lambert
#: from wrap, so the fit cannot pick it reliably (measured: lambert-heavy fits cost 0.3-0.7 dB on the fur
#: ball, docs/relight.md).
FIT_BASIS = ("wrap", "half-lambert", "uniform")
#: Simplex grid of the kernel mixture: weights in steps of 1 / WEIGHT_STEPS.
WEIGHT_STEPS = 4
#: Candidate forward-scattering weights beta and phase asymmetries g (0 = view-independent): issue 15's
#: measured useful range (beta 0.3-3, g 0.3-0.8).  A wider grid (beta to 4, g 0.3-0.9 in five steps) let the
#: fur balls pick beta 4, which explains their capture views better and relights them 0.1-0.3 dB worse
#: (docs/relight.md): the range is a prior, not fitted.
FORWARD_WEIGHTS = (0.0, 0.5, 1.0, 2.0)
FORWARD_GS = (0.5, 0.8, 0.9)
#: Capture pixels used at most (a seeded subsample; the fit takes about a second).
MAX_SAMPLES = 200_000
#: Pixels count when their coverage is at least this (partial pixels mix in the background).
MIN_ALPHA = 0.9
#: Luminance floor of the log residual (linear units, relative to the median sample luminance).
LOG_FLOOR = 0.01
#: Voxels with fewer samples than this do not count (their mean is their own sample).
MIN_GROUP_SAMPLES = 3
SEED = 0
#: Rec. 709 luminance weights.
LUMA = np.array([0.2126, 0.7152, 0.0722])


@dataclass(frozen=True)
class CaptureSamples:
    """Capture pixels of a model's RGBz views: world points (P, 3) metres, unit directions to the
    camera (P, 3), unit smoothed orientations (P, 3; 0 where undefined), linear colour luminance (P,),
    the index of the view each came from (P,) int."""

    points: np.ndarray
    views: np.ndarray
    normals: np.ndarray
    luminance: np.ndarray
    view_index: np.ndarray


@dataclass(frozen=True)
class TransferFit:
    """The fitted transfer: ``kernel`` (a ``mix:`` name), ``forward`` (beta), ``forward_g`` (g); ``score``
    its residual variance (log luminance squared) and ``scores`` every candidate's, keyed
    (kernel, beta, g); ``samples`` the capture pixels used."""

    kernel: str
    forward: float
    forward_g: float
    score: float
    scores: dict
    samples: int

    def best_fixed(self, kernel: str, forward: float, forward_g: float) -> float:
        """The score of a named candidate (NaN if it was not tried)."""
        return float(self.scores.get((kernel, float(forward), float(forward_g)), np.nan))


def capture_samples(rgbz, normals_at, max_samples: int = MAX_SAMPLES, seed: int = SEED) -> CaptureSamples:
    """The pixels of ``rgbz`` (``volume.model.RgbzImages``-like: rgb, depth, cameras, alpha) with depth and
    coverage >= MIN_ALPHA, at most ``max_samples`` (seeded), with ``normals_at`` (P, 3) -> (P, 3)."""
    pts, views, lum, idx = [], [], [], []
    for i, cam in enumerate(rgbz.cameras):
        dep = np.asarray(rgbz.depth[i], np.float64)
        sel = dep > 0
        if rgbz.alpha is not None:
            sel &= np.asarray(rgbz.alpha[i]) >= MIN_ALPHA
        if not sel.any():
            continue
        vv, uu = np.nonzero(sel)
        x = cam.unproject(np.stack([uu, vv], -1).astype(np.float64), dep[sel])
        v = cam.center - x
        views.append(v / np.linalg.norm(v, axis=1, keepdims=True))
        pts.append(x)
        lum.append(np.asarray(rgbz.rgb[i], np.float64)[sel] @ LUMA)
        idx.append(np.full(len(x), i, np.int64))
    if not pts:
        raise ValueError("relighting fit: the model's RGBz views have no covered pixels with depth")
    x, v, y, k = np.concatenate(pts), np.concatenate(views), np.concatenate(lum), np.concatenate(idx)
    if len(x) > max_samples:
        keep = np.sort(np.random.default_rng(seed).choice(len(x), max_samples, replace=False))
        x, v, y, k = x[keep], v[keep], y[keep], k[keep]
    return CaptureSamples(x, v, np.asarray(normals_at(x), np.float64), y, k)


def _groups(points, origin, side: float, res: int) -> np.ndarray:
    ijk = np.clip(np.floor((points - origin) / (side / res)).astype(np.int64), 0, res - 1)
    return (ijk[:, 0] * res + ijk[:, 1]) * res + ijk[:, 2]


def simplex_weights(n: int, steps: int = WEIGHT_STEPS) -> np.ndarray:
    """(M, n) every weight vector of n entries in multiples of 1 / steps summing to 1."""
    out = [c for c in itertools.product(range(steps + 1), repeat=n) if sum(c) == steps]
    return np.asarray(out, np.float64) / steps


def _basis(samples: CaptureSamples, env, up, fit, basis):
    """Per kernel of MIX_BASIS: luminance of E_j at the samples (P,), of F_j,g per g (G, P), of the
    reference; zeros for the kernels not in ``basis`` (no candidate weighs them)."""
    lum_e, lum_f, refs = [], [], []
    ok = np.linalg.norm(samples.normals, axis=1) > 0.5
    n = np.where(ok[:, None], samples.normals, np.array([0.0, 0.0, 1.0]))
    for name in rl.MIX_BASIS:
        if name not in basis:
            lum_e.append(np.zeros(len(n)))
            lum_f.append(np.zeros((len(FORWARD_GS), len(n))))
            refs.append(0.0)
            continue
        lt = rl.relight_lighting(env, up, rl.mix_kernel([float(k == name) for k in rl.MIX_BASIS]), fit=fit)
        lum_e.append(rl.unoccluded_transfer(lt, n) @ LUMA)
        lum_f.append([rl.forward_transfer(lt, n, samples.views, g) @ LUMA for g in FORWARD_GS])
        refs.append(float(lt.reference @ LUMA))
    return np.asarray(lum_e), np.asarray(lum_f), np.asarray(refs), ok


def _cells(samples: CaptureSamples, use, origin, side: float):
    """(cell of each used sample, voxel of each cell, which cells count): the samples grouped by (voxel,
    view); a cell counts when it has MIN_GROUP_SAMPLES pixels and its voxel has two or more such cells."""
    vox = _groups(samples.points[use], np.asarray(origin, np.float64), float(side), GROUP_RES)
    nv = int(samples.view_index.max()) + 1
    cell_key = vox * nv + samples.view_index[use]
    keys, cell = np.unique(cell_key, return_inverse=True)
    big = np.bincount(cell) >= MIN_GROUP_SAMPLES
    cvox = keys // nv
    inv = np.unique(cvox[big], return_inverse=True)[1]
    ok_cell = np.zeros(len(keys), bool)
    ok_cell[big] = np.bincount(inv)[inv] >= 2
    return cell, cvox, ok_cell


def fit_transfer(samples: CaptureSamples, env, up, origin, side: float, fit=None,
                 regularise: float = rl.REGULARISE, basis=FIT_BASIS) -> TransferFit:
    """The candidate transfer that best explains the capture (module doc).  ``env``: the capture map
    (EnvMap), ``up`` its world up; ``origin``, ``side``: the cube (metres) of the per-voxel colours;
    ``fit``: the map's SG fit (``render.shading.sg_fit``) if already made; ``basis``: the kernels of
    ``transfer.MIX_BASIS`` the mixture may use.

    The samples are first averaged per (voxel, view) cell -- mean log luminance, mean basis transfers
    (the transfers are smooth within a cell, the strand texture is not) -- and each voxel seen by two
    or more views weighs its cells alike."""
    from render.shading.sg_fit import fit_env_sg

    fit = fit_env_sg(env, rl.RELIGHT_SG_K) if fit is None else fit
    e, f, refs, ok = _basis(samples, env, up, fit, basis)
    y = samples.luminance
    floor = LOG_FLOOR * max(float(np.median(y[y > 0])) if np.any(y > 0) else 1.0, 1e-12)
    use = ok & (y > 0)
    cell, cvox, ok_cell = _cells(samples, use, origin, side)
    if ok_cell.sum() < 100:
        raise ValueError(f"relighting fit: only {int(ok_cell.sum())} (voxel, view) cells with "
                         f"{MIN_GROUP_SAMPLES}+ pixels in voxels two views saw")
    cnt = np.bincount(cell)
    mean = lambda a: np.stack([np.bincount(cell, r, len(cnt)) for r in a.reshape(-1, a.shape[-1])]) \
        .reshape(a.shape[:-1] + (len(cnt),))[..., ok_cell] / cnt[ok_cell]
    logy = mean(np.log(np.maximum(y[use], floor))[None])[0]
    e, f = mean(e[:, use]), mean(f[:, :, use])
    grp = np.unique(cvox[ok_cell], return_inverse=True)[1]
    gcnt = np.bincount(grp)
    scores = {}
    for w in simplex_weights(len(rl.MIX_BASIS)):
        if any(wj > 0 for wj, name in zip(w, rl.MIX_BASIS) if name not in basis):
            continue
        ew, ref = w @ e, float(w @ refs)
        fw = np.einsum("j,jgp->gp", w, f)
        for beta, g in [(0.0, FORWARD_GS[-1])] + [(b, g) for b in FORWARD_WEIGHTS if b for g in FORWARD_GS]:
            t = ew + (beta * fw[FORWARD_GS.index(g)] if beta else 0.0) + regularise * (1 + beta) * ref
            r = logy - np.log(np.maximum(t, 1e-30))
            r = r - (np.bincount(grp, r) / gcnt)[grp]
            scores[(rl.mix_kernel(w), float(beta), float(g))] = float(np.mean(r * r))
    best = min(scores, key=scores.get)
    return TransferFit(best[0], best[1], best[2], scores[best], scores, int(ok_cell.sum()))

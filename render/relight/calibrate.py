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

The forward term is integrated over the map's own pixels (:func:`forward_quadrature`, the map at
:data:`FORWARD_QUAD_H` rows), not over the SG lobes the renderer lights it with: a broad lobe taken as
one light at its axis misplaces the phase function's light by tens of degrees, and where the SG fit's
broad lobes sit depends on the floating-point rounding of its L-BFGS-B path (the BLAS kernels of the
CPU: on one test capture an AVX-512 machine fitted beta 0.5 and an AVX2 one the true 1.0, with a best
residual 40x the noise's).  Over the pixels the fit is the same on every machine and recovers the
transfer that made the colours (tests/render/relight/test_calibrate.py).

The choice is judged on views it did not see: the views are split into :data:`CV_FOLDS` groups of
neighbouring views (by azimuth about up), and each candidate predicts every cell of a group from the
point colours (per-voxel means) of the other groups; its error is the mean squared held-out residual.
A candidate that explains the views it was fitted to but not the next sector of views is not chosen.
Candidates within :data:`NOISE_Z` standard errors (over voxels) or :data:`NOISE_REL` of the best are
"within noise" --
the capture cannot tell them apart -- and of those the one nearest the physical default
(:data:`DEFAULT_TRANSFER`, issue 15's fixed transfer) is taken: the fit is regularised toward the
default and moves away from it only as far as the evidence demands.  Which of those equally good
transfers the new light would tell apart is render.relight.trust's question.

Measured in docs/relight.md (``furrow bench relight``: the fitted transfer against every fixed one).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

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
#: Rows of the map (h x 2h pixels, each a light) over which the forward term is integrated
#: (:func:`forward_quadrature`; 16: 512 lights, a pixel 11 degrees, the sun's energy kept by the
#: map's area-weighted resize).
FORWARD_QUAD_H = 16
#: Samples a chunk of :func:`forward_quadrature` (its (chunk, lights) arrays: 32 MB at 16 rows).
FORWARD_QUAD_CHUNK = 8192
#: Capture pixels used at most (a seeded subsample; the forward quadrature of the three fitted kernels
#: takes about 1.8 s per 100,000 here, the rest of the fit about a second).
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
#: The physical default the fit is regularised toward (kernel, beta, g): issue 15's fixed transfer.
DEFAULT_TRANSFER = (rl.mix_kernel([0, 1, 0, 0]), rl.FORWARD_SCATTER, rl.FORWARD_G)
#: The single global gain as a transfer: K = 1, no forward scattering (T_B / T_A = mean_B / mean_A).
GAIN_TRANSFER = (rl.mix_kernel([0, 0, 0, 1]), 0.0, FORWARD_GS[-1])
#: Cross-validation folds: contiguous sectors of the views by azimuth about up.
CV_FOLDS = 4
#: Candidates whose held-out error is within this many standard errors of the best are within noise...
NOISE_Z = 1.0
#: ...and so are those within this fraction of it: the transfer tables and SG lobes approximate the
#: transfers to a few per cent, a difference the sampling noise alone does not show.
NOISE_REL = 0.05


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
    """The fitted transfer: ``kernel`` (a ``mix:`` name), ``forward`` (beta), ``forward_g`` (g) -- the
    candidate taken (within noise of the best, nearest the default); ``score`` its held-out error (mean
    squared log luminance) and ``scores`` every candidate's, keyed (kernel, beta, g); ``fit_scores`` the
    in-sample residual variance of each; ``se`` each candidate's standard error of its held-out error minus
    the best one's; ``best`` the candidate of least held-out error; ``plausible`` the candidates within
    noise of it (nearest the default first); ``samples`` the (voxel, view) cells used; ``views`` the
    capture views the cells came from."""

    kernel: str
    forward: float
    forward_g: float
    score: float
    scores: dict
    samples: int
    fit_scores: dict = field(default_factory=dict)
    se: dict = field(default_factory=dict)
    best: tuple = ()
    plausible: tuple = ()
    views: int = 0

    @property
    def candidate(self) -> tuple:
        """(kernel, beta, g) of the taken transfer."""
        return (self.kernel, float(self.forward), float(self.forward_g))

    @property
    def is_default(self) -> bool:
        """The taken transfer is the physical default (the capture shows nothing better)."""
        return same_transfer(self.candidate, DEFAULT_TRANSFER)

    def best_fixed(self, kernel: str, forward: float, forward_g: float) -> float:
        """The held-out error of a named candidate (NaN if it was not tried)."""
        return float(self.scores.get(key(kernel, forward, forward_g), np.nan))


def key(kernel: str, forward: float, forward_g: float) -> tuple:
    """The candidate key (kernel name, beta, g); beta 0 ignores g (the last of FORWARD_GS)."""
    w = rl.mix_weights(kernel) if kernel.startswith(rl.MIX_PREFIX) else None
    name = rl.mix_kernel(w) if w is not None else kernel
    return (name, float(forward), float(forward_g if forward else FORWARD_GS[-1]))


def same_transfer(a: tuple, b: tuple) -> bool:
    """Two (kernel, beta, g) are the same transfer."""
    return key(*a) == key(*b)


def default_distance(c: tuple) -> float:
    """How far a candidate is from DEFAULT_TRANSFER: half the L1 distance of the kernel weights, plus
    |beta - 1| over the largest beta, plus |g - 0.8| over the range of g where beta > 0 (0 for the default)."""
    kd, bd, gd = DEFAULT_TRANSFER
    d = 0.5 * float(np.abs(rl.mix_weights(c[0]) - rl.mix_weights(kd)).sum())
    d += abs(c[1] - bd) / max(FORWARD_WEIGHTS)
    if c[1] > 0:
        d += abs(c[2] - gd) / (max(FORWARD_GS) - min(FORWARD_GS))
    return d


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


def forward_quadrature(env, up, kernels, normals, views, gs, height: int = FORWARD_QUAD_H) -> np.ndarray:
    """(J, G, P) luminance of F_j,g(n, v) = sum over the pixels w of ``env`` at ``height`` rows of
    K_j(n.w) HG_g(-v.w) L(w) dOmega(w), at world unit ``normals`` and directions to the camera ``views``
    (P, 3), for each kernel name of ``kernels`` and asymmetry of ``gs`` (module doc: the forward term
    over the map's pixels rather than its SG lobes)."""
    src = env.resized(height) if env.height != height else env
    d = src.pixel_directions().reshape(-1, 3).astype(np.float64) @ rl.world_to_env(up)
    lum = (src.data.reshape(-1, 3).astype(np.float64) @ LUMA) * src.pixel_solid_angles().reshape(-1)
    fns = [rl.kernel_fn(k) for k in kernels]
    n, v = np.asarray(normals, np.float32), np.asarray(views, np.float32)
    d32, lum32 = d.astype(np.float32), lum.astype(np.float32)
    out = np.zeros((len(fns), len(gs), len(n)))
    for s in range(0, len(n), FORWARD_QUAD_CHUNK):
        c, back = n[s:s + FORWARD_QUAD_CHUNK] @ d32.T, v[s:s + FORWARD_QUAD_CHUNK] @ d32.T  # back: v.w
        lit = [np.asarray(f(c), np.float32) * lum32 for f in fns]
        for gi, g in enumerate(gs):
            hg = rl.henyey_greenstein(-back, g, np.float32)
            for j, k in enumerate(lit):
                out[j, gi, s:s + FORWARD_QUAD_CHUNK] = np.einsum("pd,pd->p", k, hg)
    return out


def basis_transfers(samples: CaptureSamples, env, up, fit, basis):
    """Per kernel of MIX_BASIS: luminance of E_j at the samples (P,), of F_j,g per g (G, P; over the
    map's pixels, :func:`forward_quadrature`), of the reference; zeros for the kernels not in ``basis``
    (no candidate weighs them)."""
    ok = np.linalg.norm(samples.normals, axis=1) > 0.5
    n = np.where(ok[:, None], samples.normals, np.array([0.0, 0.0, 1.0]))
    names = [name for name in rl.MIX_BASIS if name in basis]
    kernels = [rl.mix_kernel([float(k == name) for k in rl.MIX_BASIS]) for name in names]
    fwd = forward_quadrature(env, up, kernels, n, samples.views, FORWARD_GS)
    lum_e = np.zeros((len(rl.MIX_BASIS), len(n)))
    lum_f = np.zeros((len(rl.MIX_BASIS), len(FORWARD_GS), len(n)))
    refs = np.zeros(len(rl.MIX_BASIS))
    for j, (name, kernel) in enumerate(zip(names, kernels)):
        i = list(rl.MIX_BASIS).index(name)
        lt = rl.relight_lighting(env, up, kernel, fit=fit)
        lum_e[i], lum_f[i], refs[i] = rl.unoccluded_transfer(lt, n) @ LUMA, fwd[j], float(lt.reference @ LUMA)
    return lum_e, lum_f, refs, ok


def _cells(samples: CaptureSamples, use, origin, side: float):
    """(cell of each used sample, voxel of each cell, view of each cell, which cells count): the samples
    grouped by (voxel, view); a cell counts when it has MIN_GROUP_SAMPLES pixels and its voxel has two or
    more such cells."""
    vox = _groups(samples.points[use], np.asarray(origin, np.float64), float(side), GROUP_RES)
    nv = int(samples.view_index.max()) + 1
    cell_key = vox * nv + samples.view_index[use]
    keys, cell = np.unique(cell_key, return_inverse=True)
    big = np.bincount(cell) >= MIN_GROUP_SAMPLES
    cvox = keys // nv
    inv = np.unique(cvox[big], return_inverse=True)[1]
    ok_cell = np.zeros(len(keys), bool)
    ok_cell[big] = np.bincount(inv)[inv] >= 2
    return cell, cvox, keys % nv, ok_cell


def view_folds(samples: CaptureSamples, up, folds: int = CV_FOLDS) -> np.ndarray:
    """(V,) fold of each capture view: ``folds`` contiguous sectors of the views ordered by the azimuth
    about ``up`` of their mean direction to the camera (neighbouring views share a fold, so a fold's
    views are predicted from views that look from elsewhere)."""
    nv = int(samples.view_index.max()) + 1
    d = np.stack([np.bincount(samples.view_index, samples.views[:, a], nv) for a in range(3)], 1)
    u = np.asarray(up, np.float64) / np.linalg.norm(up)
    e1 = np.cross(u, [1.0, 0, 0] if abs(u[0]) < 0.9 else [0, 1.0, 0])
    e1 /= np.linalg.norm(e1)
    az = np.arctan2(d @ np.cross(u, e1), d @ e1)
    fold = np.empty(nv, np.int64)
    fold[np.argsort(az)] = np.arange(nv) * folds // nv
    return fold


def held_out_errors(r, grp, fold, folds: int):
    """(e, valid): each cell's residual ``r`` minus the mean of its voxel's (``grp``) cells in the other
    folds; valid where there are such cells."""
    n = int(grp.max()) + 1
    idx = grp * folds + fold
    s_all, n_all = np.bincount(grp, r, n), np.bincount(grp, minlength=n)
    s_f, n_f = np.bincount(idx, r, n * folds), np.bincount(idx, minlength=n * folds)
    ntr = n_all[grp] - n_f[idx]
    return r - (s_all[grp] - s_f[idx]) / np.maximum(ntr, 1), ntr > 0


def _candidates(w_all, basis):
    """(weights, beta, g) of every candidate: kernel mixtures over ``basis`` x forward scattering."""
    for w in w_all:
        if any(wj > 0 for wj, name in zip(w, rl.MIX_BASIS) if name not in basis):
            continue
        for beta, g in [(0.0, FORWARD_GS[-1])] + [(b, g) for b in FORWARD_WEIGHTS if b for g in FORWARD_GS]:
            yield w, beta, g


def _standard_errors(sq: dict, grp, best) -> dict:
    """Per candidate the standard error of its mean held-out squared error minus the best one's, the
    cells' differences summed per voxel (``grp``) and the voxels taken as independent."""
    n_vox = int(grp.max()) + 1
    cnt = np.bincount(grp, minlength=n_vox).astype(np.float64)
    used = cnt > 0
    nv, total = int(used.sum()), float(cnt.sum())
    out = {}
    for c, e2 in sq.items():
        d = np.bincount(grp, e2 - sq[best], n_vox)
        delta = d.sum() / total
        out[c] = float(np.sqrt(np.sum(((d - cnt * delta)[used]) ** 2) * nv / max(nv - 1, 1)) / total)
    return out


def fit_transfer(samples: CaptureSamples, env, up, origin, side: float, fit=None,
                 regularise: float = rl.REGULARISE, basis=FIT_BASIS, folds: int = CV_FOLDS) -> TransferFit:
    """The candidate transfer that best explains the capture on views it did not see, regularised toward
    the default (module doc).  ``env``: the capture map (EnvMap), ``up`` its world up; ``origin``,
    ``side``: the cube (metres) of the per-voxel colours; ``fit``: the map's SG fit
    (``render.shading.sg_fit``) if already made; ``basis``: the kernels of ``transfer.MIX_BASIS`` the
    mixture may use; ``folds``: view sectors of the cross-validation.

    The samples are first averaged per (voxel, view) cell -- mean log luminance, mean basis transfers
    (the transfers are smooth within a cell, the strand texture is not) -- and each voxel seen by two
    or more views weighs its cells alike."""
    from render.shading.sg_fit import fit_env_sg

    fit = fit_env_sg(env, rl.RELIGHT_SG_K) if fit is None else fit
    e, f, refs, ok = basis_transfers(samples, env, up, fit, basis)
    y = samples.luminance
    floor = LOG_FLOOR * max(float(np.median(y[y > 0])) if np.any(y > 0) else 1.0, 1e-12)
    use = ok & (y > 0)
    cell, cvox, cview, ok_cell = _cells(samples, use, origin, side)
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
    fold = view_folds(samples, up, folds)[cview[ok_cell]]
    valid = held_out_errors(np.zeros(len(grp)), grp, fold, folds)[1]
    if valid.sum() < 100:
        raise ValueError(f"relighting fit: only {int(valid.sum())} cells can be predicted from views of other "
                         "sectors (the capture views cover too little of the object from several sides)")
    scores, fit_scores, sq = {}, {}, {}
    for w, beta, g in _candidates(simplex_weights(len(rl.MIX_BASIS)), basis):
        t = w @ e + (beta * np.einsum("j,jp->p", w, f[:, FORWARD_GS.index(g)]) if beta else 0.0) \
            + regularise * (1 + beta) * float(w @ refs)
        r = logy - np.log(np.maximum(t, 1e-30))
        c = key(rl.mix_kernel(w), beta, g)
        rin = r - (np.bincount(grp, r) / gcnt)[grp]
        fit_scores[c] = float(np.mean(rin * rin))
        sq[c] = held_out_errors(r, grp, fold, folds)[0][valid] ** 2
        scores[c] = float(sq[c].mean())
    best = min(scores, key=scores.get)
    se = _standard_errors(sq, grp[valid], best)
    tol = {c: max(NOISE_Z * se[c], NOISE_REL * scores[best]) for c in scores}
    plausible = tuple(sorted((c for c in scores if scores[c] - scores[best] <= tol[c]),
                             key=lambda c: (default_distance(c), scores[c])))
    k, b, g = plausible[0]
    return TransferFit(k, b, g, scores[plausible[0]], scores, int(valid.sum()), fit_scores, se, best, plausible,
                       int(len(np.unique(cview[ok_cell]))))

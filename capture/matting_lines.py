"""The colour of partial pixels from the lines B -> F of a window (issue 30, seventh round).

Before a bright room the colour of a dark, thin, partial structure is lost twice over: unmixed,
a F = C - (1 - a) B is off by (a - a_true) B (the alpha's error times the bright room: the crown
comes out pale); filled from the sure pixels (capture.matting_known step 4) it takes the colour of
the trunk and branches (olive).  Yet the photo holds the needles' colour without the matte's alpha:
each partial pixel p with a known background B_p lies on the line from B_p to its own colour F
(C_p = a_p F + (1 - a_p) B_p).  Where one colour F is shared by the partial pixels of a window and
the background behind them is textured, only one F puts every C_p on its line.

:func:`line_colour` finds, per pixel, the F of the window around it that brings the window's partial
pixels nearest to their lines: least squares over F of sum_p w_p |C_p - B_p - a_p (F - B_p)|^2 with
each a_p the projection of C_p - B_p on F - B_p (the photo's own alpha given F), by Gauss-Newton
steps from the window's mean unmixed colour (each step a 3 x 3 solve per pixel from box sums of
the window; a_p and the line's direction taken from the pixel's own window's F, the colour being
smooth).  The residual is measured where the photo's noise lives (C), not as F's distance from
the line B_p -> C_p, whose noise grows as |F - B| / |C - B| and pulls the crossing towards the
backgrounds (the first try: the conifer's needles came out twice as bright).  Weights
w_p = 1 / (LINE_NOISE^2 + (1 - a_p)^2 sigma_B^2) (the estimated background's error sigma_B enters
C - a F - (1 - a) B as (1 - a) dB).  The expected error of the window's colour as each pixel's own:
the needles' spread about it (LINE_SPREAD x the weighted residual over a^2) plus the estimate's own
variance (the residual's scale times trace M^-1, M = sum w a^2 (I - v v^T), v along F - B: it grows
without bound as the lines turn parallel, a background too uniform to tell F along them).

:func:`refine_colour` puts the window's colour where it is expected to beat the matte's own colour
(the unmixed or filled one, capture.matting_colour's per-pixel terms): a F_cell errs by
a^2 sigma_cell^2 + sigma_a^2 |F_cell|^2, the unmixed colour by (1 - a)^2 sigma_B^2 + sigma_a^2 |B|^2,
the filled one by a^2 sigma_fill^2 + sigma_a^2 |F_fill|^2.  It falls back to doing nothing, and says
so in the record (``Matte.notes['lines']``), when too few lines cross a window (MIN_LINES), when M is
singular, when fewer than VALID_SHARE of a window's lines have the colour beyond the photo from the
background (implied alpha in [0, IMPLIED_MAX]), or when the alpha's error cannot be measured.  Off
(LINES): within a window of one view the room behind a conifer's crown varies too little to cross the
lines (docs/matting.md, seventh round).

:func:`cell_colours` groups the partial pixels of every view by 3D cell instead (each placed by the
object's depth: :func:`line_samples`, the matte stage's views; volume.surroundings crosses them
after the last view; the pipeline runs it in two passes of bounded memory, capture.matting_cells,
with the same result where no view is drawn from): the same needles are seen before different parts
of the room.  The lines are crossed in the plate's common exposure (its gains), and a pixel takes
its cell's colour where the cell's expected error is below the unmixed colour's,
(sigma_a^2 |B - F|^2 + (1 - a)^2 sigma_B^2)^(1/2) / a (sigma_a the view's alpha error from
capture.matting_colour: a view without one keeps its colour; sigma_B the plate's uncertainty where
estimated).  Held out, the conifer turntable 24.80 -> 25.01 dB, orbit 26.22 -> 26.61, room + table
+ AE + lens 24.70 -> 24.74; a black capture and the fur before similar bricks the same digits.
Since the eighth round (capture.matting_global) the cubes' lines are those of photo's alpha at least
CELL_LINE_ALPHA, each cube's colour is drawn towards the object's by the cubes' measured spread, the
filled pixels of a cube whose lines do not cross take the object's colour, those of a crossed cube its
colour, and each view's colours are scaled by its brightness of the object: 25.46 / 26.89 / 24.81.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import uniform_filter

from capture.matting_known import FILL_ALPHA, clipped

#: The window (box) around each pixel whose partial pixels' lines are crossed, as a fraction of the
#: view's width (31 px at 640).  Oracle on the conifer turntable (the black twin's colour averaged
#: over the partial pixels of a window, numpy twin of gather, held out): 7 px 25.60 dB, 15 px 25.57,
#: 31 px 25.57, one colour a view 25.61, the exact colour 25.76, the room model 24.80.
WINDOW_FRACTION = 31 / 640
#: Partial pixels whose lines are used: the photo's alpha |C - B| / |B - F_ref| in [LINE_ALPHA_LO,
#: LINE_ALPHA_HI] (below, the line is the noise's; above, bark and branches, another colour).
LINE_ALPHA_LO = 0.1
LINE_ALPHA_HI = FILL_ALPHA
#: The least photo's alpha of the lines crossed across the views (the cubes and the object's colour,
#: :func:`cell_colours`, capture.matting_cells, capture.matting_global).  The faint lines pull the
#: crossing towards the room's colour: on the conifer turntable's kept views the object's lines crossed
#: as one group give red 0.068 from the lines of photo's alpha 0.1-0.3, 0.055 from 0.3-0.5, 0.048 from
#: 0.5-0.85 (the truth 0.043, 0.040, 0.043).  Held out (gather, numpy twin, docs/matting.md eighth round),
#: the cubes with the object's colour: turntable 0.1 / 0.3 / 0.5: 25.24 / 25.27 / 25.30 dB, orbit
#: 26.61 / 26.62 / 26.62.
CELL_LINE_ALPHA = 0.5
#: Least lines in a window for its colour.
MIN_LINES = 12
#: Noise of a partial pixel's colour about its line (linear, Euclidean: 8-bit steps, the renderer's or
#: sensor's noise, the plate's error where a frame saw the background).
LINE_NOISE = 0.01
#: The weighted mean squared residual over a^2 is two of three dimensions of the needles' spread about
#: the window's colour: the spread is this times it.
LINE_SPREAD = 1.5
#: A window's colour is kept only where at least VALID_SHARE of its lines have it beyond the photo
#: from the background: implied alpha (C - B).(F - B) / |F - B|^2 in [0, IMPLIED_MAX].
IMPLIED_MAX = 1.05
VALID_SHARE = 0.8
#: A group's colour is used only where M's smallest eigenvalue is at least this share of its largest.
MIN_CONDITION = 0.0015
#: Gauss-Newton steps (each moves F at most MAX_STEP, linear Euclidean).
GN_ITERATIONS = 6
MAX_STEP = 0.1
#: group_fit's passes over the samples by one compiled loop (capture.matting_lines_kernel; the same
#: totals) where the groups are summed by bincount (a ``gsum`` with a ``groups`` attribute: the 3D cubes),
#: else numpy (:func:`_gn_totals`, the reference).
GN_COMPILED = True
#: Per-view windows (capture.matting.solve_known's plate branch): off.  On the conifer turntable's
#: kept views the window's colour erred twice the matte's (median |F - F_true| 0.075 against 0.037):
#: within 31 px the room behind the crown varies by 0.05, about as much as the needles' own colour
#: (0.025), so the lines barely cross (docs/matting.md, seventh round).
LINES = False
#: Across the views (the matte stage, volume.surroundings): each 3D cell's partial pixels, every one
#: before its own view's background (:func:`cell_colours`).
CELLS = True
#: With the cell's colour, the pixel's alpha too: its projection on the line B -> F_cell.  Off: held out
#: (gather), conifer turntable 25.01 -> 24.43 dB, orbit 26.61 -> 26.53, alpha MSE 0.031 -> 0.037.
CELL_ALPHA = False
#: Cubes per the partial pixels' extent.  Held out (gather, the pipeline): 16 / 32 cubes, conifer
#: turntable 25.01 / 24.93 dB, orbit 26.61 / 26.62.
CELLS_PER_EXTENT = 16

_PAIRS = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))


def _box(x: np.ndarray, size: int) -> np.ndarray:
    """Window sums of (h, w[, k]) ``x`` over ``size`` x ``size`` boxes (zero outside)."""
    sz = (size, size) + (1,) * (x.ndim - 2)
    return uniform_filter(np.asarray(x, np.float64), sz, mode="constant") * (size * size)


def line_alpha(C: np.ndarray, B: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """(h, w) the photo's own alpha for choosing lines: |C - B| / |B - ref| (``ref`` (3,): a rough colour
    of the object), in [0, 1]; not the matte's alpha, whose error would admit pixels of pure background
    (C = B: no line) as partial ones."""
    d = np.linalg.norm(C - B, axis=-1)
    return np.clip(d / np.maximum(np.linalg.norm(B - ref, axis=-1), 1e-6), 0.0, 1.0)


def line_weights(a_line: np.ndarray, usable: np.ndarray, sigma_b: np.ndarray, lo: float = LINE_ALPHA_LO) -> np.ndarray:
    """(h, w) weight of each pixel's line, 1 / (LINE_NOISE^2 + (1 - a)^2 sigma_B^2), on the ``usable``
    pixels whose photo's alpha ``a_line`` is in [``lo``, LINE_ALPHA_HI]; 0 elsewhere."""
    a = np.asarray(a_line, np.float64)
    use = usable & (a >= lo) & (a <= LINE_ALPHA_HI)
    return np.where(use, 1.0 / (LINE_NOISE ** 2 + ((1.0 - a) * sigma_b) ** 2), 0.0)


def _terms(C: np.ndarray, B: np.ndarray, F: np.ndarray):
    """Per pixel given F: (implied alpha unclipped, alpha in [0, 1], the residual C - B - a (F - B),
    v the unit direction of F - B)."""
    d, fb = C - B, F - B
    n2 = np.maximum((fb ** 2).sum(-1), 1e-12)
    imp = (d * fb).sum(-1) / n2
    a = np.clip(imp, 0.0, 1.0)
    return imp, a, d - a[..., None] * fb, fb / np.sqrt(n2)[..., None]


def _pack(M6: np.ndarray) -> np.ndarray:
    """(..., 3, 3) symmetric matrices from their 6 entries (..., 6) in _PAIRS order."""
    M = np.empty(M6.shape[:-1] + (3, 3))
    for k, (i, j) in enumerate(_PAIRS):
        M[..., i, j] = M[..., j, i] = M6[..., k]
    return M


def _gn_totals(C, B, w, F, gsum, group):
    """One Gauss-Newton pass of :func:`group_fit` in numpy (the reference of GN_COMPILED): (the group
    totals (K, 11) of the six entries of Q, (w a) r, w |r|^2 and w a^2; each sample's implied alpha)."""
    d, fb = C - B, F[group] - B
    n2 = np.maximum((fb ** 2).sum(-1), 1e-12)
    imp = (d * fb).sum(-1) / n2
    a = np.clip(imp, 0.0, 1.0)
    r = d - a[:, None] * fb
    v = fb / np.sqrt(n2)[:, None]
    wa2 = w * a ** 2
    Q = [wa2 * ((i == j) - v[:, i] * v[:, j]) for i, j in _PAIRS]
    return gsum(np.concatenate([np.stack(Q, 1), (w * a)[:, None] * r, (w * (r ** 2).sum(-1))[:, None],
                                wa2[:, None]], 1)), imp


def group_fit(C: np.ndarray, B: np.ndarray, w: np.ndarray, alpha: np.ndarray, gsum, group: np.ndarray,
              terms: dict | None = None):
    """The colour shared by each group of samples (module docstring) for N samples: ``C``, ``B`` (N, 3),
    line weights ``w`` (N,), the matte's ``alpha`` (N,) (the start only); ``gsum``: (N, k) per-sample
    values -> (K, k) the totals of the K groups (a window's box sum: K = N, a 3D cell's sum), ``group``
    (N,) each sample's own group (whose colour its alpha and line direction are taken from).
    Returns (F (K, 3), sigma^2 (K,) the expected squared error of a group's colour as one of its
    samples' own; inf where too few lines, M singular or ill-conditioned (smallest eigenvalue under
    MIN_CONDITION of the largest: the backgrounds too alike to tell F along the lines), or too few
    lines with the colour beyond the photo).  ``terms``: a dict given the groups' last normal matrices
    ``M`` (K, 3, 3), residual scales ``s`` (K,: the weighted squared residual per degree of freedom,
    the estimate's covariance s M^-1), ``spread`` (K,: the first term of sigma^2) and line counts ``n``."""
    C, B, w = (np.asarray(x, np.float64) for x in (C, B, w))
    lines = w > 0
    am = np.where(lines, np.asarray(alpha, np.float64), 0.0)
    S = gsum(np.concatenate([(w * am)[:, None] * (C - (1.0 - am)[:, None] * B), (w * am ** 2)[:, None],
                             lines[:, None].astype(np.float64)], 1))
    n = S[:, 4]
    F = S[:, :3] / np.maximum(S[:, 3], 1e-12)[:, None]
    ok = (n >= MIN_LINES - 0.5) & (S[:, 3] > 0)
    good = ok
    groups = getattr(gsum, "groups", None) if GN_COMPILED else None  # bincount's groups: the compiled pass
    if groups is not None:
        from capture.matting_lines_kernel import gn_pass

        C, B, w, group = (np.ascontiguousarray(x) for x in (C, B, w, np.asarray(group, np.int64)))
    for it in range(GN_ITERATIONS + 1):
        if groups is not None:  # the same totals (capture.matting_lines_kernel)
            T, imp = np.zeros((groups, 11)), np.empty(len(w))
            gn_pass(C, B, w, np.ascontiguousarray(F, np.float64), group, groups, T, imp)
        else:
            T, imp = _gn_totals(C, B, w, F, gsum, group)
        M = _pack(T[:, :6])
        good = ok.copy()
        if ok.any():
            ev = np.linalg.eigvalsh(M[ok])
            good[ok] = ev[:, 0] > MIN_CONDITION * np.maximum(ev[:, 2], 1e-30)
        if it == GN_ITERATIONS:
            break
        step = np.zeros(F.shape)
        step[good] = np.linalg.solve(M[good], T[good, 6:9][..., None])[..., 0]
        norm = np.linalg.norm(step, axis=-1, keepdims=True)
        F = np.clip(F + step * np.minimum(1.0, MAX_STEP / np.maximum(norm, 1e-12)), 0.0, 1.0)
    beyond = gsum((lines & (imp >= 0.0) & (imp <= IMPLIED_MAX)).astype(np.float64)[:, None])[:, 0]
    keep = good & (beyond >= VALID_SHARE * n)
    sig2 = np.full(len(F), np.inf)
    if keep.any():
        rss, wa2s = T[keep, 9], T[keep, 10]
        var = rss / np.maximum(2.0 * n[keep] - 3.0, 1.0) * np.trace(np.linalg.inv(M[keep]), axis1=1, axis2=2)
        sig2[keep] = LINE_SPREAD * rss / np.maximum(wa2s, 1e-12) + var
    if terms is not None:
        terms.update(M=M, n=n, s=T[:, 9] / np.maximum(2.0 * n - 3.0, 1.0),
                     spread=LINE_SPREAD * T[:, 9] / np.maximum(T[:, 10], 1e-12))
    return F, sig2


def line_colour(C: np.ndarray, B: np.ndarray, w: np.ndarray, size: int, alpha: np.ndarray, where: np.ndarray):
    """(F (h, w, 3), sigma^2 (h, w)) of :func:`group_fit` with each pixel's group the ``size``-pixel
    window around it; sigma^2 inf outside ``where``."""
    h, wd = w.shape

    def gsum(x):
        return _box(x.reshape(h, wd, -1), size).reshape(h * wd, -1)

    F, sig2 = group_fit(np.reshape(C, (-1, 3)), np.reshape(B, (-1, 3)), np.ravel(w), np.ravel(alpha), gsum,
                        np.arange(h * wd))
    return F.reshape(h, wd, 3), np.where(where, sig2.reshape(h, wd), np.inf)


def cell_colour(points: np.ndarray, cell: float, C: np.ndarray, B: np.ndarray, w: np.ndarray, alpha: np.ndarray):
    """(F (N, 3), sigma^2 (N,)) of :func:`group_fit` with each sample's group the cube of side ``cell``
    (world units) its 3D point ``points`` (N, 3) falls in: the partial pixels of every view that see
    the same part of the object, each before its own view's background."""
    inv, gsum = cell_groups(points, cell)
    F, sig2 = group_fit(C, B, w, alpha, gsum, inv)
    return F[inv], sig2[inv]


def cell_groups(points: np.ndarray, cell: float):
    """(each sample's cube (N,) int64 in 0..K-1, its group sum for :func:`group_fit`) of the cubes of side
    ``cell`` from the samples' lowest corner."""
    ijk = np.floor((np.asarray(points, np.float64) - np.min(points, 0)) / cell).astype(np.int64)
    dims = ijk.max(0) + 1
    _, inv = np.unique((ijk[:, 0] * dims[1] + ijk[:, 1]) * dims[2] + ijk[:, 2], return_inverse=True)
    inv = inv.ravel()
    K = int(inv.max()) + 1 if len(inv) else 0

    def gsum(x):
        return np.stack([np.bincount(inv, x[:, j], minlength=K) for j in range(x.shape[1])], 1)

    return inv, gsum


def _view_out(C, B, F, sig2, sb, usable, index, gain, rec: dict, across: bool) -> tuple | None:
    """One view's output of :func:`cell_colours` from its coloured pixels (``C``, ``B``, colours ``F`` in the common
    exposure, the cube's ``sig2``, ``sb``, ``usable`` (crossed and usable), flat ``index``, the view's ``gain``):
    (index, colours / gain float32, implied alphas float32) or None when none; where ``across``, the part across
    each pixel's line kept (capture.matting_cells.across_line), counted in ``rec['across']``."""
    from capture.matting_cells import across_line

    if not len(index):
        return None
    imp = np.clip(_implied(C, B, F), 0.0, 1.0)
    if across:
        F, n = across_line(C, B, F, imp, sig2, sb, usable)
        rec["across"] += n
    return index, (F / gain).astype(np.float32), imp.astype(np.float32)


def _implied(C: np.ndarray, B: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Alpha implied by the colour ``F`` on the line B -> C: (C - B).(F - B) / |F - B|^2."""
    fb = F - B
    return ((C - B) * fb).sum(-1) / np.maximum((fb ** 2).sum(-1), 1e-12)


def _sigma_b(est: np.ndarray, sigma: np.ndarray | None) -> np.ndarray:
    """(h, w) the background's uncertainty: 0 where a frame saw it, the plate's sigma where estimated
    (capture.matting_colour.SIGMA_UNKNOWN where not reported or inf)."""
    from capture.matting_colour import SIGMA_UNKNOWN

    if sigma is None:
        return np.where(est, SIGMA_UNKNOWN, 0.0)
    s = np.minimum(np.nan_to_num(np.asarray(sigma, np.float64), nan=np.inf), SIGMA_UNKNOWN)
    return np.where(est, s, 0.0)


def refine_colour(image, alpha, background, known, estimated, sigma, colour, unmixed, width: int,
                  record=None) -> np.ndarray:
    """(h, w, 3) the straight ``colour`` (the matte's, capture.matting_known step 4) with the window's
    colour (:func:`line_colour`) at the partial pixels where its expected error is below the matte's
    own (module docstring); ``unmixed`` (h, w): where the matte's colour was unmixed (B known for the
    colour), filled elsewhere; ``estimated`` / ``sigma``: the plate's estimated pixels and their
    uncertainty (or None); ``width``: the view's width (the window's size).  Its record goes into
    ``record['lines']``."""
    from capture.matting_colour import alpha_error, alpha_variance, fill_error

    C = np.clip(np.asarray(image, np.float64), 0.0, 1.0)
    B = np.clip(np.asarray(background, np.float64), 0.0, 1.0)
    a = np.asarray(alpha, np.float64)
    F0 = np.asarray(colour, np.float64)
    known = np.asarray(known, bool) & ~clipped(C, B)
    est = np.zeros(a.shape, bool) if estimated is None else np.asarray(estimated, bool) & known
    s_b = _sigma_b(est, sigma)
    target = (a > 0) & (a < FILL_ALPHA)
    size = max(3, int(round(WINDOW_FRACTION * width)) | 1)
    rec = {"target": int(target.sum()), "replaced": 0}
    out = F0
    a_line = line_alpha(C, B, np.median(F0[target], axis=0)) if target.any() else None
    w = None if a_line is None else line_weights(a_line, known, s_b)
    F, sig2 = (None, None) if w is None else line_colour(C, B, w, size, a, target)
    ok = None if sig2 is None else np.isfinite(sig2) & target
    seen = known & ~est
    sa = None
    if ok is not None and ok.any():
        sa = alpha_error(C, a, B, F, seen & target, float(np.sqrt(np.median(sig2[ok]))))
    if ok is None or not ok.any():
        rec["reason"] = "the lines cross nowhere (too few, parallel, or at the background)"
    elif sa is None:
        rec["reason"] = "too few partial pixels before a seen background to measure the alpha"
    else:
        var_a = alpha_variance(sa, ((B - F) ** 2).sum(-1))
        F_exact = np.clip(B + (C - B) / np.maximum(a, 1e-6)[..., None], 0.0, 1.0)
        s_f = fill_error(F_exact, seen & (a >= FILL_ALPHA))
        e_cell = np.where(ok, a ** 2 * np.where(ok, sig2, 0.0) + var_a * (F ** 2).sum(-1), np.inf)
        e_unmix = ((1.0 - a) * s_b) ** 2 + var_a * (B ** 2).sum(-1)
        e_fill = a ** 2 * (np.inf if s_f is None else s_f ** 2) + var_a * (F0 ** 2).sum(-1)
        use = ok & (e_cell < np.where(np.asarray(unmixed, bool), e_unmix, e_fill))
        out = np.where(use[..., None], np.clip(F, 0.0, 1.0), F0)
        rec.update(replaced=int(use.sum()), crossed=int(ok.sum()), sigma_alpha=round(sa[0], 5),
                   sigma_cell=round(float(np.sqrt(np.median(sig2[use]))), 5) if use.any() else None)
    if record is not None:
        record["lines"] = rec
    return out


def line_samples(camera, image, background, known, alpha, colour, object_depth, estimated=None,
                 sigma=None) -> dict | None:
    """One view's partial pixels (0 < alpha < FILL_ALPHA) for :func:`cell_colours`: their flat pixel
    ``index``, 3D ``pts`` (the object's depth, filled by push-pull where a needle missed the pixel
    centre), the photo ``C``, background ``B`` (clipped to [0, 1]), the matte's ``a`` and colour ``F0``,
    ``usable`` (B known and not blown out) and ``sb`` the background's uncertainty (0 where a frame saw
    it; the plate's ``sigma`` where ``estimated``); float32.  None when there is none."""
    from capture.fill import push_pull

    a = np.asarray(alpha, np.float64)
    part = (a > 0) & (a < FILL_ALPHA)
    dep = np.asarray(object_depth, np.float64)
    if not part.any() or not (dep > 0).any():
        return None
    filled = push_pull(dep[..., None], (dep > 0).astype(np.float64))[..., 0]
    pts, mask = camera.depth_to_points(np.where(part, filled, 0.0))
    # every term per pixel: taken at the partial pixels only (the same values as over the whole image)
    C = np.clip(np.asarray(image)[mask].astype(np.float64), 0.0, 1.0)
    B = np.clip(np.asarray(background)[mask].astype(np.float64), 0.0, 1.0)
    use = np.asarray(known, bool)[mask] & ~clipped(C, B)
    est = np.zeros(len(use), bool) if estimated is None else np.asarray(estimated, bool)[mask] & use
    f32 = np.float32
    return {"index": np.flatnonzero(mask).astype(np.int64), "pts": pts.astype(f32), "C": C.astype(f32),
            "B": B.astype(f32), "a": a[mask].astype(f32), "F0": np.asarray(colour)[mask].astype(f32),
            "usable": use, "sb": _sigma_b(est, None if sigma is None else np.asarray(sigma)[mask]).astype(f32)}


def cell_colours(samples: list, sigma_alpha: list | None = None, gains=None,
                 cells: int = CELLS_PER_EXTENT) -> tuple[list, dict]:
    """The colour of every view's partial pixels from the lines of its 3D cell across the views
    (:func:`cell_colour`, cubes of 1 / ``cells`` of the samples' extent; ``gains`` (V, 3): the views'
    exposure gains, capture.plate.fit_gains, true colour = colour x gain: the lines are crossed in the
    common exposure and each view's colour brought back to its own), used at a pixel where its
    expected error is below the unmixed colour's, (sigma_a^2 |B - F|^2 + (1 - a)^2 sigma_B^2)^(1/2) / a
    with ``sigma_alpha`` the view's alpha error (capture.matting_colour.alpha_error; None: not measured,
    the view keeps its colour; no list: every usable cell's colour) and sigma_B the samples' ``sb``.
    Per view (flat indices, colours (n, 3), alphas implied (n,)) or None, and the record (pixels, those
    in a usable cell, those given its colour, why none)."""
    from capture.matting_global import cross_cells, filled, with_object_colour

    have = [s for s in samples if s is not None]
    rec = {"cells": cells, "pixels": int(sum(len(s["a"]) for s in have)), "crossed": 0, "coloured": 0}
    if not have:
        return [None] * len(samples), {**rec, "reason": "no partial pixels with depth"}
    if sigma_alpha is not None:  # a view without its own alpha error borrows the views' (capture.matting_contrast)
        from capture.matting_contrast import pooled_alpha_errors
        sigma_alpha, rec["alpha_error_pooled"] = pooled_alpha_errors(sigma_alpha, [s is not None for s in samples])
    g = np.ones((len(samples), 3)) if gains is None else np.asarray(gains, np.float64)
    cat = {k: np.concatenate([s[k] * (g[v] if k in ("C", "B", "F0") else 1) for v, s in enumerate(samples)
                              if s is not None]).astype(np.float64 if k != "usable" else bool)
           for k in ("pts", "C", "B", "a", "F0", "usable")}
    sb = np.concatenate([s.get("sb", np.zeros(len(s["a"]))) for s in have]).astype(np.float64)
    al = line_alpha(cat["C"], cat["B"], np.median(cat["F0"], 0))
    # sigma_B in the lines' weights too (estimated backgrounds weigh less): turntable 25.007 -> 24.987 dB,
    # AE + lens 24.743 -> 24.752 held out; left out
    w = line_weights(al, cat["usable"], np.zeros(len(al)), CELL_LINE_ALPHA)
    extent = float((cat["pts"].max(0) - cat["pts"].min(0)).max())
    if extent <= 0 or int((w > 0).sum()) < MIN_LINES:
        return [None] * len(samples), {**rec, "reason": "too few partial pixels before a known background"}
    inv, gsum = cell_groups(cat["pts"], extent / cells)
    fill = np.concatenate([filled(s["C"], s["B"], s["a"], s["F0"]) for s in have])  # each view's own exposure
    view = np.concatenate([np.full(len(s["a"]), v) for v, s in enumerate(samples) if s is not None])
    from capture.matting_cells import KEEP_ACROSS, after_crossing, agreeing_before, object_sig2

    why, before = agreeing_before(cat["C"], cat["B"], w, cat["a"], cat["F0"])
    if why:
        return [None] * len(samples), {**rec, "global": before, "reason": why}
    F, sig2, F_obj, kv, rec["global"] = cross_cells(cat["C"], cat["B"], w, cat["a"], cat["F0"], fill, gsum, inv,
                                                    view, len(samples))
    why = after_crossing(rec["global"])
    rec["global"].update({"gate": before["agreeing"]} if before else {})
    if why:
        return [None] * len(samples), {**rec, "reason": why}
    F, sig2 = F[inv], sig2[inv]
    ok = np.isfinite(sig2)
    rec["global_coloured"] = rec["filled_coloured"] = rec["across"] = 0
    s2o = object_sig2(F_obj, rec["global"])
    out, off, blind = [], 0, 0
    for v, s in enumerate(samples):
        if s is None:
            out.append(None)
            continue
        k = slice(off, off + len(s["a"]))
        off += len(s["a"])
        sa = None if sigma_alpha is None else sigma_alpha[v]
        use = ok[k].copy()
        if sigma_alpha is not None:
            blind += int(sa is None)
            a2 = np.maximum(cat["a"][k], 1e-6) ** 2
            unmix2 = 0.0 if sa is None else \
                (sa ** 2 * ((cat["B"][k] - F[k]) ** 2).sum(-1) + ((1.0 - cat["a"][k]) * sb[k]) ** 2) / a2
            use &= sig2[k] < unmix2
        rec["coloured"] += int(use.sum())
        allowed = sigma_alpha is None or sa is not None
        use, Fv, n_obj, n_fill = with_object_colour(use, ok[k], fill[k], F[k], F_obj, allowed, kv[v])
        rec["global_coloured"], rec["filled_coloured"] = rec["global_coloured"] + n_obj, rec["filled_coloured"] + n_fill
        out.append(_view_out(cat["C"][k][use], cat["B"][k][use], Fv[use], np.where(ok[k], sig2[k], s2o or 0.0)[use],
                             sb[k][use], ((ok[k] | (s2o is not None)) & cat["usable"][k])[use], s["index"][use], g[v],
                             rec, KEEP_ACROSS and sigma_alpha is not None and sa is not None))
    rec["crossed"] = int(ok.sum())
    if blind:
        rec["views_without_alpha_error"] = blind
    if not ok.any():
        rec["reason"] = "the lines cross in no cell (too few, or the backgrounds behind them too alike)"
    else:
        rec["sigma_median"] = round(float(np.sqrt(np.median(sig2[ok]))), 5)
    return out, rec

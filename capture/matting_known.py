"""Matting with a known background (issue 30): alpha and the object's own colour from C = a F + (1 - a) B.

With the background B under every pixel known (a clean plate, ``capture.plate``; a plain backdrop),
the compositing equation leaves one unknown per pixel instead of four: the difference D = C - B
lies along F - B, and only how far (1 / a) is open.  :func:`known_background_matte` closes it:

1. **Bounds.**  F lies in [0, 1] per channel, so a >= max over channels of (C - B) / (1 - B) where
   C > B and (B - C) / B where C < B, less the noise of C and of the plate (``NOISE_ABS``,
   ``NOISE_REL`` of B; a JPEG's subsampled chroma: capture.jpeg_chroma): :func:`alpha_lower_bound`.  Where C or B
   is clipped in a channel, only the channels clipped in neither give data, and a clipped plate a bound
   (capture.matting_channels).
2. **Candidate colours.**  Each pixel's F is sought among a few candidate colours: the colour of
   the nearest sure foreground (the trimap's opaque pixels and pixels whose bound is above
   ``SOURCE_ALPHA``, taken as opaque, F = C: capture.matting_sources), filled outwards by a push-pull
   pyramid (:func:`capture.fill.push_pull`), and a palette of the view's sure foreground colours
   (``capture.matting_palette.PALETTE_SIZE``, k-means); sources only where B is known (``SOURCES_KNOWN_ONLY``;
   :func:`colour_sources` and :func:`fit_candidates`, shared with capture.matting_scale).  Per
   candidate P, alpha is the projection of D on P - B, clipped to [bound, 1]; the candidate that
   explains C best (least residual) wins, a palette colour only by ``PALETTE_MARGIN`` over the
   nearest sure colour: sampling matting (Wang & Cohen 2007; He et al. 2011) with the background a
   sample known exactly.
3. **Smooth solve.**  Those per-pixel alphas enter the closed-form matting system (Levin et al.
   2008; pymatting's Laplacian) as a data term weighted by how well the winning candidate is told
   from B (``SEPARATION``) and how well it explains C (``RESIDUAL``): (L + lambda W) a = lambda W a_hat
   with the trimap's opaque and background pixels fixed; where B is unknown W = 0 and the
   Laplacian alone decides (today's estimate).  Then a >= bound again.
4. **Colour.**  Where B is known and a > 0, F = B + (C - B) / a exactly: the
   premultiplied colour a F = C - (1 - a) B reproduces the photo over B and, over black (B = 0), is
   the photo itself, whatever a is.  Elsewhere F is pymatting's ML foreground (Germer et al. 2020).
   Where B is the frames' lines' estimate, capture.matting_colour chooses per pixel (``colour``).

:func:`known_background_matte` is the fast path (pymatting's numba Laplacian, incomplete-Cholesky
conjugate gradient); :func:`known_background_matte_reference` the slow numpy / scipy twin (the
Laplacian built window by window, a sparse direct solve) for tests on small crops.  Both take an
image, its trimap and its background: a function of the pixels alone, so that it can run on a
downscaled crop (issue 32).
"""

from __future__ import annotations

import numpy as np

from capture import matting_channels as mch
from capture.fill import push_pull
from capture.jpeg_chroma import chroma_allowance
from capture.matting_bound import clipped_mask, lower_bound
from capture.matting_candidates_kernel import fit_fused
from capture.matting_cap import blown_cap
from capture.matting_fast import channel_max, channel_sum, dilate
from capture.matting_fringe import fill_colour
from capture.matting_guide import view_guide
from capture.matting_interior import interior, opaque_sources, unseen_fill
from capture.matting_palette import palette
from capture.matting_sources import source_coverage
from capture.matting_window import window_candidates

#: Trimap values (pymatting's convention, as capture.matting).
BG, UNKNOWN, FG = 0.0, 0.5, 1.0
#: Noise of C = a F + (1 - a) B (linear): |C - B| up to NOISE_ABS + NOISE_REL * B is no evidence (8-bit, the plate).
NOISE_ABS = 0.004
NOISE_REL = 0.03
#: Pixels whose alpha bound is at least this are sure foreground colour sources (step 2).
SOURCE_ALPHA = 0.85
#: The sure colour sources only where the background is known (step 2; the depth's opaque pixels
#: before a blown-out window or a background no frame gave are left out: a needle over the window
#: there is a pale mixture).  Path-traced conifer turntable, 6 kept views, the partial band's alpha
#: MSE where B was seen / estimated, with PALETTE_MARGIN 0.02: all sources 0.0057 / 0.0062, only
#: where B is known 0.0022 / 0.0049, leaving out only blown-out photo pixels and those before a
#: blown-out B whose bound against it is below SOURCE_ALPHA 0.0039 / 0.0055.
SOURCES_KNOWN_ONLY = True
#: Refinement passes (step 2 again with the solved alphas above REFINE_ALPHA as colour sources).
REFINE_PASSES = 0
REFINE_ALPHA = 0.5
#: Linear level at which a channel counts as clipped (8-bit sRGB 252).
CLIP_LEVEL = 0.975
#: Where the plate is blown out and the photo is not, alpha is kept above the bound against the plate
#: (:func:`blown_bound`; the matte's alpha there is the Laplacian's, the data term's only from the channels a
#: clipped pixel keeps, capture.matting_channels).
BLOWN_BOUND = True
#: Alpha from which a pixel whose background is not known is taken as opaque (F = C).
OPAQUE_ALPHA = 0.999
#: Where B is unknown but the nearest known plate is at least this bright (linear, largest channel),
#: the partial pixels take the nearest sure colours (push-pull); before a darker one pymatting's ML
#: foreground, whose error grows with B (step 4).
FILL_BRIGHT = 0.15
#: Where B is blown out or not known, the colour is filled (push-pull) from the pixels whose exact
#: F = B + (C - B) / a has alpha at least this: the sure colours of step 2 (the plate's error enters
#: F times (1 - a) / a).  Was REFINE_ALPHA (0.5) until alpha before a blown-out wall came right
#: (capture.matting_blind): the conifer turntable's kept views, premultiplied colour MSE of the
#: blown-out pixels against the black twin (6 views) 0.0015 at 0.5, 0.0007 at 0.7, 0.0006 at 0.85,
#: 0.0004 at 0.95; taken as SOURCE_ALPHA rather than tuned on that capture.
FILL_ALPHA = SOURCE_ALPHA
#: Fewer sure colour sources than MIN_SOURCES where B is known: the opaque pixels (alpha >= OPAQUE_ALPHA, the photo
#: not clipped: their colour is the photo's) are sources too.
OPAQUE_SOURCES = True
#: Fewer sure colour sources than this: the colour where B is not known is pymatting's estimate.
MIN_SOURCES = 50
#: Data-term confidence: a candidate that differs from B by SEPARATION (linear, Euclidean) gets half weight; a
#: residual of RESIDUAL (linear) halves it again.  0.1 since stop 73 (was 0.05): where |P - B| is 0.05-0.1 the data
#: term's alpha errs by 0.13-0.14 RMS on the conifers (scripts/data_term_error.py), which 0.05 weighted 0.7; held out
#: +0.053 dB on average over eleven rooms, over black the same (docs/matting.md "The data term's half weight").
SEPARATION = 0.1
RESIDUAL = 0.03
#: A palette colour wins over the nearest sure colour only when its residual is smaller by this
#: (linear): along the line from B through C every colour explains C exactly, so before a bright
#: room the dark needle colours of the palette all fit a partial pixel within noise and the first
#: by chance set its alpha.  Path-traced conifer turntable, 6 kept views, the partial band's alpha
#: MSE where B was seen / estimated: margin 0 0.0067 / 0.0072, 0.01 0.0030 / 0.0055, 0.02
#: 0.0022 / 0.0049, 0.04 and no palette 0.0022 / 0.0049-0.0050; on tests/plate_scenes.needle_composite
#: (green needles by a brown core: the nearest sure colour is often the core's) no palette cost
#: +20 % alpha MSE, the margin 0.02 -2 % to +1 %.
PALETTE_MARGIN = 0.02
#: Step 2's candidates include the colour each pixel's window of lines meets at over a textured known background
#: (capture.matting_window), in windows of radius WINDOW_RADIUS.  Off: on the path-traced conifer turntable it left the
#: kept views' alpha MSE as it was (the fit passed its checks in 10-13 % of the band, its colour error 0.10 median
#: against the nearest sure colour's 0.045) for 0.15 s a view; on tests/plate_scenes.needle_composite -10 to -30 %.
WINDOW_CANDIDATE = False
WINDOW_RADIUS = 3
#: Weight lambda of the data term against the matting Laplacian (and against capture.matting_blind's priors, whose
#: weights are absolute).  Swept in stop 82 (docs/matting.md "The data term's weight"): 0.1 / 0.3 took three 320 x 240
#: room conifers up by 1.1-1.8 dB and two courtyard turntables down by 0.6-1.25 dB / 0.05 SSIM; kept at 1.
DATA_WEIGHT = 1.0
#: Where the background is known, the depth's opaque pixels are unknown too, with a prior towards
#: opaque of this weight (against DATA_WEIGHT x confidence): a gap between needles inside the
#: depth's silhouette shows the background through it.
OPAQUE_PRIOR = 0.05
#: Closed-form Laplacian regularisation and window radius.  Epsilon is larger than capture.matting's
#: 1e-7 (there the Laplacian alone decides): with B known the data term carries the alpha, and a
#: smoother colour-line model across a textured background lets it.  Path-traced conifer, held out
#: (gather masked PSNR / SSIM): orbit 24.31 / 0.552 -> 24.89 / 0.559, turntable 22.25 / 0.481 ->
#: 22.31 / 0.477, the 315 degree turn 23.82 / 0.550 -> 23.78 / 0.530; 1e-4 took the orbit to 25.25
#: but SSIM down by 0.02-0.06 everywhere.
CF_EPSILON = 1e-5
CF_RADIUS = 1
#: Conjugate-gradient iterations before the solve gives up (then the per-pixel alphas stand), and its
#: relative residual (the data term conditions the system: 1e-5 changes alpha by < 1e-3).
CG_MAX_ITERATIONS = 2000
CG_RTOL = 1e-6
#: The incomplete Cholesky preconditioner (pymatting's ichol) drops entries below this.  pymatting's
#: default 1e-4 with CG_RTOL 1e-5 was the solve before issue 32's round 5; 3e-3 with 1e-6 builds in
#: about half the time and takes 11-12 iterations for 3, as close to the exact solve on phone views
#: (largest alpha error 1-3e-4 either way; docs/speed.md round 5; tests/capture/test_matting_known.py).
#: 3e-2 no longer factors without pymatting's diagonal shifts (a second build).
ICHOL_DISCARD = 3e-3
#: Trimap widening: a background pixel of the depth's trimap within this fraction of the image width of the unknown
#: band whose alpha bound is above WIDEN_ALPHA becomes unknown (a needle no depth pixel saw); 12 px at 640.
WIDEN_FRACTION = 12 / 640
WIDEN_ALPHA = 0.0
#: ... and at least this many pixels (a small image: the bottom of a sphere whose depth the extent
#: stage cut two rows short stayed background at 1 px, and the Laplacian dragged the sphere's alpha
#: down to 0.53 from there).
WIDEN_MIN_PX = 3


def widen_px(width: int) -> int:
    """Pixels of the trimap widening in an image (or crop) ``width`` wide: WIDEN_FRACTION of it, at
    least WIDEN_MIN_PX."""
    return max(WIDEN_MIN_PX, int(round(WIDEN_FRACTION * width)))


def alpha_lower_bound(image: np.ndarray, background: np.ndarray, noise: float = NOISE_ABS,
                      chroma: bool = False) -> np.ndarray:
    """(h, w) least alpha for which F = B + (C - B) / a stays in [0, 1] (step 1 of the module
    docstring), with the noise allowance (``noise`` + NOISE_REL B, linear) taken off: 0 where C is
    within noise of B.  capture.matting_bound's compiled pass when it takes the arrays.  ``chroma``: a
    (h, w, 3) frame whose chroma was subsampled (a JPEG's) also has capture.jpeg_chroma's allowance."""
    chroma = chroma and np.ndim(image) == 3
    if not chroma and (fused := lower_bound(image, background, noise, NOISE_REL)) is not None:
        return fused
    C = np.asarray(image, np.float64)
    B = np.asarray(background, np.float64)
    d = C - B
    allow = noise + NOISE_REL * B
    slack = np.abs(d) - (allow + chroma_allowance(C) if chroma else allow)
    room = np.where(d > 0, 1.0 - B, B)
    lo = np.where(slack > 0, slack / np.maximum(room, 1e-6), 0.0)
    return np.clip(channel_max(lo), 0.0, 1.0)


def candidate_alpha(image: np.ndarray, background: np.ndarray, candidates: np.ndarray,
                    lower: np.ndarray, margin: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Per pixel the best of the candidate colours (step 2): (alpha_hat (h, w), confidence (h, w)).
    ``candidates`` (K, h, w, 3), or a sequence of K such arrays: per-pixel candidate colours (a palette
    colour broadcast); a
    candidate after the first wins only with a residual smaller by ``margin``."""
    C = np.asarray(image, np.float64)
    B = np.asarray(background, np.float64)
    D = C - B
    best_res = np.full(C.shape[:2], np.inf)
    a_hat = np.zeros(C.shape[:2])
    sep = np.zeros(C.shape[:2])
    best_cost = np.full(C.shape[:2], np.inf)
    for k, P in enumerate(candidates):
        E = P - B
        e2 = channel_sum(E * E)
        de = channel_sum(D * E)
        a = np.clip(de / np.maximum(e2, 1e-9), lower, 1.0)
        res = np.sqrt(channel_sum((D - a[..., None] * E) ** 2))
        cost = res + (margin if k else 0.0)
        better = cost < best_cost
        best_cost = np.where(better, cost, best_cost)
        best_res = np.where(better, res, best_res)
        a_hat = np.where(better, a, a_hat)
        sep = np.where(better, np.sqrt(e2), sep)
    conf = (sep ** 2 / (sep ** 2 + SEPARATION ** 2)) * (RESIDUAL ** 2 / (best_res ** 2 + RESIDUAL ** 2))
    return a_hat, np.where(np.isfinite(best_res), conf, 0.0)


def colour_sources(opaque: np.ndarray, known: np.ndarray, lower: np.ndarray) -> np.ndarray:
    """(h, w) bool: step 2's sure foreground colour sources, taken as opaque (F = C): the depth's
    ``opaque`` pixels (their colour, even where a gap shows the room: with them left out the
    candidates were the darkest needles and alpha came out 0.06 low) and the pixels whose bound
    ``lower`` says nearly opaque (SOURCE_ALPHA); both only where the background is ``known``
    (SOURCES_KNOWN_ONLY): before a blown-out window or a background no frame gave, a depth-opaque
    pixel may be a needle over the window (white sources: issue 30 third round, docs/matting.md).
    Shared by the full-size path (:func:`data_term`) and the working-resolution one
    (capture.matting_scale)."""
    known = np.asarray(known, bool)
    src = np.asarray(opaque, bool) | (known & (np.asarray(lower) >= SOURCE_ALPHA))
    return src & known if SOURCES_KNOWN_ONLY else src


def fit_candidates(image: np.ndarray, background: np.ndarray, nearest: np.ndarray, sources: np.ndarray,
                   lower: np.ndarray, extra=()) -> tuple[np.ndarray, np.ndarray]:
    """Step 2's choice (:func:`candidate_alpha`): (alpha_hat, confidence) of ``image`` (..., 3) before
    ``background`` from the nearest sure colour ``nearest`` (same shape) first, then the palette of
    the sources' colours ``sources`` (N, 3) and any ``extra`` candidates (same shape as ``image``),
    each of which wins over it only by PALETTE_MARGIN.  Shared by the full-size path and the
    working-resolution one (capture.matting_scale)."""
    shape, pal = np.shape(image), palette(sources)  # capture.matting_candidates_kernel when it takes them
    if (fused := fit_fused(image, background, nearest, pal, extra, lower, PALETTE_MARGIN, SEPARATION, RESIDUAL)):
        return fused
    cands = [nearest] + [np.broadcast_to(p, shape) for p in pal] + list(extra)
    return candidate_alpha(image, background, cands, lower, PALETTE_MARGIN)  # a list: np.stack copied them all


def widen_trimap(trimap: np.ndarray, lower: np.ndarray, known: np.ndarray) -> np.ndarray:
    """``trimap`` with its background pixels near the unknown band (:func:`widen_px` of its width)
    made unknown where the known background cannot explain them (alpha bound above WIDEN_ALPHA)."""
    tri = np.asarray(trimap, np.float64).copy()
    near = dilate(tri > BG, widen_px(tri.shape[1]))  # ndimage.binary_dilation(..., iterations=...)
    grow = (tri <= BG) & near & np.asarray(known, bool) & (lower > WIDEN_ALPHA)
    tri[dilate(grow) & near & (tri <= BG) & np.asarray(known, bool)] = UNKNOWN
    return tri


def solve_trimap(trimap: np.ndarray, image: np.ndarray, background: np.ndarray, known: np.ndarray,
                 noise: float, chroma: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(trimap solved, opaque prior (h, w) bool): the depth's ``trimap`` widened (:func:`widen_trimap`)
    and its opaque pixels made unknown where the background is known (they keep a prior)."""
    known = np.asarray(known, bool)
    lower = np.where(known, alpha_lower_bound(image, background, noise, chroma), 0.0)
    tri = widen_trimap(np.asarray(trimap, np.float64), lower, known)
    opaque = (tri >= FG) & known
    tri[opaque] = UNKNOWN
    return tri, opaque


def data_term(image: np.ndarray, trimap: np.ndarray, background: np.ndarray, known: np.ndarray,
              noise: float = NOISE_ABS, alpha: np.ndarray | None = None,
              opaque: np.ndarray | None = None, blown: np.ndarray | None = None, chroma: bool = False,
              coverage: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(target alpha, weight, lower bound, similar), each (h, w), of steps 1-2 for the unknown pixels of
    ``trimap``; weight and bound are 0 where the background is not known; similar: the nearest sure colour
    within SEPARATION of B (alpha barely moves C there; capture.matting_blind.WEAK_PRIOR).  ``alpha``: a previous
    solve, whose pixels above REFINE_ALPHA become the colour sources; ``opaque``: pixels the depth
    calls opaque (a prior towards 1 of weight OPAQUE_PRIOR, and colour sources on the first pass);
    ``blown``: (h, w) the pixels whose B is given but clipped (capture.matting_channels' data and bound);
    ``coverage``: the sources' measured coverage (capture.matting_sources.capture_coverage; None: opaque)."""
    C = np.clip(np.asarray(image, np.float64), 0.0, 1.0)
    B = np.clip(np.asarray(background, np.float64), 0.0, 1.0)
    known = np.asarray(known, bool)
    opaque = (trimap >= FG) if opaque is None else (np.asarray(opaque, bool) | (trimap >= FG))
    lower = np.where(known, alpha_lower_bound(C, B, noise, chroma), 0.0)
    if alpha is None:
        src = colour_sources(opaque, known, lower)
        a_src = source_coverage(lower, src, coverage)
    else:
        a_src = np.maximum(lower, alpha)
        src = (trimap >= FG) | (a_src >= REFINE_ALPHA)
    Fs = np.clip(np.where(known[..., None], B + (C - B) / np.maximum(a_src, 1e-6)[..., None], C), 0.0, 1.0)
    unk = trimap == UNKNOWN
    if src.any():
        extra = window_candidates(C, B, known, WINDOW_RADIUS, known & unk) if WINDOW_CANDIDATE else []
        a_hat, conf = fit_candidates(C, B, near := push_pull(Fs, src.astype(np.float64)), Fs[src], lower, extra)
        similar = unk & (channel_sum((near - B) ** 2) < SEPARATION ** 2)
        w_data = DATA_WEIGHT * np.where(known & unk, conf, 0.0)
        if blown is not None and (ch := mch.open_channels(C, B, CLIP_LEVEL, blown & unk)) is not None:
            a_hat, w_data = mch.open_channel_term(C, B, near, ch, ch.any(-1), a_hat, w_data,
                                                  (DATA_WEIGHT, SEPARATION, RESIDUAL))
        if blown is not None:  # the bound against a blown plate with the candidate's colour
            lower = np.maximum(lower, mch.colour_bound(C, B, near, blown & unk, CLIP_LEVEL, noise))
    else:
        a_hat, w_data, similar = np.zeros(C.shape[:2]), np.zeros(C.shape[:2]), np.zeros(C.shape[:2], bool)
    w_op = np.where(opaque & unk, OPAQUE_PRIOR, 0.0)
    w = w_data + w_op
    target = np.where(w > 0, (w_data * a_hat + w_op) / np.maximum(w, 1e-12), 0.0)
    return target, w, lower, similar


def _system(L, trimap: np.ndarray, a_hat: np.ndarray, weight: np.ndarray):
    """(A, b, unknown mask) of (L_U + lambda W_U) a_U = -R a_K + lambda W_U a_hat_U (step 3)."""
    from scipy.sparse import diags

    t = trimap.ravel()
    unk = t == UNKNOWN
    fixed = (t >= FG).astype(np.float64)
    L = L.tocsr()
    w = weight.ravel()[unk]
    A = L[unk][:, unk] + diags(w)
    b = -L[unk][:, ~unk] @ fixed[~unk] + w * a_hat.ravel()[unk]
    return A.tocsr(), b, unk


def _alpha(trimap: np.ndarray, a_u: np.ndarray, unk: np.ndarray, lower: np.ndarray) -> np.ndarray:
    """(h, w) alpha: the trimap's fixed values, the solved unknowns ``a_u`` kept above ``lower``."""
    a = (trimap >= FG).astype(np.float64).ravel()
    a[unk] = a_u
    a = np.clip(np.maximum(a.reshape(trimap.shape), lower), 0.0, 1.0)
    a[trimap <= BG] = 0.0
    a[trimap >= FG] = 1.0
    return a


def _finish(image, trimap, background, known, a_u, unk, lower, fallback_fg, colour=None, record=None):
    """(alpha, F) of step 4 from the solved unknown alphas ``a_u``; ``colour(image, alpha, background,
    known)``: where B counts as known for the colour (capture.matting_colour.colour_gate; None: ``known``);
    ``record``: :func:`foreground_colour`'s."""
    a = _alpha(trimap, a_u, unk, lower)
    return a, foreground_colour(image, a, background, known if colour is None else colour(image, a, background, known),
                                fallback_fg, record)


def clipped(image: np.ndarray, background: np.ndarray) -> np.ndarray:
    """(h, w) bool: pixels where the photo or the plate reaches CLIP_LEVEL in a channel.  There
    C = a F + (1 - a) B no longer holds (the true B of a blown-out window is above 1), so B
    counts as unknown there.  capture.matting_bound's compiled pass when it takes the arrays."""
    if (fused := clipped_mask(image, background, CLIP_LEVEL)) is not None:
        return fused
    return (channel_max(image) >= CLIP_LEVEL) | (channel_max(background) >= CLIP_LEVEL)


def blown_bound(image: np.ndarray, background: np.ndarray, where: np.ndarray, noise: float,
                chroma: bool = False) -> np.ndarray:
    """(h, w) least alpha at the ``where`` pixels whose plate is blown out (:func:`clipped`) but whose
    photo is not: the true background there is at least the plate, so the bound against the plate
    (:func:`alpha_lower_bound`; darker than it, C - B < 0, needs alpha >= (B - C) / B, which only
    grows with B) still holds; 0 elsewhere and with BLOWN_BOUND off."""
    C = np.asarray(image, np.float64)
    use = np.asarray(where, bool) & (channel_max(C) < CLIP_LEVEL) & (channel_max(background) >= CLIP_LEVEL)
    if not BLOWN_BOUND or not use.any():
        return np.zeros(C.shape[:2])
    B = np.clip(np.asarray(background, np.float64), 0.0, 1.0)
    return np.where(use, alpha_lower_bound(C, B, noise, chroma), 0.0)


def foreground_colour(image: np.ndarray, alpha: np.ndarray, background: np.ndarray, known: np.ndarray,
                      fallback_fg, record: dict | None = None) -> np.ndarray:
    """(h, w, 3) float64 straight colour in [0, 1] (step 4): F = B + (C - B) / alpha where B is ``known``, not
    :func:`clipped` and alpha > 0.  Where B is known but blown out, the colour of the nearest pixels whose F is exact
    and alpha at least FILL_ALPHA (a push-pull fill: the needle's own colour; pymatting's estimate there takes the
    white window into F: a conifer before a blown-out wall came out white, premultiplied colour 18.1 dB against the
    truth over black, 21.7 dB with the fill); a partial pixel's, the view's measured fringe's (capture.matting_fringe);
    the object's interior, its photo (capture.matting_interior).  Where B is not known, ``fallback_fg(C, alpha, need)``
    (pymatting's ML foreground: the fill there made blocks of a far colour on a fur ball whose sides no other view saw
    behind, 10.6 dB held out against 20.1).  Where alpha is 0, the nearest sure object colour.  Before a blown plate
    the colour is kept within the photo (capture.matting_cap).  ``record`` (a dict) gets ``opaque_sources``, the
    pixels filled, where OPAQUE_SOURCES gave the fill its sources, ``fringe``, ``interior`` and ``unseen_blown``."""
    C = np.clip(np.asarray(image, np.float64), 0.0, 1.0)
    B = np.clip(np.asarray(background, np.float64), 0.0, 1.0)
    a = np.asarray(alpha, np.float64)
    known = np.asarray(known, bool)
    blown = known & clipped(C, B) & (a > 0)
    ok = known & ~blown & (a > 0)
    F = np.clip(B + (C - B) / np.maximum(a, 1e-6)[..., None], 0.0, 1.0)
    # an opaque pixel is its own colour whatever B, unless B is blown out ("opaque" the depth's guess) off the interior
    inner = interior(C, a, B, known, OPAQUE_ALPHA, CLIP_LEVEL, record)  # (capture.matting_interior)
    need = (a > 0) & ~ok & ((a < OPAQUE_ALPHA) | blown) & ~inner
    if not need.any():
        return _extended(unseen_fill(np.where(ok[..., None], F, C), C, a, B, known, blown, record), a)
    sure = ok & (a >= FILL_ALPHA)
    opaque = OPAQUE_SOURCES and sure.sum() < MIN_SOURCES
    if opaque:
        sure = sure | (opaque_sources(blown, inner) & (a >= OPAQUE_ALPHA) & (channel_max(C) < CLIP_LEVEL))
    fill = np.zeros(a.shape, bool)
    if sure.sum() >= MIN_SOURCES:  # before a bright background (blown out or not known: the plate's nearest)
        bright = channel_max(push_pull(B, (known & ~blown).astype(np.float64))) >= FILL_BRIGHT if known.any() \
            else np.zeros(a.shape, bool)
        fill = need & (blown | bright)
        if opaque and record is not None and fill.any():
            record["opaque_sources"] = int(fill.sum())
    rest = need & ~fill
    fb = np.asarray(fallback_fg(C, a, rest), np.float64) if rest.any() else C
    if fill.any():  # the body's; a partial pixel's before a blown plate the view's fringe's (matting_fringe)
        fb = np.where(fill[..., None], fill_colour(F, B, a, ok, sure, blown, FILL_ALPHA, MIN_SOURCES, record), fb)
    out = np.clip(np.where(ok[..., None], F, np.where(need[..., None], fb, C)), 0.0, 1.0)
    return _extended(blown_cap(unseen_fill(out, C, a, B, known, blown, record), C, a, B, blown), a)


def _extended(F: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """``F`` with its alpha-0 pixels given the nearest sure object colour (a push-pull fill from the
    pixels with alpha at least REFINE_ALPHA: a faint pixel's F = B + (C - B) / alpha carries its noise
    times 1 / alpha), as pymatting's ML foreground extends it: a bilinear lookup across the object's
    edge (the photometric stage's, a texture's) then mixes no background into the object's colour."""
    zero = alpha <= 0
    sure = alpha >= REFINE_ALPHA
    if not zero.any() or not sure.any():
        return F
    return np.where(zero[..., None], push_pull(F, sure.astype(np.float64)), F)


def _passes(img, trimap, background, known, noise, laplacian, solve, mask=None, record=None, chroma=False,
            coverage=None):
    """Steps 1-3 (module docstring) with ``laplacian(img, unknown (h, w) bool)`` and
    ``solve(A, b, x0 or None) -> (x, converged)``: (alpha_u, unknown mask (h w,), lower bound,
    trimap solved, known as given (blown-out pixels included: step 4 tells them), converged).
    ``mask``: the object's depth (h, w) bool, for the prior where the photo is blown out
    (capture.matting_blind); its record goes into ``record`` (a dict) when given; ``chroma``: alpha_lower_bound's."""
    from capture.matting_blind import blind_prior

    given = np.asarray(known, bool)
    known = given & ~clipped(img, background)
    floor = blown_bound(img, background, given & ~known, noise, chroma)
    tri, opaque = solve_trimap(trimap, img, background, known, noise, chroma)
    unk_map = tri == UNKNOWN
    if record is not None:  # the channels a clip leaves (capture.matting_channels): the same in every pass
        record["clipped_channels"] = mch.open_count(img, background, CLIP_LEVEL, given & ~known & unk_map)
    converged, a_prev = True, None
    unk, a_u = unk_map.ravel(), np.zeros(0)
    L, has = None, unk_map.any()
    for _ in range(1 + REFINE_PASSES if has else 1):
        a_hat, weight, lower, similar = data_term(img, tri, background, known, noise, a_prev, opaque, given & ~known,
                                                  chroma, coverage)
        lower = np.maximum(lower, floor)
        a_hat, weight, rec = blind_prior(img, unk_map, a_hat, weight, mask, similar)
        if record is not None:
            record["blind_prior"] = rec
        if not has:
            break
        L = laplacian(view_guide(img, rec), unk_map) if L is None else L  # capture.matting_guide
        A, b, unk = _system(L, tri, a_hat, weight)
        a_u, ok = solve(A, b, None if a_prev is None else a_prev.ravel()[unk])
        if not ok:  # the per-pixel alphas of step 2 stand
            a_u, converged = a_hat.ravel()[unk], False
        a_prev = _alpha(tri, a_u, unk, lower)
    return a_u, unk, lower, tri, given, converged


def known_background_matte(image: np.ndarray, trimap: np.ndarray, background: np.ndarray, known: np.ndarray,
                           noise: float = NOISE_ABS, mask: np.ndarray | None = None,
                           record: dict | None = None, colour=None,
                           chroma: bool = False, coverage: float | None = None
                           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
    """(alpha (h, w), straight colour F (h, w, 3), the trimap solved (widened), converged) of
    linear ``image`` (h, w, 3) under ``trimap`` (BG / UNKNOWN / FG) with the background
    ``background`` (h, w, 3) known where ``known`` (h, w); ``noise``: linear noise of C - B (module
    docstring).  Not converged: the per-pixel alphas of step 2 stand.  ``mask``: the object's depth
    (h, w) bool, for the prior where the photo is blown out (capture.matting_blind; None: none);
    ``record``: a dict that gets its record; ``colour``: step 4's rule for where B counts as known
    (:func:`_finish`); ``chroma``: the frame's chroma was subsampled (:func:`alpha_lower_bound`); ``coverage``: the
    depth-opaque sources' measured coverage (capture.matting_sources.capture_coverage; None: opaque)."""
    from pymatting import cf_laplacian

    from capture.foreground_ml import ml_foreground_in
    from capture.matting_fast import pcg

    pre = {}  # one preconditioner for every pass (they differ in the data weights only)

    def solve(A, b, x0):
        return pcg(A, b, x0, pre, ICHOL_DISCARD, CG_RTOL, CG_MAX_ITERATIONS)

    img = np.clip(np.asarray(image, np.float64), 0.0, 1.0)
    a_u, unk, lower, tri, known, ok = _passes(img, trimap, background, known, noise,
        lambda im, u: cf_laplacian(im, epsilon=CF_EPSILON, radius=CF_RADIUS, is_known=~u), solve, mask, record, chroma,
        coverage)
    a, F = _finish(img, tri, background, known, a_u, unk, lower, ml_foreground_in, colour, record)
    return a, F, tri, ok


def known_background_matte_reference(image: np.ndarray, trimap: np.ndarray, background: np.ndarray,
                                     known: np.ndarray, noise: float = NOISE_ABS,
                                     mask: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The slow twin of :func:`known_background_matte` (same steps; the matting Laplacian built
    window by window in numpy, a sparse direct solve; F where not exact: the image itself).
    Small crops only."""
    from scipy.sparse.linalg import spsolve

    from capture.matting import closed_form_laplacian_reference

    img = np.clip(np.asarray(image, np.float64), 0.0, 1.0)
    a_u, unk, lower, tri, known, _ = _passes(
        img, trimap, background, known, noise, lambda im, u: closed_form_laplacian_reference(im, CF_EPSILON),
        lambda A, b, x0: (spsolve(A.tocsc(), b), True), mask)
    a, F = _finish(img, tri, background, known, a_u, unk, lower, lambda C, a, need: C)
    return a, F

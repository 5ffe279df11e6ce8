"""Numpy twin of the microfacet renderer's geometry (docs/methods.md §1.2-§1.7).

Everything the shaders compute is written here once more in plain float64 numpy, so that
tests can compare the GPU output with an obviously-correct reference:

* the slice spacing l and pyramid level from the screen-space tolerance E (Eq. 8-11) are in
  ``render/microfacet/lod.py``: they run on the CPU once per frame and reach the GPU as uniforms.
* :func:`slice_distances`: slices perpendicular to the ray eye -> voxel centre, at distances
  n*l from the eye, only where their clip slab meets the voxel, at least one (docs/methods.md §1.2);
  :func:`slice_half_extents`: the quad that covers the voxel seen from the eye.
* :func:`select_cameras`: per voxel, input cameras in increasing angle phi whose image holds
  the voxel's footprint; the nearest ``K_BLEND`` are blended with unstructured-lumigraph
  weights (Buehler et al. 2001), the next ones are per-fragment fallbacks (docs/methods.md §1.3).
* :func:`eq2_pass`: the RGBz depth clip |d - D| < l/2 (Eq. 2, docs/methods.md §1.4);
  :func:`classify` / :func:`shade_fragments`: why a camera rejects (occluded, saw through,
  unsure), the weighted vote of the blend cameras and the per-fragment fallback.
The brute-force ray caster of whole frames built from these is ``render/microfacet/reference.py``.

The GLSL counterparts are ``render/microfacet/shaders/microfacet_common.glsl`` and friends.
"""

from __future__ import annotations

import numpy as np

from capture.camera import Camera
from capture.sampling import nearest_pixel

#: A slice is a square of side sqrt(3) w, so it covers its voxel from every direction (§1.2).
SLICE_SIDE_FACTOR = float(np.sqrt(3.0))
#: Cameras blended per voxel (the nearest by phi).
K_BLEND = 3
#: Candidate cameras per voxel: K_BLEND blended + (K_CAND - K_BLEND) per-fragment fallbacks.
K_CAND = 6
#: Most slices one voxel may get (geometry-shader output bound); l is clamped so that
#: sqrt(3) w / l + 1 + 2 SLAB_COVER <= MAX_SLICES.
MAX_SLICES = 8
#: Footprint tested for "the camera's image contains the slice" (§1.3), as a multiple of the
#: voxel's bounding radius sqrt(3) w / 2: the projected centre must lie inside the image shrunk
#: by that many radii (1.0 = the paper's full containment; negative = grown, i.e. the footprint
#: only has to touch the image).  We use -1: fragments that fall outside a camera's image are
#: handled per fragment (NO_VIEW -> next camera), while full containment drops the nearest
#: camera for every coarse voxel near the image border (measured: input-pose PSNR on the fur
#: ball at 4^3 fell to 31 dB).
FOOTPRINT_SCALE = -1.0
#: Slices are generated where their clip slab [n l - c l, n l + c l] meets the voxel, c = this.
#: 0 is the paper's "where the slice plane intersects the voxel"; but Eq. 2 keeps only texels
#: within l/2 of a slice, so with 0 the ends of the voxel (up to l/2 deep) belong to no slice
#: and show as rings of holes.  0.5 makes the slabs of a voxel cover all of it.
SLAB_COVER = 0.5
#: Slice quads: True = the rectangle that just covers the perspective projection of the voxel
#: onto the slice plane (its 8 corners seen from the eye); False = the paper's square of side
#: sqrt(3) w.  Both cover the voxel from the current eye; the rectangle has about half the area
#: (fill is the cost driver of coarse levels on llvmpipe).
TIGHT_RECT = True
#: Rectangles are clamped to this many times the paper's half side (voxels next to the eye).
RECT_CLAMP = 2.0
#: Per-fragment fallback: how many candidates after the blend cameras are tried (0..K_CAND-K_BLEND).
#: Measured on the fur ball (6 held-out views, E = 8): 0 -> 19.20 dB, 210 ms; 1 -> 19.27 dB,
#: 214 ms; 3 -> 19.31 dB, 306 ms (llvmpipe, loaded machine).
N_FALLBACK = 1
#: Smallest angle used in the weights and in Eq. 10 (radians): avoids 1/0 when the eye
#: sits exactly on an input camera (that camera then takes all the weight).
PHI_EPS = 1e-6
#: Below this total weight the blend is considered empty and the first passing candidate is used.
WEIGHT_EPS = 1e-8
#: When fewer than K_BLEND + 1 cameras are valid, the ULR threshold is this factor times
#: the largest valid phi (so the last valid camera keeps a non-zero weight).
ULR_THRESHOLD_FACTOR = 2.0


# ------------------------------------------------------------------ selection footprint
def footprint_radius(w: float) -> float:
    """Radius (m) of the footprint tested in the camera selection for voxel size w."""
    return FOOTPRINT_SCALE * 0.5 * SLICE_SIDE_FACTOR * w


def slice_distances(centers: np.ndarray, w: float, eye_pos: np.ndarray, spacing: float,
                    near: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Slices of each voxel: distances s = n*l from the eye along its ray that cut the voxel.

    The plane {x : (x - eye) . v = s} (v = unit ray eye -> centre) meets the axis-aligned cube
    of side w iff |s - s_c| <= h with s_c = |centre - eye| and h = w/2 (|v_x| + |v_y| + |v_z|).
    Every voxel gets at least one slice (n = round(s_c / l) when no multiple falls inside);
    slices closer than ``near`` are dropped; at most MAX_SLICES, nearest to the centre kept.

    Returns:
        voxel: (M,) int64 voxel index of every slice.
        n: (M,) int64 slice number (its distance is n * spacing).
    """
    c = np.asarray(centers, dtype=np.float64).reshape(-1, 3)
    d = c - np.asarray(eye_pos, dtype=np.float64)
    sc = np.linalg.norm(d, axis=1)
    v = d / np.maximum(sc, 1e-12)[:, None]
    h = 0.5 * w * np.abs(v).sum(axis=1)
    lo = np.ceil((sc - h) / spacing - SLAB_COVER).astype(np.int64)
    hi = np.floor((sc + h) / spacing + SLAB_COVER).astype(np.int64)
    none = hi < lo
    lo[none] = hi[none] = np.round(sc[none] / spacing).astype(np.int64)
    # cap at MAX_SLICES (only reachable through rounding; l >= min_spacing)
    over = hi - lo + 1 > MAX_SLICES
    lo[over] = np.round(sc[over] / spacing).astype(np.int64) - (MAX_SLICES - 1) // 2
    hi[over] = lo[over] + MAX_SLICES - 1
    near_n = np.ceil(near / spacing - 1e-12).astype(np.int64) if near > 0 else None
    if near_n is not None:
        lo = np.maximum(lo, near_n)
    count = np.maximum(hi - lo + 1, 0)
    voxel = np.repeat(np.arange(len(c)), count)
    start = np.repeat(lo, count)
    off = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    return voxel, start + off


def slice_frame(centers: np.ndarray, eye_pos: np.ndarray, eye_right: np.ndarray, eye_up: np.ndarray):
    """Unit view direction v and in-plane axes (a, b) of each voxel's slices.

    a = the eye's right vector made perpendicular to v (the eye's up vector when they are
    parallel), b = v x a.  Returns three (N, 3) arrays.
    """
    d = np.asarray(centers, dtype=np.float64).reshape(-1, 3) - eye_pos
    v = d / np.maximum(np.linalg.norm(d, axis=1), 1e-12)[:, None]
    a = eye_right - (v @ eye_right)[:, None] * v
    na = np.linalg.norm(a, axis=1)
    bad = na < 1e-6
    if bad.any():
        a2 = eye_up - (v[bad] @ eye_up)[:, None] * v[bad]
        a[bad] = a2
        na[bad] = np.linalg.norm(a2, axis=1)
    a = a / na[:, None]
    b = np.cross(v, a)
    return v, a, b


# ------------------------------------------------------------------ cameras (§1.3)
def camera_angles(points: np.ndarray, eye_pos: np.ndarray, cameras) -> np.ndarray:
    """(N, C) angle phi (radians) between the view ray eye -> point and each camera's ray
    camera -> point."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    v = p - eye_pos
    v /= np.maximum(np.linalg.norm(v, axis=1), 1e-12)[:, None]
    out = np.empty((len(p), len(cameras)))
    for i, cam in enumerate(cameras):
        u = p - cam.center
        u /= np.maximum(np.linalg.norm(u, axis=1), 1e-12)[:, None]
        out[:, i] = np.arccos(np.clip((v * u).sum(axis=1), -1.0, 1.0))
    return out


def footprint_inside(points: np.ndarray, radius: float, cameras) -> np.ndarray:
    """(N, C) bool: the sphere of ``radius`` around each point lies in front of the camera and
    its projection (centre +- f r / z) lies inside the image [-0.5, W - 0.5] x [-0.5, H - 0.5].
    A negative radius grows the image instead (the point only has to be in front, z > 0)."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    out = np.zeros((len(p), len(cameras)), dtype=bool)
    for i, cam in enumerate(cameras):
        uv, z = cam.project(p)
        ok = z - max(radius, 0.0) > 0
        zs = np.where(ok, z, 1.0)
        ru = cam.K[0, 0] * radius / zs
        rv = cam.K[1, 1] * radius / zs
        with np.errstate(invalid="ignore"):
            ok &= (uv[:, 0] - ru >= -0.5) & (uv[:, 0] + ru <= cam.width - 0.5)
            ok &= (uv[:, 1] - rv >= -0.5) & (uv[:, 1] + rv <= cam.height - 0.5)
        out[:, i] = ok
    return out


def ulr_weights(phi_sorted: np.ndarray, n_valid: np.ndarray) -> np.ndarray:
    """Unstructured-lumigraph blend weights of the first K_BLEND of each row of ascending
    angles (Buehler et al. 2001): w_i = (1 - phi_i / t) / phi_i with t the (K_BLEND+1)-th
    angle (or ULR_THRESHOLD_FACTOR times the largest valid angle), normalised to sum 1.

    Args:
        phi_sorted: (N, >= K_BLEND + 1) ascending angles; entries past n_valid are ignored.
        n_valid: (N,) number of valid cameras per row.
    Returns:
        (N, K_BLEND) weights (0 for invalid slots).
    """
    N = len(phi_sorted)
    k = np.arange(K_BLEND)
    p = np.maximum(phi_sorted[:, :K_BLEND], PHI_EPS)
    last = np.take_along_axis(phi_sorted, np.clip(n_valid - 1, 0, None)[:, None], axis=1)[:, 0]
    t_next = phi_sorted[:, K_BLEND] if phi_sorted.shape[1] > K_BLEND else np.full(N, np.inf)
    t = np.where(n_valid > K_BLEND, t_next, ULR_THRESHOLD_FACTOR * np.maximum(last, PHI_EPS))
    with np.errstate(invalid="ignore"):
        w = np.maximum(1.0 - p / t[:, None], 0.0) / p
    w = np.nan_to_num(w, nan=0.0, posinf=0.0)
    w[k[None, :] >= n_valid[:, None]] = 0.0
    s = w.sum(axis=1, keepdims=True)
    return np.where(s > 0, w / np.where(s > 0, s, 1.0), 0.0)


def select_cameras(centers: np.ndarray, footprint_radius: float, eye_pos: np.ndarray, cameras):
    """Per voxel: candidate cameras by increasing phi among those whose image holds the
    footprint, and the blend weights of the first K_BLEND (docs/methods.md §1.3).

    Returns:
        idx: (N, K_CAND) int64 camera indices in increasing phi, -1 past the valid ones.
        weights: (N, K_BLEND) float64 ULR weights (sum 1 where any camera is valid).
    """
    p = np.asarray(centers, dtype=np.float64).reshape(-1, 3)
    C = len(cameras)
    if C == 0 or len(p) == 0:
        return np.full((len(p), K_CAND), -1, np.int64), np.zeros((len(p), K_BLEND))
    phi = camera_angles(p, eye_pos, cameras)
    ok = footprint_inside(p, footprint_radius, cameras)
    phi_m = np.where(ok, phi, np.inf)
    order = np.argsort(phi_m, axis=1, kind="stable")
    ncol = min(C, K_CAND + 1)
    order = order[:, :ncol]
    ps = np.take_along_axis(phi_m, order, axis=1)
    n_valid = np.isfinite(ps).sum(axis=1)
    if ncol < K_BLEND + 1:
        ps = np.concatenate([ps, np.full((len(p), K_BLEND + 1 - ncol), np.inf)], axis=1)
    weights = ulr_weights(ps, n_valid)
    idx = np.full((len(p), K_CAND), -1, np.int64)
    m = min(ncol, K_CAND)
    idx[:, :m] = np.where(np.isfinite(ps[:, :m]), order[:, :m], -1)
    return idx, weights


# ------------------------------------------------------------------ Eq. 2 (§1.4)
def eq2_pass(d: np.ndarray, D: np.ndarray, spacing: float) -> np.ndarray:
    """RGBz clip (Eq. 2): keep where the camera saw geometry (d > 0) and |d - D| < l / 2."""
    d = np.asarray(d)
    return (d > 0) & (np.abs(d - np.asarray(D)) < 0.5 * spacing)


#: classify() outcomes: the camera does not see the point (outside, behind, occluded) ...
NO_VIEW = 0
#: ... Eq. 2 passes ...
PASS = 1
#: ... or the camera saw through the point (d == 0 or d >= D + l/2): free space.
FREE = 2
#: Between l/2 and FREE_FACTOR * l/2 from the surface (either side) a camera is UNSURE: it
#: neither passes nor frees the point, but its weight counts against drawing it.  Beyond that
#: in front of the point (d <= D - FREE_FACTOR l/2) the camera is occluded (NO_VIEW, no vote);
#: behind it (d >= D + FREE_FACTOR l/2, or d == 0) the camera saw through it (FREE).
FREE_FACTOR = 2.0
#: classify() outcome: within (l/2, FREE_FACTOR l/2) of the camera's surface.
UNSURE = 3
#: An UNSURE camera's weight counts this much against drawing (a FREE camera counts 1).
UNSURE_WEIGHT = 0.5
#: Parallax correction of passing fragments' colours: fixed-point steps along the eye ray to
#: the camera's depth map (0 = the paper's colour at the slice point).
DEPTH_REFINE = 2
#: ... the corrected point must stay within REFINE_RANGE * l/2 (camera depth) of the slice point ...
REFINE_RANGE = 2.0
#: ... and lie on the camera's surface within REFINE_ACCEPT * l/2, else the slice point's colour is kept.
REFINE_ACCEPT = 1.0
#: Fallback rules: "vote" (default) and "any" (see shade_fragments).
FALLBACK_RULES = ("vote", "any")
#: Debug outputs of the fragment shader (RenderOptions.debug), index = its DEBUG_VIEW define
#: (0 = the colour): the dominant camera index + 1 per drawn pixel, or DEBUG_KEPT / DEBUG_REJECTED
#: per pixel (a fragment Eq. 2 / the vote rejects is drawn at DEBUG_BACK_DEPTH, behind all kept ones).
DEBUG_OUTPUTS = (None, "camera", "rejections")
DEBUG_KEPT, DEBUG_REJECTED = 1, 2
#: Window depth of rejected fragments in the rejections view (just in front of the cleared 1.0).
DEBUG_BACK_DEPTH = 0.999999
#: "vote" rule: a fragment is drawn when the passing share of the seeing blend weight >= this.
ALPHA_VOTE = 0.5


def sample_rgbz(cam: Camera, rgb: np.ndarray, depth: np.ndarray, points: np.ndarray):
    """Nearest-texel RGBz lookup of world points in one camera.

    Returns (colour (N, C) of ``rgb`` (H, W, C): 3 colours, or 4 = premultiplied colour + alpha
    with a matte (render.microfacet.rgbz_textures.twin_colours), d (N,) stored depth, D (N,) the
    points' own z-depth, inside (N,) bool: in front of the camera and inside the image).
    """
    uv, D = cam.project(points)
    with np.errstate(invalid="ignore"):
        ix, iy = nearest_pixel(uv[:, 0]), nearest_pixel(uv[:, 1])
        inside = (D > 0) & (ix >= 0) & (ix < cam.width) & (iy >= 0) & (iy < cam.height)
    ixi = np.where(inside, ix, 0)
    iyi = np.where(inside, iy, 0)
    d = np.where(inside, depth[iyi, ixi], 0.0)
    col = np.where(inside[:, None], rgb[iyi, ixi], 0.0)
    return col, d, D, inside


def classify(d: np.ndarray, D: np.ndarray, inside: np.ndarray, spacing: float) -> np.ndarray:
    """NO_VIEW / PASS / FREE / UNSURE per point: Eq. 2 with tolerance l/2 is PASS; FREE when the
    camera saw nothing there or a surface at least FREE_FACTOR * l/2 behind the point;
    NO_VIEW when outside / behind / occluded by at least FREE_FACTOR * l/2; else UNSURE."""
    tol = 0.5 * spacing
    e = d - D
    far = np.where(e > 0, FREE, NO_VIEW)
    out = np.where(d > 0, np.where(np.abs(e) < tol, PASS, np.where(np.abs(e) < FREE_FACTOR * tol, UNSURE, far)), FREE)
    return np.where(inside, out, NO_VIEW)


def project_h(cam: Camera, points: np.ndarray) -> np.ndarray:
    """(N, 3) homogeneous projection (u z, v z, z) of world points (the shader's cam_project_h)."""
    pc = cam.world_to_cam(np.asarray(points, np.float64).reshape(-1, 3))
    return pc @ cam.K.T


def refine_colours(cam: Camera, rgb: np.ndarray, depth: np.ndarray, points: np.ndarray, eye_pos: np.ndarray,
                   d0: np.ndarray, tol: float, col: np.ndarray, iterations: int = None) -> np.ndarray:
    """Parallax-corrected colours of passing fragments (the shader's refine_colour).

    The eye ray through each fragment, projected into the camera, is pe + s (pr - pe) (pr, pe:
    homogeneous projections of the fragment and of the eye).  Starting from the depth d0 seen
    at the fragment's texel, each step moves to the ray point whose camera depth equals the
    depth seen so far (s = (d - pe_z) / dir_z) and reads the texel there.  A step that leaves
    REFINE_RANGE * tol of the fragment's own depth, the image, or the measured pixels keeps the
    original colour; after ``iterations`` steps the new texel's colour is used when its depth
    agrees with the ray point within REFINE_ACCEPT * tol.
    """
    iterations = DEPTH_REFINE if iterations is None else int(iterations)
    col = np.array(col, np.float64, copy=True)
    if iterations <= 0 or len(points) == 0:
        return col
    pr = project_h(cam, points)
    pe = project_h(cam, np.asarray(eye_pos, np.float64)[None])[0]
    dirv = pr - pe
    ok = np.abs(dirv[:, 2]) > 1e-12
    d = np.asarray(d0, np.float64).copy()
    q = pr.copy()
    tcol = np.zeros_like(col)
    H, W = depth.shape
    for _ in range(iterations):
        with np.errstate(divide="ignore", invalid="ignore"):
            s_ = (d - pe[2]) / np.where(ok, dirv[:, 2], 1.0)
            q2 = pe + s_[:, None] * dirv
            ok &= (q2[:, 2] > 0) & (np.abs(q2[:, 2] - pr[:, 2]) <= REFINE_RANGE * tol)
            zz = np.where(ok, q2[:, 2], 1.0)
            ix, iy = nearest_pixel(q2[:, 0] / zz), nearest_pixel(q2[:, 1] / zz)
        ok &= (ix >= 0) & (iy >= 0) & (ix < W) & (iy < H)
        ixi = np.where(ok, ix, 0)
        iyi = np.where(ok, iy, 0)
        dn = depth[iyi, ixi]
        ok &= dn > 0
        tcol = np.where(ok[:, None], rgb[iyi, ixi], tcol)
        q = np.where(ok[:, None], q2, q)
        d = np.where(ok, dn, d)
    ok &= np.abs(d - q[:, 2]) < REFINE_ACCEPT * tol
    return np.where(ok[:, None], tcol, col)


def shade_fragments(points: np.ndarray, cand: np.ndarray, weights: np.ndarray, spacing: float,
                    cameras, rgb: np.ndarray, depth: np.ndarray, rule: str = "vote",
                    n_fallback: int = None, eye_pos: np.ndarray | None = None, refine: int | None = None,
                    with_source: bool = False):
    """Colour of slice fragments (the fragment shader's twin, microfacet_rgbz.glsl).

    "vote": the blend cameras that see the point (PASS, FREE or UNSURE) vote with their
    weights; the fragment is drawn when the passing share >= ALPHA_VOTE, coloured by the
    weighted mean of the passing cameras.  If no blend camera sees it, the first of the
    remaining candidates (phi order, after the K_BLEND blend cameras) that passes or frees it
    decides: the per-fragment fallback.
    "any": blend the passing blend cameras; if none passes, the first passing remaining candidate.
    With ``eye_pos`` given, passing colours are parallax-corrected (:func:`refine_colours`,
    ``refine`` steps, default DEPTH_REFINE).
    ``rgb`` (N_cams, H, W, C): C = 4 carries premultiplied colour + alpha through the same rules.
    Returns (colour (N, C), alive (N,) bool); dead fragments are discarded.  With ``with_source``
    also (N,) the dominant camera of each alive fragment: the passing blend camera of largest
    weight (first of equals), or the fallback candidate that decided; -1 for dead ones.
    """
    if rule not in FALLBACK_RULES:
        raise ValueError(f"unknown fallback rule {rule!r}; use one of {FALLBACK_RULES}")
    N = len(points)
    status = np.zeros((N, K_CAND), np.int64)
    cols = np.zeros((N, K_CAND, np.shape(rgb)[-1]))
    for k in range(K_CAND):
        ci = cand[:, k]
        for c in np.unique(ci[ci >= 0]):
            m = ci == c
            col, d, D, inside = sample_rgbz(cameras[c], rgb[c], depth[c], points[m])
            st = classify(d, D, inside, spacing)
            if eye_pos is not None and (DEPTH_REFINE if refine is None else refine) > 0 and np.any(st == PASS):
                ps = st == PASS
                col[ps] = refine_colours(cameras[c], rgb[c], depth[c], points[m][ps], eye_pos, d[ps], 0.5 * spacing,
                                         col[ps], refine)
            status[m, k] = st
            cols[m, k] = col
    wb = np.where(cand[:, :K_BLEND] >= 0, weights, 0.0)
    passing = status[:, :K_BLEND] == PASS
    wpass = (wb * passing).sum(1)
    acc = ((wb * passing)[:, :, None] * cols[:, :K_BLEND]).sum(1)
    st_b = status[:, :K_BLEND]
    seen = (wb * (((st_b == PASS) | (st_b == FREE)) + UNSURE_WEIGHT * (st_b == UNSURE))).sum(1)
    blend_col = acc / np.where(wpass > 0, wpass, 1.0)[:, None]
    valid = cand >= 0
    n_fallback = N_FALLBACK if n_fallback is None else n_fallback
    valid[:, :K_BLEND] = False  # the fallback tries the n_fallback candidates after the blend cameras
    valid[:, K_BLEND + n_fallback:] = False
    if rule == "vote":
        use_blend = seen > WEIGHT_EPS
        alive_b = (wpass >= ALPHA_VOTE * seen) & (wpass > WEIGHT_EPS)
        sees = valid & ((status == PASS) | (status == FREE))
        has = sees.any(1)
        first = np.argmax(sees, axis=1)
        fstat = status[np.arange(N), first]
        fcol = cols[np.arange(N), first]
        alive = np.where(use_blend, alive_b, has & (fstat == PASS))
        out = np.where(use_blend[:, None], blend_col, fcol)
        fsrc = cand[np.arange(N), first]
    else:
        use_blend = wpass > WEIGHT_EPS
        ok = valid & (status == PASS)
        has = ok.any(1)
        first = np.argmax(ok, axis=1)
        fcol = cols[np.arange(N), first]
        alive = use_blend | has
        out = np.where(use_blend[:, None], blend_col, fcol)
        fsrc = cand[np.arange(N), first]
    colour = np.where(alive[:, None], out, 0.0)
    if not with_source:
        return colour, alive
    bsrc = cand[np.arange(N), np.argmax(wb * passing, axis=1)]
    return colour, alive, np.where(alive, np.where(use_blend, bsrc, fsrc), -1)


def debug_codes(alive: np.ndarray, source: np.ndarray, debug: str) -> np.ndarray:
    """(N,) codes the fragment shader writes for the ``debug`` output (DEBUG_OUTPUTS) of fragments
    shaded by :func:`shade_fragments` (``with_source``): camera index + 1 (0 = discarded), or
    DEBUG_KEPT / DEBUG_REJECTED."""
    if debug == "camera":
        return np.where(alive, source + 1, 0)
    if debug == "rejections":
        return np.where(alive, DEBUG_KEPT, DEBUG_REJECTED)
    raise ValueError(f"unknown debug output {debug!r}; use one of {DEBUG_OUTPUTS[1:]}")


# ------------------------------------------------------------------ whole frame


def slice_half_extents(centers: np.ndarray, w: float, eye_pos: np.ndarray, v: np.ndarray, a: np.ndarray,
                       b: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Half sizes (along a, b) of the slice quads at distance s of voxels at ``centers``.

    TIGHT_RECT: the largest |(X' - q) . a|, |(X' - q) . b| over the 8 cube corners X, with X' the
    corner's central projection from the eye onto the slice plane and q the quad's centre;
    clamped to RECT_CLAMP * sqrt(3) w / 2 (also used when a corner is not in front of the eye).
    Else the paper's sqrt(3) w / 2 for both.
    """
    c = np.asarray(centers, np.float64).reshape(-1, 3)
    s = np.asarray(s, np.float64).reshape(-1)
    half = 0.5 * SLICE_SIDE_FACTOR * w
    if not TIGHT_RECT:
        return np.full(len(c), half), np.full(len(c), half)
    offs = 0.5 * w * np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], np.float64)
    X = c[:, None, :] + offs[None] - eye_pos  # corners relative to the eye
    depth = (X * v[:, None, :]).sum(-1)
    ok = depth > 1e-9
    Xp = X * (s[:, None] / np.where(ok, depth, 1.0))[:, :, None] - (s[:, None] * v)[:, None, :]
    ha = np.abs((Xp * a[:, None, :]).sum(-1)).max(1)
    hb = np.abs((Xp * b[:, None, :]).sum(-1)).max(1)
    lim = RECT_CLAMP * half
    bad = ~ok.all(1)
    ha = np.where(bad, lim, np.minimum(ha, lim))
    hb = np.where(bad, lim, np.minimum(hb, lim))
    return ha, hb

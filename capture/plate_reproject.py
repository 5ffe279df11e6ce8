"""A moving camera's background plate: what the other views saw behind the object (issue 30).

For a pixel p of view i near the object, the background behind it is a point X on p's ray beyond
the object.  Its colour is looked up in the other views that saw X beside the object:

* **hypotheses for X** (:func:`background_points`), tried in order: the support plane under the
  object (``capture.extent``: the ray's hit, when it lies in front of the camera), then the room
  at the depth the view measured around the object (inverse depth filled inwards by a push-pull
  pyramid, so a wall or a slanted floor continues under the object), else a point at infinity in
  p's direction (an environment far away: the background depends on the direction only, and the
  views' pixels together form a panorama of it).
* **a sample from view j** (:func:`gather_samples`) counts when X projects inside j's image onto
  pixels that are all confidently background there (outside j's object depth and its band: all
  four bilinear taps), and j's measured depth there agrees with X (the plane or room really is
  there and is not hidden; for X at infinity, j measured nothing or something beyond the
  object's region).  Its colour is j's, bilinear in linear light, times g_j / g_i (the views'
  exposure gains, ``capture.plate``).  A sample blown out in j (a tap at capture.matting_known.CLIP_LEVEL
  in a channel) is only a lower bound of the background; brought into a view of a darker exposure
  (g_j / g_i below 1 in a channel) it would read as an unclipped, too dark colour, so there it does not
  count (CLIPPED_SOURCES_DROPPED; at equal or brighter exposure it stays blown out, as before).
* **the plate** is the per-channel median of the samples of the first hypothesis that has any
  (:func:`reproject_plate`); a pixel without samples stays unknown (``known`` False).

The samples of one source view are gathered by one compiled loop (``capture.plate_reproject_kernel``,
switch GATHER_COMPILED; :func:`gather_samples`' numpy is the reference, the same samples bit for bit here).
Each pixel's median and count over the sources are one compiled pass too (MEDIAN_COMPILED; numpy's
:func:`nan_median` the reference, the same values).

The views' pixels are looked up directly, not through a resampled panorama grid: one resampling,
not two, and a point at infinity is just the direction of the project's one camera model.

As a path of ``capture.plate`` (``capture.plate.path_functions``): :func:`panorama_start`,
:func:`panorama_predict` and :func:`panorama_draw` on a ``capture.plate.PlateSet``, each view
consulting its ``neighbours`` nearest views by optical axis (:func:`neighbour_order`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from capture.camera import Camera
from capture.matting_known import CLIP_LEVEL
from capture.sampling import linear_taps, sample_image

if TYPE_CHECKING:
    from capture.plate import PlateSet

#: A point "at infinity": this many metres along the ray (float64 keeps 1e-6 px of parallax).
FAR_METRES = 1e6
#: Depth agreement: |measured - expected| within this fraction of the expected z-depth (a D435's
#: z-squared noise is 0.4 % at 1 m; plus the plane's fit).
DEPTH_TOL = 0.03
#: For a point at infinity, j's measurement must lie beyond this multiple of its distance to the
#: focus centre + radius (else j sees something nearer: the table, clutter).
FAR_MARGIN = 1.0
#: gather_samples by one compiled loop (capture.plate_reproject_kernel; the same samples), else numpy.
GATHER_COMPILED = True
#: A source's blown-out sample does not count for a view of a darker exposure (module docstring; True), else
#: it counts as any sample (the rule before: on the path-traced orbit with auto exposure a dark view's plate
#: was drawn from its brighter neighbours' clipped sunlit floor, error 0.47 against 0.001 elsewhere).
CLIPPED_SOURCES_DROPPED = True
#: reproject_plate's median and sample count of each pixel by one compiled pass (capture.plate_reproject_kernel.
#: median_count; the same values), else numpy's sort of every source's samples (nan_median, the reference).
MEDIAN_COMPILED = True
#: The room hypothesis needs at least this fraction of the view's background ring with depth off the plane.
ROOM_MIN_FRACTION = 0.3


#: A background depth point higher than this above the support plane is the room, not the support (metres).
PLANE_OFF_METRES = 0.02


@dataclass(frozen=True)
class PlateSource:
    """What view j lends to the others' plates.

    Attributes:
        camera: its camera.
        linear: (H, W, 3) float32 linear colour.
        background: (H, W) bool, confidently background (outside its object depth and band).
        depth: (H, W) float32 z-depth of its background (the capture's depth where it is not the
            object: support, walls; 0 = none).
        gain: (3,) float64 its exposure gain g (true colour = colour x g).
        focus_far: z-depth beyond which its measurement counts as far (metres).
    """

    camera: Camera
    linear: np.ndarray
    background: np.ndarray
    depth: np.ndarray
    gain: np.ndarray
    focus_far: float


def gather_samples(points: np.ndarray, kind: str, src: PlateSource, gain_i: np.ndarray,
                   fast: bool | None = None, out: np.ndarray | None = None) -> np.ndarray:
    """(N, 3) colours view ``src`` saw at world ``points`` (N, 3) in the exposure of the view whose
    gain is ``gain_i``, NaN where the sample does not count (module docstring).  ``kind``:
    'plane', 'room' or 'far' (what the points are).  ``fast`` (default GATHER_COMPILED): one compiled
    loop (capture.plate_reproject_kernel), else the numpy reference below.  ``out``: (N, 3) float32,
    all NaN, C-contiguous, to write into (returned)."""
    if GATHER_COMPILED if fast is None else fast:
        return _gather_compiled(points, kind, src, gain_i, out)
    if out is not None:
        out[...] = gather_samples(points, kind, src, gain_i, False)
        return out
    H, W = src.background.shape
    out = np.full((len(points), 3), np.nan, np.float32)
    uv, z = src.camera.project(points)
    ok = np.isfinite(uv).all(axis=1) & (z > 0)
    uv = np.where(ok[:, None], uv, -2.0)
    blown = np.asarray(src.linear).max(axis=-1).astype(np.float64) >= CLIP_LEVEL if drops_clipped(src, gain_i) else None
    for idx, inside, _ in linear_taps(uv[:, ::-1], (H, W), "zero"):  # all four taps inside and background
        ok &= src.background[idx] & (True if inside is None else inside)
        if blown is not None:
            ok &= ~blown[idx]
    d = sample_image(src.depth, uv[:, 0], uv[:, 1], "nearest")
    if kind == "far":
        ok &= (d <= 0) | (d > FAR_MARGIN * src.focus_far)
    elif kind == "plane":
        ok &= (d > 0) & (np.abs(d - z) <= DEPTH_TOL * z)
    else:
        ok &= (d <= 0) | (np.abs(d - z) <= DEPTH_TOL * z)
    if ok.any():
        k = np.flatnonzero(ok)
        out[k] = sample_image(src.linear, uv[k, 0], uv[k, 1], "linear") * (src.gain / gain_i)
    return out


def drops_clipped(src: PlateSource, gain_i: np.ndarray) -> bool:
    """Whether ``src``'s blown-out samples do not count for the view of gain ``gain_i`` (module docstring)."""
    return CLIPPED_SOURCES_DROPPED and bool(np.any(np.asarray(src.gain, np.float64) / gain_i < 1.0))


def _gather_compiled(points: np.ndarray, kind: str, src: PlateSource, gain_i: np.ndarray,
                     out: np.ndarray | None = None) -> np.ndarray:
    """gather_samples by capture.plate_reproject_kernel.gather_kernel (the same samples)."""
    from capture.plate_reproject_kernel import F16_TABLE, KINDS, gather_kernel

    out = np.full((len(points), 3), np.nan, np.float32) if out is None else out
    cw = src.camera.cam_from_world
    img = src.linear  # the views' own arrays, not copies (a half-float view is read through its bits)
    half = img.dtype == np.float16
    img = np.ascontiguousarray(img).view(np.uint16) if half else np.ascontiguousarray(img)
    gather_kernel(np.ascontiguousarray(points, np.float64), KINDS[kind], np.ascontiguousarray(cw[:3, :3]),
                  np.ascontiguousarray(cw[:3, 3]), np.ascontiguousarray(src.camera.K, np.float64),
                  np.ascontiguousarray(src.background, bool), np.ascontiguousarray(src.depth, np.float32),
                  img, F16_TABLE, np.asarray(src.gain / gain_i, np.float64),
                  np.float32(FAR_MARGIN * src.focus_far), float(DEPTH_TOL),
                  float(CLIP_LEVEL) if drops_clipped(src, gain_i) else np.inf, out)
    return out


def off_plane(cam, depth: np.ndarray, plane: np.ndarray | None, fast: bool = True) -> np.ndarray:
    """(H, W) bool: the ``depth`` pixels off the support ``plane`` (more than PLANE_OFF_METRES above
    it; every depth pixel without a plane).  ``fast``: capture.extent_kernel.above_plane (one
    compiled loop), else the numpy back-projection (the same pixels: tests/capture/test_plate.py)."""
    if plane is None:
        return np.isfinite(depth) & (depth > 0)
    if fast:
        from capture.extent_kernel import above_plane

        return above_plane(depth, cam, plane, PLANE_OFF_METRES)
    pts, m = cam.depth_to_points(depth)
    off = np.zeros(depth.shape, bool)
    if len(pts):
        off[m] = (pts @ plane[:3] + plane[3]) > PLANE_OFF_METRES
    return off


def room_depth(depth: np.ndarray, ring: np.ndarray, off_plane: np.ndarray) -> np.ndarray | None:
    """(H, W) z-depth of the room filled in under the object (inverse depth, push-pull from the
    measured depth ``depth`` of the ``ring`` pixels that are ``off_plane``), or None when under
    ROOM_MIN_FRACTION of the ring has such depth."""
    from capture.fill import push_pull
    from capture.plate_fast import room_counts  # the test counted before any mask is made (the same)

    if (counts := room_counts(ring, off_plane, depth)) is not None and \
            (not counts[0] or counts[1] < ROOM_MIN_FRACTION * counts[0]):
        return None
    have = ring & off_plane & (depth > 0)
    if not ring.any() or have.sum() < ROOM_MIN_FRACTION * ring.sum():
        return None
    inv = np.where(have, 1.0 / np.maximum(depth, 1e-6), 0.0)
    filled = push_pull(inv[..., None], have.astype(np.float64))[..., 0]
    return np.where(filled > 0, 1.0 / np.maximum(filled, 1e-9), 0.0)


def background_points(cam: Camera, pix: np.ndarray, plane: np.ndarray | None,
                      room: np.ndarray | None) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """Hypotheses for the background behind pixels ``pix`` (N, 2) (x, y ints) of ``cam``, in the
    order tried: [(kind, points (N, 3), valid (N,) bool)] (module docstring)."""
    rays_c = cam.pixel_rays(pix.astype(np.float64))
    R = cam.world_from_cam[:3, :3]
    rays = rays_c @ R.T  # world direction per unit z-depth
    o = cam.center
    hyps = []
    if plane is not None:
        den = rays @ plane[:3]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = -(o @ plane[:3] + plane[3]) / den
        valid = np.isfinite(t) & (t > 0)
        hyps.append(("plane", o + rays * np.where(valid, t, 1.0)[:, None], valid))
    if room is not None:
        z = room[pix[:, 1], pix[:, 0]]
        hyps.append(("room", o + rays * np.where(z > 0, z, 1.0)[:, None], z > 0))
    unit = rays / np.linalg.norm(rays, axis=1, keepdims=True)
    hyps.append(("far", o + unit * FAR_METRES, np.ones(len(pix), bool)))
    return hyps


def nan_median(s: np.ndarray) -> np.ndarray:
    """(N, C) per-column median over axis 0 of (K, N, C) samples, NaN = none: np.nanmedian's values
    without its per-column Python loop (samples sorted, NaNs last); a column without any sample
    gives a meaningless value (the caller masks it)."""
    srt = np.sort(s, axis=0)
    n = np.maximum(np.isfinite(s).sum(axis=0), 1)  # (N, C)
    lo = np.take_along_axis(srt, ((n - 1) // 2)[None], axis=0)[0]
    hi = np.take_along_axis(srt, (n // 2)[None], axis=0)[0]
    return 0.5 * (lo + hi)


def reproject_plate(cam: Camera, pix: np.ndarray, gain_i: np.ndarray, sources: list[PlateSource],
                    plane: np.ndarray | None, room: np.ndarray | None,
                    fast: bool | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(colour (N, 3) float32 linear in view i's exposure, known (N,) bool, samples (N,) int) of the
    background behind pixels ``pix`` (N, 2) of camera ``cam`` from the ``sources`` (the other
    views; module docstring): the median of :func:`first_samples`.  ``fast``: gather_samples'."""
    med, count = _median_count(first_samples(cam, pix, gain_i, sources, plane, room, fast))
    known = count > 0
    med[~known] = 0.0
    return med, known, count


def first_samples(cam: Camera, pix: np.ndarray, gain_i: np.ndarray, sources: list[PlateSource],
                  plane: np.ndarray | None, room: np.ndarray | None, fast: bool | None = None,
                  kinds: np.ndarray | None = None) -> np.ndarray:
    """(K, N, 3) float32 samples (NaN = none) of the background behind pixels ``pix`` (N, 2) of ``cam`` from
    each of the K ``sources``, in the exposure of gain ``gain_i``: per pixel those of the first hypothesis
    (:func:`background_points`, in its order) that any source has a sample of (module docstring).  What the
    plate's median takes (:func:`reproject_plate`) and the exposure's pairs compare (capture.plate_pairs).  ``kinds``:
    (N,) int, -1, gets each pixel's hypothesis (its index in background_points' list; capture.vignetting)."""
    n = len(pix)
    s = np.full((len(sources), n, 3), np.nan, np.float32)
    done = np.zeros(n, bool)
    for h, (kind, pts, valid) in enumerate(background_points(cam, pix, plane, room)):
        todo = np.flatnonzero(valid & ~done)
        if not len(todo) or not sources:
            continue
        whole = len(todo) == n  # every pixel still open: the samples go straight into s
        got = s if whole else np.full((len(sources), len(todo), 3), np.nan, np.float32)
        at = np.ascontiguousarray(pts[todo])
        for k, src in enumerate(sources):
            gather_samples(at, kind, src, gain_i, fast, got[k])
        seen = np.isfinite(got[..., 0]).any(axis=0)
        if not whole:
            s[:, todo[seen]] = got[:, seen]
        done[todo[seen]] = True
        if kinds is not None:
            kinds[todo[seen]] = h
    return s


def _median_count(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(median (N, 3) float32 of each pixel's finite samples, meaningless where none; count (N,) int64 of
    the sources with a sample) of the samples ``s`` (K, N, 3) float32, NaN = none: MEDIAN_COMPILED's
    kernel, else numpy (:func:`nan_median`; the same values)."""
    if MEDIAN_COMPILED:
        from capture.plate_reproject_kernel import median_count

        med, cnt = np.empty(s.shape[1:], np.float32), np.empty(s.shape[1], np.int64)
        median_count(np.ascontiguousarray(s, np.float32), med, cnt)
        return med, cnt
    have = np.isfinite(s[..., 0])
    return nan_median(s), have.sum(axis=0)


def neighbour_order(cams: list[Camera], i: int, k: int, skip=()) -> list[int]:
    """Indices of the ``k`` cameras other than ``i`` (and those in ``skip``) nearest to it by optical axis."""
    f = np.array([c.forward for c in cams])
    ang = np.arccos(np.clip(f @ f[i], -1, 1))
    ang[[i, *skip]] = np.inf
    return [int(j) for j in np.argsort(ang)[:k] if np.isfinite(ang[j])]


def panorama_sources(ps: PlateSet, gains: np.ndarray) -> list[PlateSource]:
    """What every view lends to the others' plates, with its exposure gain."""
    center, radius = ps.focus
    return [PlateSource(p.view.camera, p.view.linear, p.source, p.background_depth, gains[j],
                        float(p.view.camera.world_to_cam(center)[2] + radius)) for j, p in enumerate(ps.views)]


def panorama_prediction(ps: PlateSet, i: int, pix: np.ndarray, sources: list[PlateSource]) -> np.ndarray:
    """(N, 3) colour behind pixels ``pix`` (N, 2) of view i in its exposure from its
    ``ps.neighbours`` nearest other views (NaN where unknown)."""
    nb = [sources[j] for j in neighbour_order(ps.cameras, i, ps.neighbours, sorted(ps.dropped))]
    col, known, _ = reproject_plate(ps.views[i].view.camera, pix, sources[i].gain, nb, ps.plane, ps.views[i].room)
    col = col.astype(np.float32)
    col[~known] = np.nan
    return col


def panorama_start(ps: PlateSet) -> np.ndarray:
    """The moving camera's first gains: 1 (the rings say more than any common pixel)."""
    return np.ones((len(ps.views), 3))


def panorama_predict(ps: PlateSet, gains: np.ndarray) -> list[np.ndarray]:
    """Per view its ring (N_i, 3) predicted from the other views, in its own exposure."""
    from capture.plate_threads import thread_map  # views side by side (the same predictions)

    src = panorama_sources(ps, gains)
    return list(thread_map(lambda i: panorama_prediction(ps, i, ps.views[i].ring, src), range(len(ps.views))))


def panorama_draw(ps: PlateSet, gains: np.ndarray):
    """Per view, one at a time (a generator), (colour (H, W, 3) float32 in its exposure, known (H, W))
    on its need mask; drawn side by side (capture.plate_threads), a few views ahead at most."""
    from capture.plate_threads import thread_map

    src = panorama_sources(ps, gains)

    def one(i):
        p = ps.views[i]
        y, x = np.nonzero(p.need)
        col = panorama_prediction(ps, i, np.stack([x, y], axis=1), src)
        ok = np.isfinite(col[:, 0])
        img = np.zeros(p.view.linear.shape, np.float32)
        known = np.zeros(p.need.shape, bool)
        img[y[ok], x[ok]] = col[ok]
        known[y[ok], x[ok]] = True
        return img, known

    return thread_map(one, range(len(ps.views)))

"""Depth maps stored the wrong way round, or as distances along the rays: part of the depth-agreement check
(volume/agreement.py, capture/depth_agreement.py).

Two mistakes of a depth exporter pass every other check and cost a model several dB without a word:

* **A depth map stored upside down** (bottom row first, as an OpenGL read-back gives it), mirrored left to
  right (a front camera's colour mirrored and its depth not), or turned 180 degrees.  The path-traced conifer
  (room, table, auto exposure, lens) with every depth map upside down still "agreed" with its poses (8.5 % of
  the points against 22.8 %, above the 5 % floor), its given mattes still covered the depth, and its held-out
  views fell 26.41 -> 19.31 dB (docs/capture_formats.md).
* **Depth along the ray** (the distance from the camera's centre, what a ray tracer's hit distance or a
  "range" image holds) where transforms.json's depth is z-depth (along the optical axis): every pixel's depth
  1 / cos(its angle from the axis) too far, 3-9 % at the edges of a phone's field of view.  The same conifer
  22.8 % -> 21.1 %, "agree", held out 26.41 -> 23.46 dB.

The check.  Each view's sampled points (capture.depth_agreement.view_sample: measured pixels back-projected
with their depth) are read again as each of :data:`READINGS` says the depth was meant: flipped, the sample's
pixel p goes to its mirror p' and its point to ray(p') z; as range, the point to ray(p) z / |ray(p)| (a ray
of z = 1).  They are projected into the neighbour views as capture.depth_agreement.pair_hits does, and each
neighbour's depth is read the same way at the pixel a point lands on (its mirror's sample; the range over
|ray|).  For every reading, the points that agree only read that way (b) and those that agree only as stored
(c) give McNemar's z = (b - c) / sqrt(b + c); the reading with the largest z is named where z >= :data:`READING_Z`.
Measured (docs/capture_formats.md): right captures -11.5 to -59 for every reading (the synthetic fur ball, the
path-traced conifer and fur with a table, auto exposure and a lens); the copies with their depth upside down
+16.8 to +48, mirrored +24.9, as range +9.9 to +18.8.

A flip is named only where the colour's edges sit at the flipped depth's at least as well as at the stored one's
(:func:`flip_sums`, :data:`FLIP_COLOUR_GAIN`): where they do not, flipping the depth alone would part it from its
colour (the depth files of the next frame on a ring of three spheres agreed better upside down, z 56, and the colour
said 0.65).  ``--depth-agreement fix`` reads every depth map as named (:func:`read_depth`).
"""

from __future__ import annotations

import numpy as np

from capture.camera import mirror_pixels
from capture.depth_agreement import depth_at

#: The readings tried: name -> (rows reversed, columns reversed, the depth along the ray).
READINGS = {
    "upside down": (True, False, False),
    "left to right": (False, True, False),
    "turned 180 degrees": (True, True, False),
    "range": (False, False, True),
}
#: A reading is named where the points agreeing only read that way outnumber those agreeing only as stored by
#: this many standard deviations (McNemar's z): right captures -11.5 to -59, the broken copies +9.9 to +48.
READING_Z = 5.0
#: Each reading is held at its own best depth scale within this factor either way of the capture's (ratio
#: SCALE_STEP): a range image reads about 1-3 % deep over an object, and the first scale search takes that up.
SCALE_SPAN = 1.05
SCALE_STEP = 1.005
#: A flip is named only where the colour's edges score at the flipped depth's edges at least this many
#: times their score at the stored depth's (capture.depth_registration's measure, each at its best shift): the
#: copies with their depth flipped 1.01 (a fur ball, nearly symmetric) to 1.29; a ring of three spheres given the
#: next frame's depth files, which agree better upside down with the poses, 0.65.
FLIP_COLOUR_GAIN = 0.9
#: What each reading asks in the warning.
READING_HINTS = {
    "upside down": "stored upside down (bottom row first, as an OpenGL read-back gives them)",
    "left to right": "mirrored left to right (a front camera's colour mirrored and its depth not?)",
    "turned 180 degrees": "turned 180 degrees",
    "range": "distances along each pixel's ray from the camera's centre (a ray tracer's hit distance, a range "
             "image), not z-depth along the optical axis as transforms.json's depth is",
}


def read_points(points: np.ndarray, camera, shape: tuple[int, int], reading: str) -> np.ndarray:
    """(m, 3) a view's sampled camera-frame ``points`` (capture.depth_agreement.view_sample of a (H, W) = ``shape``
    depth map) as ``reading`` (a key of :data:`READINGS`) says the depth was meant."""
    pts = np.asarray(points, np.float64)
    if not len(pts):
        return pts
    rows, cols, along = READINGS[reading]
    z = pts[:, 2:3]
    if along:
        return pts * (z / np.linalg.norm(pts, axis=1, keepdims=True))
    K = camera.K
    uv = (pts / z) @ K[:2].T
    return camera.pixel_rays(mirror_pixels(uv, shape, rows, cols)) * z


def reading_hits(points: np.ndarray, cam_i, cam_j, sample_j, shape_j: tuple[int, int], s: np.ndarray, rel: float,
                 reading: str | None) -> np.ndarray:
    """(S, m) whether each of view i's camera-frame ``points`` (already read as ``reading``) agrees with view j's
    depth read as ``reading`` (None: as stored; then capture.depth_agreement.pair_hits' answer), every depth
    times each of ``s`` (S,).  ``sample_j``: view j's (points, depth map every ``step`` pixels, step) of a
    (H, W) = ``shape_j`` map."""
    _, small, step = sample_j
    s = np.asarray(s, np.float64)
    Ti = cam_i.world_from_cam
    world = s[:, None, None] * (np.asarray(points, np.float64) @ Ti[:3, :3].T)[None] + Ti[:3, 3]
    uv, z = cam_j.project(world)
    rows, cols, along = (False, False, False) if reading is None else READINGS[reading]
    zj, inside = depth_at(mirror_pixels(uv, shape_j, rows, cols), z, small, step)
    if along:
        zj[inside] /= np.linalg.norm(cam_j.pixel_rays(uv[inside]), axis=-1)
    zj *= s[:, None]
    return (zj > 0) & (np.abs(z - zj) <= rel * zj)


def reading_scales(scale: float) -> np.ndarray:
    """(S,) the depth scales each reading is held at: ``scale`` times :data:`SCALE_STEP` ** k within
    :data:`SCALE_SPAN` (a range image is on average 1-3 % deeper than its z-depth over an object, and the
    scale search of capture.depth_agreement takes part of that up)."""
    k = int(np.ceil(np.log(SCALE_SPAN) / np.log(SCALE_STEP)))
    return float(scale) * SCALE_STEP ** np.arange(-k, k + 1, dtype=np.float64)


def reading_check(samples, shapes, cameras, pairs, scale: float, rel: float) -> dict:
    """The depth read as each of :data:`READINGS` against as stored (module docstring), over the view ``pairs``
    (i, j), as stored and as range each at its own best depth scale of :func:`reading_scales` (``scale``), a flip at
    ``scale`` or 1, the better (a flip changes no depth, but the first search's scale of a flipped map is any):
    ``tried`` (per reading:
    the share agreeing, its scale, McNemar's z against as stored at its best scale), ``share_as_stored``, ``status``
    ``reading`` with ``reading`` (the one named) or ``as stored``, and the warning's ``message``."""
    names = [None, *READINGS]
    grids = {name: reading_scales(scale) if name is None or READINGS[name][2] else np.unique([scale, 1.0])
             for name in names}
    read = {name: [x[0] if name is None else read_points(x[0], c, sh, name)
                   for x, c, sh in zip(samples, cameras, shapes)] for name in names}
    hits = {name: [] for name in names}
    for i, j in pairs:
        if len(samples[i][0]):
            for name in names:
                hits[name].append(reading_hits(read[name][i], cameras[i], cameras[j], samples[j], shapes[j],
                                               grids[name], rel, name))
    if not hits[None]:
        return {"status": "as stored", "tried": {}, "share_as_stored": 0.0}
    best = {}
    for name in names:
        h = np.concatenate(hits[name], axis=1)
        k = int(np.argmax(h.sum(axis=1)))
        best[name] = (h[k], float(grids[name][k]))
    base, n = best[None][0], len(best[None][0])
    tried = {}
    for name in READINGS:
        ok, at = best[name]
        b, c = int((ok & ~base).sum()), int((base & ~ok).sum())
        tried[name] = {"share": round(float(ok.sum()) / n, 4), "scale": round(at, 4),
                       "z": round((b - c) / max(float(np.sqrt(b + c)), 1e-9), 2)}
    top = max(tried, key=lambda k: tried[k]["z"])
    rec = {"tried": tried, "share_as_stored": round(float(base.sum()) / n, 4),
           "scale_as_stored": round(best[None][1], 4)}
    if tried[top]["z"] < READING_Z:
        return {**rec, "status": "as stored"}
    t = tried[top]
    return {**rec, "status": "reading", "reading": top, "message": (
        f"the views' depths agree with their poses far more often read as {READING_HINTS[top]} ({t['share']:.1%} "
        f"of the points against {rec['share_as_stored']:.1%} as stored; McNemar's z {t['z']:.1f}): are the depth "
        "maps " + ("z-depth?" if top == "range" else "stored the way the colour images are?"))}


def read_depth(depth: np.ndarray, camera, reading: str) -> np.ndarray:
    """(H, W) float32 ``depth`` as ``reading`` says it was meant (what ``--depth-agreement fix`` does): flipped back,
    or z-depth from the distance along each pixel's ray (0 and NaN kept); the map has ``camera``'s pixel grid."""
    rows, cols, along = READINGS[reading]
    z = np.asarray(depth, np.float32)
    if along:
        h, w = z.shape
        ys, xs = np.mgrid[0:h, 0:w]
        norm = np.linalg.norm(camera.pixel_rays(np.stack([xs, ys], axis=-1).astype(np.float64)), axis=-1)
        return (z / norm).astype(np.float32)
    return np.ascontiguousarray(z[::-1 if rows else 1, ::-1 if cols else 1])


def flip_sums(rgb: np.ndarray, depth: np.ndarray, reading: str, seed: int = 0) -> np.ndarray:
    """(2,) the colour's gradient magnitude summed at the depth's edges as stored, then at the edges of the depth
    flipped as ``reading`` says, each at its best shift within capture.depth_registration.OFFSET_RADIUS working
    pixels (the depth's own offset from the colour), of one view (the edges that stay inside the margin either
    way); zeros with too few edges."""
    from capture.depth_registration import OFFSET_RADIUS as R
    from capture.depth_registration import _around, _gradient_and_edges

    rows, cols, _ = READINGS[reading]
    G, ys, xs, _ = _gradient_and_edges(rgb, depth, seed)
    if G is None:
        return np.zeros(2)
    m = mirror_pixels(np.stack([xs, ys], axis=-1), G.shape, rows, cols).astype(np.int64)
    ok = (m[:, 1] >= R) & (m[:, 1] < G.shape[0] - R) & (m[:, 0] >= R) & (m[:, 0] < G.shape[1] - R)
    return np.array([_around(G, ys[ok], xs[ok]).sum(axis=-1).max(), _around(G, m[ok, 1], m[ok, 0]).sum(axis=-1).max()])

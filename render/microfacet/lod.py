"""Level of detail of the microfacet renderer (docs/methods.md §1.7, Eq. 8-11): the slice spacing l and
the pyramid level from the screen-space tolerance E.  Run on the CPU once per frame; the result
reaches the GPU as uniforms (render.microfacet.gl)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from capture.camera import Camera
from render.microfacet.geometry import (
    K_BLEND,
    MAX_SLICES,
    PHI_EPS,
    SLAB_COVER,
    SLICE_SIDE_FACTOR,
    WEIGHT_EPS,
    camera_angles,
    select_cameras,
)

#: Paper default screen-space tolerance E in pixels (§1.7).
DEFAULT_TOLERANCE_PX = 8.0


#: Draw, on every coarse level, the ancestors of the finest level's surface voxels too
#: (covering_surfaces): the plant's top vanished from a fused 8^3 level (volume.build), whose
#: surface voxels ended 7.6 cm below the plant's tip.
COARSE_COVERS_FINE = True


def eq10_spacing(e_world: float, phi: float, w: float) -> float:
    """Largest slice spacing l (metres) for tolerance ``e_world`` (metres at the voxel) and
    angle ``phi`` (radians) on a level of voxel size ``w``: l = min(E / tan phi, w cos phi)
    (Eq. 10).  phi -> 0 gives w; phi is clamped to [0, pi/2]."""
    phi = float(np.clip(phi, 0.0, np.pi / 2))
    geo = w * np.cos(phi)
    t = np.tan(phi)
    if t <= np.tan(PHI_EPS):
        return float(geo)
    return float(min(e_world / t, geo))


def eq11_level(l_desired: float, phi: float, voxel_sizes) -> int:
    """Index of the pyramid level for a desired spacing (Eq. 11): the level i with
    w_i cos(phi) / 2 < l <= w_i cos(phi).  Coarser than every level -> the coarsest (index 0,
    voxel_sizes coarse -> fine, i.e. decreasing); finer than every level -> the finest."""
    ws = np.asarray(voxel_sizes, dtype=np.float64)
    if ws.size == 0:
        raise ValueError("eq11_level: no levels")
    c = max(np.cos(float(np.clip(phi, 0.0, np.pi / 2))), 1e-12)
    for i, w in enumerate(ws):
        if w * c / 2 < l_desired <= w * c:
            return i
    if l_desired > ws[0] * c:
        return 0
    return len(ws) - 1


def min_spacing(w: float) -> float:
    """Smallest l allowed on a level of voxel size w (keeps slices per voxel <= MAX_SLICES)."""
    return SLICE_SIDE_FACTOR * w / (MAX_SLICES - 1 - 2 * SLAB_COVER)


@dataclass(frozen=True)
class Lod:
    """The per-frame level-of-detail choice (docs/methods.md §1.7).

    Attributes:
        level: index into the pyramid levels (coarse -> fine).
        spacing: slice spacing l in metres (Eq. 10 on that level, clamped by :func:`min_spacing`).
        phi: representative angle (radians) between the view ray and the blended cameras.
        e_world: the tolerance E expressed in metres at the object's centre.
    """

    level: int
    spacing: float
    phi: float
    e_world: float


def choose_lod(eye: Camera, center: np.ndarray, cameras, voxel_sizes, counts, tolerance_px: float,
               footprint_radius: float = 0.0) -> Lod:
    """Pick the level and slice spacing for one frame.

    E (pixels) becomes E_world = E * z / f at the object's centre (z its depth in the eye,
    f the eye's mean focal length).  phi is the weighted mean angle of the cameras blended
    at the centre (:func:`select_cameras`).  l_E = E_world / tan(phi); the level follows Eq. 11;
    then l = Eq. 10 on that level.  Levels with no surface voxel are skipped (nearest
    non-empty level, finer first).

    Args:
        eye: the rendering camera.
        center: (3,) world point standing for the object (bounds centre).
        cameras: input cameras.
        voxel_sizes: w per level, coarse -> fine.
        counts: surface voxels per level (0 = empty level).
        tolerance_px: E in pixels (> 0).
        footprint_radius: radius (m) of the footprint used in the camera selection at the centre.
    """
    if not tolerance_px > 0:
        raise ValueError(f"tolerance must be > 0 pixels, got {tolerance_px}")
    center = np.asarray(center, dtype=np.float64)
    f = 0.5 * (eye.K[0, 0] + eye.K[1, 1])
    z = float(eye.world_to_cam(center)[2])
    dist = float(np.linalg.norm(center - eye.center))
    z = z if z > 1e-9 else max(dist, 1e-9)
    e_world = tolerance_px * z / f
    idx, wts = select_cameras(center[None], footprint_radius, eye.center, cameras)
    valid = idx[0, :K_BLEND] >= 0
    if valid.any():
        phis = camera_angles(center[None], eye.center, cameras)[0][idx[0, :K_BLEND][valid]]
        phi = float(np.sum(wts[0, :K_BLEND][valid] * phis) / max(np.sum(wts[0, :K_BLEND][valid]), WEIGHT_EPS))
    else:
        phi = 0.0
    ws = np.asarray(voxel_sizes, dtype=np.float64)
    counts = np.asarray(counts)
    t = np.tan(max(phi, PHI_EPS))
    l_e = e_world / t
    lev = eq11_level(l_e, phi, ws)
    if counts[lev] == 0:
        nonempty = np.flatnonzero(counts > 0)
        if nonempty.size == 0:
            return Lod(lev, float(eq10_spacing(e_world, phi, ws[lev])), phi, e_world)
        # nearest non-empty level, the finer one on ties
        lev = int(min(nonempty, key=lambda i: (abs(int(i) - lev), -int(i))))
    spacing = max(eq10_spacing(e_world, phi, ws[lev]), min_spacing(ws[lev]))
    return Lod(int(lev), float(spacing), float(phi), float(e_world))


def covering_surfaces(levels) -> list[np.ndarray]:
    """Surface voxel indices drawn per level: the level's own surface voxels plus the ancestors
    of the finest level's surface voxels (COARSE_COVERS_FINE).

    A fused pyramid's coarse levels can lose thin parts (plant tips, needles) that its finest
    level keeps; the slices are carved by Eq. 2 anyway, so a coarse voxel that contains finer
    surface must be drawn.  With an exact distance field the union adds nothing (a parent of a
    surface voxel is a surface voxel when |d| <= half the diagonal)."""
    out = [np.asarray(lv.surface, np.int64) for lv in levels]
    if not COARSE_COVERS_FINE or not levels:
        return [o.astype(np.int32) for o in out]
    fine = levels[-1]
    for i, lv in enumerate(levels[:-1]):
        ratio = fine.resolution // lv.resolution
        if ratio < 1 or fine.resolution % lv.resolution or len(fine.surface) == 0:
            continue
        anc = np.asarray(fine.surface, np.int64) // ratio
        out[i] = unique_rows(np.concatenate([out[i], anc]) if len(out[i]) else anc)
    return [o.astype(np.int32) for o in out]


def unique_rows(ijk: np.ndarray) -> np.ndarray:
    """``np.unique(ijk, axis=0)`` of (N, 3) integer voxel indices, the same rows in the same (lexicographic) order:
    each row packed into one int64 key (mixed radix from the rows' own ranges), a 1-D unique, unpacked: 3-4x faster
    than the row-wise unique (which sorts a structured view); falls back to it where the key would not fit."""
    ijk = np.asarray(ijk, np.int64)
    if ijk.ndim != 2 or ijk.shape[1] != 3 or len(ijk) == 0:
        return np.unique(ijk, axis=0)
    lo = ijk.min(0)
    span = ijk.max(0) - lo + 1
    if float(span[0]) * float(span[1]) * float(span[2]) >= 2.0 ** 62:
        return np.unique(ijk, axis=0)
    d = ijk - lo
    key = np.unique((d[:, 0] * span[1] + d[:, 1]) * span[2] + d[:, 2])
    ij, k = np.divmod(key, span[2])
    i, j = np.divmod(ij, span[1])
    return np.stack([i, j, k], 1) + lo

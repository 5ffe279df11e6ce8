"""Mesh for the fixed-mesh baseline renderer: marching cubes, pymeshlab cleanup, vertex colour.

Marching cubes (scikit-image) on one fused level's signed distance (``MeshConfig.level``,
128^3 by default: its surface already has about the 60k triangles the baseline draws, where
the 256^3 surface had 1.2M that took 20 s of CPU to decimate), cleaned with pymeshlab
(duplicates, unreferenced vertices, tiny components) and decimated by quadric error:
``fast`` = Fast-Quadric-Mesh-Simplification (the ``fast-simplification`` package, about 15x
faster), ``pymeshlab`` = pymeshlab's quadric edge collapse, the reference it is tested
against (tests/volume/test_mesh.py).  pymeshlab's OpenMP threads collapse on a busy 2-core
machine (docs/pitfalls.md), so the wait policy is set to passive before it is imported.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from capture.sampling import nearest_pixel, points_box
from volume.model import SdfLevel

os.environ.setdefault("OMP_WAIT_POLICY", "passive")

#: Decimators: name -> the function of (vertices, faces, target faces).
DECIMATORS = ("fast", "pymeshlab")
#: Components whose bounding-box diagonal is below this fraction of the object's are dropped.
MIN_COMPONENT_FRACTION = 0.02
#: A vertex takes colour from a camera only when its z-depth there is within this many voxels
#: of the geometry depth (visibility) ...
COLOR_DEPTH_TOL_VOXELS = 1.5
#: ... and the camera sees its normal within this angle (degrees).
COLOR_MAX_ANGLE_DEG = 80.0


@dataclass(frozen=True)
class MeshConfig:
    """Mesh extraction parameters."""

    target_faces: int = 60000
    """Decimate to at most this many triangles (0 = no decimation)."""
    clean: bool = True
    """Remove duplicate / unreferenced vertices and small components with pymeshlab."""
    level: int = 128
    """Fused level (L^3, capped at the finest level fused; 0 = the finest) that marching cubes runs on."""
    decimator: str = "fast"
    """Quadric decimation: 'fast' (fast-simplification) or 'pymeshlab' (the reference)."""

    def __post_init__(self) -> None:
        if self.decimator not in DECIMATORS:
            raise ValueError(f"mesh decimator must be one of {DECIMATORS}, got {self.decimator!r}")
        if self.level < 0 or self.level & (self.level - 1):
            raise ValueError(f"mesh level must be a power of two or 0 (the finest), got {self.level}")
        if self.target_faces < 0:
            raise ValueError(f"mesh target_faces must be >= 0, got {self.target_faces}")


def marching_cubes(level: SdfLevel) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (V,3) float32 world metres, faces (F,3) int32) of the zero level set, with faces
    counter-clockwise seen from outside (normals towards positive distance)."""
    from skimage.measure import marching_cubes as mc

    v = level.values
    if v is None:
        raise ValueError(f"level {level.resolution} has no signed distance values")
    if not (v.min() < 0 < v.max()):
        return np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32)
    w = level.voxel_size
    verts, faces, _, _ = mc(np.array(v, np.float32), level=0.0, spacing=(w, w, w), gradient_direction="ascent")
    verts = verts + level.origin + 0.5 * w
    # skimage's winding with "ascent" is clockwise seen from outside: flip to counter-clockwise
    # (checked by the signed volume in tests/volume/test_parts.py)
    return verts.astype(np.float32), np.ascontiguousarray(faces[:, [0, 2, 1]]).astype(np.int32)


def clean_and_decimate(verts: np.ndarray, faces: np.ndarray, cfg: MeshConfig) -> tuple[np.ndarray, np.ndarray]:
    """pymeshlab cleanup, then quadric decimation to ``cfg.target_faces`` by ``cfg.decimator``."""
    if len(faces) == 0 or (not cfg.clean and not cfg.target_faces):
        return verts, faces
    if cfg.decimator == "pymeshlab":
        return _pymeshlab_clean_decimate(verts, faces, cfg.clean, cfg.target_faces)
    if cfg.clean:
        verts, faces = _pymeshlab_clean_decimate(verts, faces, True, 0)
    if cfg.target_faces and len(faces) > cfg.target_faces:
        verts, faces = fast_decimate(verts, faces, cfg.target_faces)
    return verts, faces


def fast_decimate(verts: np.ndarray, faces: np.ndarray, target_faces: int) -> tuple[np.ndarray, np.ndarray]:
    """Quadric decimation to at most ``target_faces`` triangles (fast-simplification), unused
    vertices dropped; winding kept."""
    import fast_simplification

    v, f = fast_simplification.simplify(np.ascontiguousarray(verts, np.float32), np.ascontiguousarray(faces, np.int32),
                                        target_count=int(target_faces))
    used = np.zeros(len(v), bool)
    used[f.reshape(-1)] = True
    remap = np.cumsum(used) - 1
    return np.asarray(v, np.float32)[used], remap[f].astype(np.int32)


def _pymeshlab_clean_decimate(verts: np.ndarray, faces: np.ndarray, clean: bool,
                              target_faces: int) -> tuple[np.ndarray, np.ndarray]:
    """pymeshlab cleanup and quadric edge collapse (threads kept passive, see module docstring)."""
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=verts.astype(np.float64), face_matrix=faces.astype(np.int32)))
    if clean:
        ms.meshing_remove_duplicate_vertices()
        ms.meshing_remove_duplicate_faces()
        ms.meshing_remove_null_faces()
        diag = float(np.linalg.norm(np.diff(points_box(verts), axis=0)))
        ms.meshing_remove_connected_component_by_diameter(
            mincomponentdiag=pymeshlab.PureValue(MIN_COMPONENT_FRACTION * diag))
        ms.meshing_remove_unreferenced_vertices()
    if target_faces and ms.current_mesh().face_number() > target_faces:
        ms.meshing_decimation_quadric_edge_collapse(targetfacenum=int(target_faces), preservenormal=True,
                                                    preservetopology=False, qualitythr=0.3)
        ms.meshing_remove_unreferenced_vertices()
    m = ms.current_mesh()
    return m.vertex_matrix().astype(np.float32), m.face_matrix().astype(np.int32)


def vertex_normals(verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(V, 3) area-weighted unit vertex normals."""
    v = verts.astype(np.float64)
    fn = np.cross(v[faces[:, 1]] - v[faces[:, 0]], v[faces[:, 2]] - v[faces[:, 0]])
    n = np.zeros_like(v)
    for k in range(3):
        np.add.at(n, faces[:, k], fn)
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    return n / np.where(norm > 0, norm, 1.0)


def vertex_colors(verts: np.ndarray, faces: np.ndarray, cameras, images, geom_depth: np.ndarray,
                  voxel_size: float) -> np.ndarray:
    """(V, 3) float32 linear colour per vertex: the mean over the cameras that see it.

    A camera sees a vertex when the vertex projects into the image, its z-depth there matches
    the geometry depth (N, H, W) within COLOR_DEPTH_TOL_VOXELS voxels, and it faces the camera
    within COLOR_MAX_ANGLE_DEG; samples are weighted by the cosine.  Unseen vertices get the
    mean colour of the seen ones (grey if none).
    """
    return vertex_colors_views(verts, faces, cameras, zip(images, geom_depth), voxel_size)


def vertex_colors_views(verts: np.ndarray, faces: np.ndarray, cameras, views, voxel_size: float) -> np.ndarray:
    """:func:`vertex_colors` with ``views`` an iterable of (image (H, W, 3), geometry depth (H, W))
    per camera, consumed one at a time (a model's views decoded one by one)."""
    V = len(verts)
    if V == 0:
        return np.zeros((0, 3), np.float32)
    spec = colour_spec(verts, faces, voxel_size)
    return colours_from_terms((view_colour_terms(spec, cam, img, gd) for cam, (img, gd) in zip(cameras, views)), V)


@dataclass(frozen=True)
class ColourSpec:
    """What :func:`view_colour_terms` needs of the mesh (made once, handed to every view): ``verts``
    (V, 3), their unit normals ``nrm`` (V, 3) float64, the depth tolerance ``tol`` (metres) and the
    cosine limit ``cmin``."""

    verts: np.ndarray
    nrm: np.ndarray
    tol: float
    cmin: float


def colour_spec(verts: np.ndarray, faces: np.ndarray, voxel_size: float) -> ColourSpec:
    """The :class:`ColourSpec` of a mesh whose level has voxels of ``voxel_size``."""
    return ColourSpec(verts, vertex_normals(verts, faces), COLOR_DEPTH_TOL_VOXELS * voxel_size,
                      float(np.cos(np.radians(COLOR_MAX_ANGLE_DEG))))


def view_colour_terms(spec: ColourSpec, cam, img: np.ndarray, gd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One camera's share of :func:`vertex_colors`: (weight (V,), weight times the colour seen (V, 3)),
    for image ``img`` (H, W, 3) and geometry depth ``gd`` (H, W); what :func:`colours_from_terms` sums
    in view order (a pass over the views may make them side by side: volume.rgbz)."""
    verts = spec.verts
    uv, z = cam.project(verts.astype(np.float64))
    with np.errstate(invalid="ignore"):
        u, v = nearest_pixel(uv[:, 0]), nearest_pixel(uv[:, 1])
        inb = np.isfinite(uv).all(axis=1) & (u >= 0) & (u < cam.width) & (v >= 0) & (v < cam.height) & (z > 0)
    ui = np.where(inb, u, 0)
    vi = np.where(inb, v, 0)
    g = gd[vi, ui]
    view = cam.center - verts
    view /= np.maximum(np.linalg.norm(view, axis=1, keepdims=True), 1e-12)
    cos = np.sum(spec.nrm * view, axis=1)
    ok = inb & (g > 0) & (np.abs(z - g) < spec.tol) & (cos > spec.cmin)
    wgt = np.where(ok, cos, 0.0)
    return wgt, wgt[:, None] * img[vi, ui]


def colours_from_terms(terms, V: int) -> np.ndarray:
    """(V, 3) float32 vertex colours from every view's :func:`view_colour_terms` (an iterable, in view
    order): the weighted mean, unseen vertices the mean of the seen ones (grey if none)."""
    acc = np.zeros((V, 3))
    wsum = np.zeros(V)
    for wgt, wimg in terms:
        acc += wimg
        wsum += wgt
    seen = wsum > 0
    out = np.empty((V, 3), np.float32)
    out[seen] = acc[seen] / wsum[seen, None]
    out[~seen] = out[seen].mean(0) if seen.any() else 0.5
    return out

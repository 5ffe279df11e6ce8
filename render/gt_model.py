"""A Model built from exact geometry, for evaluating the renderers on synthetic scan sets.

The renderers' inputs are a :class:`volume.model.Model`; ``furrow model`` builds one from the
scans (signed distance fusion).  To measure the renderers on their own, this module builds a
model whose *voxels* come from the ground-truth mesh (``gt/mesh.ply`` of a synthetic set):

* surface voxels of every level = voxels whose centre lies within half a voxel diagonal of
  the mesh (docs/methods.md §1.1 step 2 with the exact unsigned distance; Open3D RaycastingScene),
  found coarse-to-fine (a child can only be a surface voxel if its parent is);
* RGBz = the scans' own colour and depth (as the paper: the range image of each view), with
  the depth extended to colour-only fringe pixels (:func:`fill_fringe_depth`);
* the baseline mesh = Open3D TSDF fusion of the same scans at the finest level, marching
  cubes, vertex colours from the fused colour (the paper's "fixed polygon model" from range
  scans), so the fixed-mesh baseline does not see the exact geometry.
"""

from __future__ import annotations

import numpy as np

from capture.sampling import voxel_centres
from capture.scan import ScanSet, srgb_to_linear
from volume.grid import cube_for_bounds
from volume.model import Model, RgbzImages, SdfLevel, SdfPyramid, SphereSet
from volume.tsdf import integrate_tsdf

#: Coarsest level kept in the pyramid.
L_MIN = 4
#: TSDF truncation of the baseline mesh, in finest voxel sizes.
TSDF_TRUNC_VOXELS = 3.0
#: RGBz cleaning: pixels with colour but no depth (anti-aliased strand fringes, small depth
#: holes) within this many pixels of a measured depth take the nearest measured depth (2 px left
#: 24 isolated strand-tip pixels black on the 200x150 fur ball: input-pose PSNR 34.1 dB).
FRINGE_RADIUS_PX = 4.0
#: Smallest matte value the straight colour is recovered at (photo / alpha); below, 8-bit
#: quantisation of the photo makes the quotient noise.
MATTE_MIN_ALPHA = 1.0 / 64
#: Largest mean linear value outside the matte of photos over black: an 8-bit matte leaves strand
#: tips below half a step (alpha < 0.002) outside it, far darker than any room behind an object.
OVER_BLACK_MEAN = 1e-3


def fill_fringe_depth(srgb8: np.ndarray, depth: np.ndarray, radius: float = FRINGE_RADIUS_PX) -> np.ndarray:
    """(H, W) depth where every non-black pixel without depth within ``radius`` px of a measured
    pixel gets that nearest measured depth (the RGBz cleaning of docs/methods.md §1.4 for a
    supersampled capture whose colour covers more pixels than its single-sample depth)."""
    from scipy import ndimage

    depth = np.asarray(depth, np.float32)
    valid = depth > 0
    if not valid.any():
        return depth.copy()
    dist, (iy, ix) = ndimage.distance_transform_edt(~valid, return_indices=True)
    fill = (~valid) & (np.asarray(srgb8).max(axis=-1) > 0) & (dist <= radius)
    out = depth.copy()
    out[fill] = depth[iy[fill], ix[fill]]
    return out


def surface_pyramid(vertices: np.ndarray, faces: np.ndarray, origin: np.ndarray, extent: float, l_max: int,
                    l_min: int = L_MIN) -> SdfPyramid:
    """Surface voxels |distance to the mesh| <= half a voxel diagonal on levels l_min..l_max."""
    import open3d as o3d

    if l_max & (l_max - 1) or l_min & (l_min - 1) or l_min > l_max:
        raise ValueError(f"levels must be powers of two with l_min <= l_max, got {l_min}, {l_max}")
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(np.asarray(vertices, np.float32)),
                        o3d.core.Tensor(np.asarray(faces, np.uint32)))
    levels = []
    L = l_min
    cand = np.stack(np.meshgrid(*[np.arange(L)] * 3, indexing="ij"), -1).reshape(-1, 3)
    while L <= l_max:
        w = extent / L
        centres = voxel_centres(cand, origin, w)
        d = scene.compute_distance(o3d.core.Tensor(centres.astype(np.float32))).numpy()
        surf = cand[d <= 0.5 * np.sqrt(3) * w]
        levels.append(SdfLevel(L, origin, w, surf.astype(np.int32)))
        offs = np.stack(np.meshgrid([0, 1], [0, 1], [0, 1], indexing="ij"), -1).reshape(-1, 3)
        cand = (2 * surf[:, None, :] + offs[None]).reshape(-1, 3)
        L *= 2
    return SdfPyramid(tuple(levels), levels[-1].resolution)


def tsdf_mesh(scanset: ScanSet, origin: np.ndarray, extent: float, resolution: int):
    """Baseline mesh from the scans: Open3D UniformTSDFVolume (0.19, ``volume.tsdf.integrate_tsdf``
    with colour) + marching cubes.

    Returns (vertices (V, 3) float32, faces (F, 3) int32, colours (V, 3) float32 linear)."""
    w = extent / resolution
    m = integrate_tsdf(scanset, origin, extent, resolution, TSDF_TRUNC_VOXELS * w, colour=True).extract_triangle_mesh()
    v = np.asarray(m.vertices, np.float32)
    f = np.asarray(m.triangles, np.int32)
    c = srgb_to_linear(np.asarray(m.vertex_colors, np.float32)) if m.has_vertex_colors() else np.zeros_like(v)
    return v, f, c.astype(np.float32)


def rgb_and_matte(scans) -> tuple[np.ndarray, np.ndarray | None]:
    """(N, H, W, 3) float32 linear colour of the scans and their (N, H, W) matte when every scan has
    one (capture.scan.Scan.alpha) and the photos are over black (their mean linear value outside
    the matte at most OVER_BLACK_MEAN), else None (a photo over a room needs the foreground colour the
    model stage estimates).  With a matte the colour is the straight foreground colour: photo / alpha
    where alpha >= MATTE_MIN_ALPHA (below, the photo: too dark to divide)."""
    rgb = np.stack([s.linear_rgb for s in scans]).astype(np.float32)
    if any(s.alpha is None for s in scans):
        return rgb, None
    alpha = np.stack([s.alpha for s in scans]).astype(np.float32)
    outside = rgb[alpha <= 0]
    if outside.size and float(outside.mean()) > OVER_BLACK_MEAN:
        return rgb, None
    a = alpha[..., None]
    straight = np.where(a >= MATTE_MIN_ALPHA, rgb / np.maximum(a, MATTE_MIN_ALPHA), rgb)
    return straight.astype(np.float32), alpha


def model_from_geometry(scanset: ScanSet, vertices: np.ndarray, faces: np.ndarray, l_max: int = 128,
                        l_min: int = L_MIN, provenance: dict | None = None) -> Model:
    """The Model of ``scanset`` with voxels from the exact mesh (module docstring)."""
    origin, extent = cube_for_bounds(scanset.bounds)
    pyr = surface_pyramid(vertices, faces, origin, extent, l_max, l_min)
    rgb, alpha = rgb_and_matte(scanset.scans)
    depth = np.stack([fill_fringe_depth(s.srgb8, s.depth) for s in scanset.scans]).astype(np.float32)
    mv, mf, mc = tsdf_mesh(scanset, origin, extent, l_max)
    return Model(pyramid=pyr, rgbz=RgbzImages(rgb, depth, tuple(scanset.cameras), alpha),
                 spheres=SphereSet(np.zeros((0, 3)), np.zeros(0)), mesh_vertices=mv, mesh_faces=mf, mesh_colors=mc,
                 bounds=scanset.bounds, params={"geometry": "ground-truth mesh", "l_max": l_max, "l_min": l_min,
                                                "baseline_mesh": f"open3d TSDF {l_max}^3"},
                 provenance=provenance or {})


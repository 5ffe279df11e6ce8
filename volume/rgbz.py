"""RGBz images (docs/methods.md §1.4): the geometry's z-depth in every camera, cleaned.

For each input camera:
1. **geometry depth**: the model's mesh in the camera, z-buffer rasterised at the pixel
   centres (volume.mesh_depth, numba) or ray cast (``capture.raycast.raycast_depth``: Open3D RaycastingScene, exact
   triangle intersection, z-depth = t * cos of the ray with the optical axis: the reference,
   ``RgbzConfig.mesh_depth = "raycast"``);
2. **combine with the measured depth** (``keep_measured``, default): every measured depth
   sample is kept and the geometry depth fills only the pixels nothing was measured at.  In
   the paper the RGBz depth *is* the range image taken with the colour image (docs/methods.md §1.4,
   §1.1 "Input"); on fur and plants the fused surface lies inside the fuzz, so replacing the
   measured fringe by it (or dropping fringe pixels with no geometry hit) makes Eq. 2 discard
   exactly the texels the method is for (measured on the demo fur ball: holes and an eroded
   silhouette).  With ``keep_measured=False`` (the former rule) a measured pixel is kept only
   where it agrees with the geometry (|measured - geometry| < ``agree_voxels`` voxels) or,
   where the geometry has no hit, where the measured point lies within ``agree_voxels``
   voxels of the surface; otherwise the geometry depth is used;
3. **morphological closing** (OpenCV, elliptical kernel of ``closing_px``) fills small holes;
   only empty pixels are written.
The hole fraction before and after step 3 is reported per view: empty pixels inside the
object's filled silhouette over the silhouette's area.

Views are done one at a time.  ``RgbzConfig.store = "compact"`` (default) keeps of each view
only its encoded crop around the object (volume.rgbz_store.RgbzCrop: 8-bit sRGB colour, 16-bit
depth, 8-bit alpha), so the stage holds the crops plus one frame; "dense" stacks full float16
frames (the store of every model before issue 24, kept as the reference).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from scipy import ndimage

from capture.raycast import raycast_depth
from capture.sampling import index_coords, sample_grid
from capture.scan import ScanSet
from capture.scan_store import scan_has_alpha
from capture.view_map import or_serial
from volume.model import RGBZ_STORAGE, RgbzImages, SdfLevel
from volume.rgbz_store import CropFile, RgbzCrop, save_crops
from volume.rgbz_zip import DeflatedCrop, deflate_crop, save_deflated_crops

#: RgbzConfig.store choices.
STORES = ("compact", "dense")
#: A spilled run's crops (build_rgbz with a ``crop_file``) deflated in the pass over the views (its
#: workers; volume.rgbz_zip.deflate_crop) and only copied into the model's file by this process
#: (volume.rgbz_zip.save_deflated_crops); False: each view's crop written plain and the whole file
#: deflated here (volume.rgbz_store.save_crops, the reference).  The same decoded arrays
#: (tests/volume/test_rgbz_zip.py); 72 views at 1280x960: 3.0 s of zlib in the main process after the
#: pool (docs/speed.md, round 13).
CROPS_DEFLATED_IN_VIEWS = True


@dataclass(frozen=True)
class RgbzConfig:
    """RGBz preparation parameters (docs/methods.md §1.4)."""

    agree_voxels: float = 2.0
    """Measured and geometry depth agree within this many finest-level voxels."""
    keep_measured: bool = True
    """Keep every measured depth sample (geometry fills the rest); False: only those agreeing
    with the geometry (``agree_voxels``)."""
    closing_px: int = 5
    """Diameter (pixels) of the elliptical closing kernel; 0 disables the closing."""
    mesh_depth: str = "raster"
    """Geometry depth: 'raster' (numba z-buffer, volume.mesh_depth) or 'raycast' (Open3D, the reference)."""
    store: str = "compact"
    """'compact': per-view crops, 8-bit colour and alpha, 16-bit depth; 'dense': full float16 frames."""

    def __post_init__(self) -> None:
        if self.mesh_depth not in ("raster", "raycast"):
            raise ValueError(f"rgbz mesh_depth must be 'raster' or 'raycast', got {self.mesh_depth!r}")
        if self.store not in STORES:
            raise ValueError(f"rgbz store must be one of {STORES}, got {self.store!r}")


def sdf_at(level: SdfLevel, points: np.ndarray) -> np.ndarray:
    """Trilinear signed distance at world points (M, 3); points outside the cube get +inf."""
    L, w = level.resolution, level.voxel_size
    g = index_coords(points, level.origin, w)
    inside = np.all((g >= 0) & (g <= L - 1), axis=1)
    out = np.full(len(g), np.inf)
    if inside.any():
        out[inside] = sample_grid(level.values, g[inside], "linear", "clamp")
    return out


HOLES_FLOOD = True
"""Count :func:`hole_fraction`'s holes with OpenCV's flood fill from the border (one pass, 4-connected,
uint8) instead of ``scipy.ndimage.binary_fill_holes`` (iterated dilations; the reference,
``fast=False``). The same pixels are holes (tests/volume/test_rgbz.py); about 0.03 s a 1280x960 view
less, twice a view."""


def hole_fraction(depth: np.ndarray, fast: bool | None = None) -> float:
    """Empty pixels inside the filled silhouette of ``depth > 0`` over the silhouette's area: the empty
    pixels that no 4-connected path of empty pixels joins to the image's border."""
    full = np.asarray(depth) > 0
    if not (HOLES_FLOOD if fast is None else fast):
        sil = ndimage.binary_fill_holes(full)
        n = int(sil.sum())
        return float(((depth <= 0) & sil).sum()) / n if n else 0.0
    inside = _enclosed(~full)
    n = int(full.sum()) + int(np.count_nonzero(inside))
    return int(np.count_nonzero(inside & (np.asarray(depth) <= 0))) / n if n else 0.0


def _enclosed(empty: np.ndarray) -> np.ndarray:
    """(H, W) bool: the pixels of ``empty`` that no 4-connected path of ``empty`` joins to the border."""
    import cv2

    h, w = empty.shape
    pad = np.ones((h + 2, w + 2), np.uint8)
    pad[1:-1, 1:-1] = empty
    cv2.floodFill(pad, None, (0, 0), 0, flags=4)
    return pad[1:-1, 1:-1].astype(bool)


def close_holes(depth: np.ndarray, closing_px: int) -> np.ndarray:
    """Fill the empty pixels that a morphological closing (OpenCV) covers; others unchanged."""
    if closing_px <= 0:
        return depth
    import cv2

    k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (int(closing_px), int(closing_px)))
    closed = cv2.morphologyEx(depth.astype(np.float32), cv2.MORPH_CLOSE, k)
    return np.where(depth > 0, depth, closed).astype(np.float32)


def combine_depth(measured: np.ndarray, geometry: np.ndarray, cam, level: SdfLevel, tol: float,
                  keep_measured: bool = False) -> np.ndarray:
    """Step 2 of the module docstring for one camera."""
    m = np.asarray(measured, np.float32)
    g = np.asarray(geometry, np.float32)
    if keep_measured:
        return np.where(m > 0, m, g).astype(np.float32)
    out = g.copy()
    agree = (m > 0) & (g > 0) & (np.abs(m - g) < tol)
    out[agree] = m[agree]
    lone = (m > 0) & (g <= 0)
    if lone.any() and level.values is not None:
        pts = cam.unproject(cam.pixel_grid()[lone], m[lone])
        near = np.abs(sdf_at(level, pts)) < tol
        idx = np.nonzero(lone)
        out[idx[0][near], idx[1][near]] = m[lone][near]
    return out


def geometry_depth(verts: np.ndarray, faces: np.ndarray, cam, mesh_depth: str = "raster") -> np.ndarray:
    """(H, W) float32 z-depth of the mesh in one camera (step 1 of the module docstring)."""
    if mesh_depth == "raster":
        from volume.mesh_depth import mesh_depth as raster

        return raster(verts, faces, [cam])[0]
    return raycast_depth(verts, faces, [cam])[0]


def rgbz_view(scan, n, arg):
    """Per view (``arg``: (verts, faces, level, RgbzConfig, with_alpha, folder or None[, the mesh's
    volume.mesh.ColourSpec])): (None, (its RgbzCrop -- or, with a folder, the file it is written to --,
    its hole statistics[, its share of the mesh's vertex colours, volume.mesh.view_colour_terms of the
    decoded crop])), steps 1-3 of the module docstring; the compact store."""
    verts, faces, level, cfg, with_alpha, folder, *colour = arg
    crop, stats = _one_view(scan, verts, faces, level, cfg, with_alpha)
    terms = ()
    if colour and colour[0] is not None:
        from volume.mesh import view_colour_terms
        from volume.rgbz_store import full_frame

        cam = scan.camera
        rgb, depth, _ = full_frame(crop.rect, *crop.decode(), cam.width, cam.height)
        terms = (view_colour_terms(colour[0], cam, rgb, depth),)
    if folder is not None and CROPS_DEFLATED_IN_VIEWS:
        crop = deflate_crop(Path(folder) / f"rgbz_view_{n:06d}.zip", n, crop, with_alpha)
    elif folder is not None:
        crop = crop.save(Path(folder) / f"rgbz_view_{n:06d}.npz")
    return None, (crop, stats, *terms)


def _one_view(scan, verts, faces, level, cfg, with_alpha):
    """(the view's RgbzCrop, or its cleaned depth for the dense store when ``with_alpha`` is None;
    its hole statistics)."""
    cam = scan.camera
    geo = geometry_depth(verts, faces, cam, cfg.mesh_depth)
    comb = combine_depth(scan.depth, geo, cam, level, cfg.agree_voxels * level.voxel_size, cfg.keep_measured)
    before = hole_fraction(comb)
    closed = close_holes(comb, cfg.closing_px)
    stats = {"view": scan.name, "holes_before": before, "holes_after": hole_fraction(closed)}
    measured = measured_depth(scan.depth, closed)
    if with_alpha is None:
        return (closed, measured), stats
    alpha = scan.alpha if scan.alpha is not None or not with_alpha else (closed > 0).astype(np.float32)
    return RgbzCrop.encode(scan.rgb, closed, alpha, measured=measured), stats


def measured_depth(measured: np.ndarray, depth: np.ndarray) -> np.ndarray:
    """(H, W) bool: where the RGBz ``depth`` is the capture's ``measured`` depth (not the geometry's
    fill or the closing): what a renderer may let win over the fill (render.gather)."""
    m = np.asarray(measured, np.float32)
    return (m > 0) & (np.asarray(depth, np.float32) == m)


def build_rgbz(scanset: ScanSet, verts: np.ndarray, faces: np.ndarray, level: SdfLevel,
               cfg: RgbzConfig | None = None, progress=None, crop_file=None,
               map_views=None) -> tuple[RgbzImages, list[dict]]:
    """:func:`build_rgbz_coloured` without the vertex colours."""
    return build_rgbz_coloured(scanset, verts, faces, level, cfg, progress, crop_file, map_views)[:2]


def build_rgbz_coloured(scanset: ScanSet, verts: np.ndarray, faces: np.ndarray, level: SdfLevel,
                        cfg: RgbzConfig | None = None, progress=None, crop_file=None,
                        map_views=None, colour=None) -> tuple[RgbzImages, list[dict], np.ndarray | None]:
    """RgbzImages for every scan's camera and per-view hole statistics
    ``[{"view", "holes_before", "holes_after"}]`` (fractions, see :func:`hole_fraction`).

    ``crop_file`` (a path; compact store only): the crops are written there (volume.rgbz_store.save_crops)
    and the store reads them back view by view, so the crops of a capture are never all held in
    memory: each view's crop waits in a file of its own beside ``crop_file`` until it is written.
    ``map_views``: the pass over the views (capture.view_map, :func:`rgbz_view`; default: in this process).
    ``colour`` (the mesh's volume.mesh.ColourSpec; compact store only): the mesh's vertex colours from
    the crops, each view's share made in its pass (volume.mesh.colours_from_terms: what
    volume.mesh.vertex_colors_views gives over the store's views); else None."""
    cfg = cfg or RgbzConfig()
    cams = [s.camera for s in scanset.scans]
    sizes = {(c.width, c.height) for c in cams}
    if len(sizes) != 1:
        raise ValueError(f"RGBz images need one image size for all cameras, got {sorted(sizes)}")
    with_alpha = any(scan_has_alpha(s) for s in scanset.scans)
    if cfg.store == "dense":
        return (*_dense(scanset, verts, faces, level, cfg, with_alpha, progress), None)
    if cfg.keep_measured:  # the level's distances are read only to test measured depth (keep_measured False)
        level = replace(level, values=None, surface=level.surface[:0])
    folder = None if crop_file is None else Path(crop_file).parent
    arg = (verts, faces, level, cfg, with_alpha, folder, colour)
    notes = or_serial(map_views, progress=(lambda it, d: progress(it)) if progress else None)(
        rgbz_view, list(scanset.scans), arg, "rgbz")[1]
    stats = [note[1] for note in notes]
    colours = None
    if colour is not None:
        from volume.mesh import colours_from_terms

        colours = colours_from_terms((note[2] for note in notes), len(colour.verts))
    crops = [note[0] for note in notes]
    if crop_file is None:
        return RgbzImages.from_crops(cams, crops), stats, colours
    if not (CROPS_DEFLATED_IN_VIEWS and save_deflated_crops(crop_file, crops)):
        save_crops(crop_file, (_crop_of(c, n, with_alpha) for n, c in enumerate(crops)), with_alpha)
    return RgbzImages.from_crops(cams, CropFile(crop_file)), stats, colours


def _crop_of(c, n: int, with_alpha: bool) -> RgbzCrop:
    """View ``n``'s RgbzCrop from what its pass handed back (a crop, a crop's file, or a
    DeflatedCrop, read back and removed)."""
    if not isinstance(c, DeflatedCrop):
        return RgbzCrop.load(c, remove=True)
    with np.load(c.file, allow_pickle=False) as z:
        crop = RgbzCrop(c.rect, z[f"v{n}_srgb"], z[f"v{n}_depth"], c.z0, c.dz,
                        z[f"v{n}_alpha"] if with_alpha else None,
                        z[f"v{n}_measured"] if f"v{n}_measured" in z.files else None)
    Path(c.file).unlink()
    return crop


def _dense(scanset, verts, faces, level, cfg, with_alpha, progress):
    """The dense store (the reference): full float16 frames."""
    n_views = len(scanset.scans)
    cam = scanset.scans[0].camera
    depth = np.zeros((n_views, cam.height, cam.width), RGBZ_STORAGE)
    measured = np.zeros(depth.shape, bool)
    stats = []
    for n in (progress(range(n_views)) if progress else range(n_views)):
        (depth[n], measured[n]), st = _one_view(scanset.scans[n], verts, faces, level, cfg, None)
        stats.append(st)
    rgb = np.stack([s.linear_rgb.astype(RGBZ_STORAGE) for s in scanset.scans])
    alpha = np.stack([s.alpha if s.alpha is not None else (depth[n] > 0).astype(np.float32)
                      for n, s in enumerate(scanset.scans)]) if with_alpha else None
    return RgbzImages(rgb, depth, tuple(s.camera for s in scanset.scans), alpha, measured=measured), stats

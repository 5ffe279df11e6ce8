"""The runnable peer of the consensus fusion: Open3D's TSDF integration (docs/methods.md §1.1).

Open3D 0.19.0 ``UniformTSDFVolume`` (docs/pitfalls.md: 0.20's ScalableTSDFVolume returns empty
meshes) integrates every depth map with its projective distance D - z, truncated to
``trunc`` and averaged with unit weights.  Its band (voxels with weight > 0 and |tsdf| < 1)
gives the values near the surface; everything else gets its sign from the same space-carving
votes as the consensus fusion and its magnitude from the distance transform
(``volume.completion.complete_sdf``), so the two methods differ only in how the band is fused.
"""

from __future__ import annotations

import numpy as np

from capture.scan import ScanSet
from volume.fusion import FusedSdf, FusionConfig, carve_field, completed, scan_maps

#: Depth beyond which Open3D ignores a pixel (metres); far larger than any turntable scene.
DEPTH_TRUNC = 1000.0


def integrate_tsdf(scanset: ScanSet, origin, length: float, resolution: int, trunc: float, colour: bool = False):
    """Open3D ``UniformTSDFVolume`` of the cube ``origin + [0, length]^3`` at ``resolution``^3 voxels
    with every scan's depth (metres) integrated, truncation ``trunc`` (metres), unit weights; with
    ``colour`` the scans' sRGB8 colour is fused too (else none)."""
    import open3d as o3d

    kind = o3d.pipelines.integration.TSDFVolumeColorType
    vol = o3d.pipelines.integration.UniformTSDFVolume(
        length=float(length), resolution=int(resolution), sdf_trunc=float(trunc),
        color_type=kind.RGB8 if colour else kind.NoColor, origin=np.asarray(origin, np.float64).reshape(3, 1))
    for scan in scanset.scans:
        cam = scan.camera
        depth = o3d.geometry.Image(np.ascontiguousarray(scan.depth, dtype=np.float32))
        rgb = np.ascontiguousarray(scan.srgb8) if colour else np.zeros((cam.height, cam.width, 3), np.uint8)
        rgbd = o3d.geometry.RGBDImage.create_from_color_and_depth(
            o3d.geometry.Image(rgb), depth, depth_scale=1.0, depth_trunc=DEPTH_TRUNC, convert_rgb_to_intensity=False)
        K = cam.K
        intr = o3d.camera.PinholeCameraIntrinsic(cam.width, cam.height, K[0, 0], K[1, 1], K[0, 2], K[1, 2])
        vol.integrate(rgbd, intr, np.ascontiguousarray(cam.cam_from_world))
    return vol


def tsdf_volume(scanset: ScanSet, origin, voxel_size: float, resolution: int, trunc: float):
    """Raw Open3D TSDF: (tsdf (L,L,L) float32 in metres, weight (L,L,L) float32), [i,j,k] = x,y,z."""
    L = int(resolution)
    vol = integrate_tsdf(scanset, origin, L * voxel_size, L, trunc)
    tw = np.asarray(vol.extract_volume_tsdf(), dtype=np.float32)
    # Open3D 0.19 stores voxel (x, y, z) at x L^2 + y L + z, i.e. C order [x, y, z]
    # (checked against an independent numpy projective TSDF in tests/volume/test_fusion.py)
    tsdf = tw[:, 0].reshape(L, L, L) * np.float32(trunc)
    weight = tw[:, 1].reshape(L, L, L)
    return np.ascontiguousarray(tsdf), np.ascontiguousarray(weight)


def fuse_tsdf(scanset: ScanSet, origin, voxel_size: float, resolution: int, cfg: FusionConfig | None = None,
              maps=None, coarse: FusedSdf | None = None, progress=None, complete: bool = True) -> FusedSdf:
    """Open3D TSDF band + shared carving sign + distance-transform completion (module docstring);
    ``complete`` as in volume.fusion.fuse_consensus."""
    cfg = cfg or FusionConfig()
    L, w = int(resolution), float(voxel_size)
    origin = np.asarray(origin, np.float64)
    trunc = cfg.trunc(w)
    tsdf, weight = tsdf_volume(scanset, origin, w, L, trunc)
    maps = maps if maps is not None else [scan_maps(s, cfg.max_grazing_deg, cfg.smooth_sigma_z) for s in scanset.scans]
    outside, seen, near = carve_field(maps, origin, w, L, cfg, coarse, progress)
    shape = (L, L, L)
    outside = outside.reshape(shape)
    band = (weight > 0) & (np.abs(tsdf) < np.float32(trunc) * np.float32(0.999))
    bvals = np.where(band, tsdf, 0).astype(np.float32)
    support = np.minimum(weight, 255).astype(np.uint8) * band
    f = FusedSdf(None, band, support, seen.reshape(shape), origin, w, L, (near > 0).reshape(shape) | band,
                 bvals, band, (bvals, outside))
    return completed(f, cfg.backend) if complete else f

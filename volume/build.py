"""Scan set -> Model: fusion of every pyramid level, L_opt, spheres, mesh, RGBz (docs/methods.md §1.1, §1.4, §3).

Levels are fused coarse to fine (each level's pass 1 only near the coarser level's surface,
see volume.fusion.carve_field) for every power of two from ``min_res`` to ``max_res``; Eq. 1
is then evaluated from ``max_res`` down exactly as the paper's loop does, and the pyramid keeps
the levels up to L_opt.  Each level's volume is computed the same way whatever the order, so
the result equals the paper's top-down loop.

Only what a consumer needs is built.  Eq. 1 reads the *measured* field, which fusion gives
before its distance-transform completion; the finest level's completion (most of its cost)
is therefore deferred and done only when something uses that level's values: the pyramid
(L_opt = max_res), the mesh (``MeshConfig.level``) or the spheres (level min(max_res, 64)).
Spheres, mesh and the RGBz geometry depth describe the solid, not the
billboard LOD: they use their own levels even when Eq. 1 keeps coarser levels only.
``ModelConfig.reference()`` is the former pipeline (mesh on the finest level, pymeshlab
decimation, every level completed), kept for the side-by-side benchmark (furrow/bench/model.py).
"""

from __future__ import annotations

import contextlib
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from capture.io import jsonable
from capture.photometric import PhotometricConfig
from capture.scan import ScanSet
from volume.fusion import FusionConfig, completed, fuse_consensus, prepare_maps, scan_maps
from volume.grid import cube_for_bounds
from volume.lopt_sample import sampled_eq1
from volume.mesh import MeshConfig, clean_and_decimate, marching_cubes, vertex_colors_views
from volume.model import Model, SdfLevel, SdfPyramid
from volume.photometric import align_views
from volume.prepare import PrepareConfig, prepare_scans
from volume.pyramid import LoptConfig, build_pyramid, choose_l_opt, discontinuity_fraction
from volume.rgbz import RgbzConfig, build_rgbz
from volume.spheres import fit_spheres
from volume.stream import NORMAL_THREADS, native_scale, pack_scans
from volume.tsdf import fuse_tsdf

#: Sphere sets are fitted on this level (or L_opt if coarser): finer levels cost time, not accuracy
#: of the occluder (docs/methods.md §3: tens to hundreds of spheres).
SPHERE_LEVEL = 64
METHODS = ("consensus", "tsdf")
#: Finest level whose signed distances the model stores (the renderers read surface voxels; the
#: relighting's orientation grid reads <= 32^3): a 256^3 level's values are 64 MB, 20x a
#: 640x480 capture of 18 frames, and nothing reads them.
VALUES_MAX_RES = 64


@dataclass(frozen=True)
class ModelConfig:
    """Everything ``furrow model`` can set."""

    sdf: str = "consensus"
    """Fusion method: 'consensus' (Wheeler-Sato-Ikeuchi style) or 'tsdf' (Open3D peer)."""
    lopt: LoptConfig = field(default_factory=LoptConfig)
    """L_opt search (max_res, alpha, t; docs/methods.md §1.1 Eq. 1)."""
    fusion: FusionConfig = field(default_factory=FusionConfig)
    """Fusion parameters."""
    sphere_error: float = 0.2
    """Target 1 - volume IoU of the occluder sphere set (docs/methods.md §3)."""
    mesh: MeshConfig = field(default_factory=MeshConfig)
    """Mesh extraction."""
    rgbz: RgbzConfig = field(default_factory=RgbzConfig)
    """RGBz preparation (docs/methods.md §1.4)."""
    prepare: PrepareConfig = field(default_factory=PrepareConfig)
    """The object apart from its surroundings before fusion: extent and matte stages (volume.prepare)."""
    measured_voxels: bool = True
    """Voxels holding measured depth points of >= 2 scans are surface voxels too (volume.pyramid)."""
    keep_values: bool = True
    """Store the levels' signed distance values in the model (not only surface voxels)..."""
    values_max_res: int = VALUES_MAX_RES
    """...up to this resolution (finer levels keep their surface voxels only; module constant)."""
    defer_finest: bool = True
    """Complete the finest fused level's distances only when a consumer needs them (module docstring)."""
    photometric: PhotometricConfig | None = field(default_factory=PhotometricConfig)
    """Per-view exposure / white-balance alignment before everything (volume.photometric); None = off."""
    sample_eq1: bool = True
    """Judge L_max by Eq. 1 on a sample first and fuse it only when Eq. 1 may keep it (volume.lopt_sample)."""

    def __post_init__(self) -> None:
        if self.sdf not in METHODS:
            raise ValueError(f"--sdf must be one of {METHODS}, got {self.sdf!r}")

    @classmethod
    def reference(cls, **kw) -> ModelConfig:
        """The pipeline before the build-only-what-is-needed changes: numpy fusion passes, mesh
        marched on the finest level and decimated by pymeshlab, every fused level completed,
        RGBz geometry depth ray cast by Open3D."""
        mesh = MeshConfig(level=0, decimator="pymeshlab")
        fusion = replace(kw.pop("fusion", FusionConfig()), backend="numpy")
        rgbz = replace(kw.pop("rgbz", RgbzConfig()), mesh_depth="raycast")
        return cls(mesh=mesh, defer_finest=False, fusion=fusion, rgbz=rgbz, sample_eq1=False,
                   values_max_res=1 << 30, **kw)


def _release_free_memory() -> None:
    """Hand the heap memory freed by the normal threads back to the system (glibc keeps a worker
    thread's arena otherwise: measured +200-350 MiB of peak resident memory in the fusion after
    it); a no-op where the C library has no malloc_trim."""
    import ctypes
    import ctypes.util

    try:
        ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):
        pass


def scan_maps_of(scanset: ScanSet, fcfg: FusionConfig, progress=None):
    """The fusion's per-scan maps: packed footprint rectangles computed view by view
    (volume.stream.pack_scans) for the compiled backend; the list of full-frame ScanMaps (the
    reference) for 'numpy'."""
    if fcfg.backend == "numba":
        return pack_scans(scanset.scans, fcfg.max_grazing_deg, fcfg.smooth_sigma_z, NORMAL_THREADS, progress,
                          native_scale(scanset, fcfg.map_oversample))
    with ThreadPoolExecutor(NORMAL_THREADS) as pool:
        # numpy and OpenCV release the GIL in these whole-image operations: measured on 18 views of
        # a 640x480 capture, 1.5 s on one thread, 0.8-1.0 s on two (quiet 2-core machine)
        futures = [pool.submit(scan_maps, s, fcfg.max_grazing_deg, fcfg.smooth_sigma_z) for s in scanset.scans]
        return prepare_maps([f.result() for f in (progress(futures, "normals") if progress else futures)],
                            fcfg.backend)


def fuse_levels(scanset: ScanSet, cfg: ModelConfig, stage=None, progress=None, defer_finest: bool = False,
                needed_res: int | None = None):
    """Fuse the levels min_res..max_res; returns (origin, extent, {L: FusedSdf}, {L: Eq. 1 fraction},
    {L: SampledEq1}).

    ``defer_finest``: the finest level's values are left to volume.fusion.completed.
    ``needed_res``: the finest level something other than Eq. 1 reads (mesh, spheres); with
    ``cfg.sample_eq1`` a finer L_max is first judged on a sample (volume.lopt_sample) and fused
    only when Eq. 1 may keep it (then its fraction is exact); a skipped level's fraction is the
    sample's estimate."""
    stage = stage or (lambda name: contextlib.nullcontext())
    origin, extent = cube_for_bounds(scanset.bounds)
    fuse = fuse_consensus if cfg.sdf == "consensus" else fuse_tsdf
    with stage("depth normals"):
        maps = scan_maps_of(scanset, cfg.fusion, progress)
    _release_free_memory()
    fused, frac, sampled = {}, {}, {}
    coarse = None
    top = cfg.lopt.max_res
    sample_top = (cfg.sample_eq1 and cfg.sdf == "consensus" and needed_res is not None and top > needed_res
                  and top // 2 >= cfg.lopt.min_res)
    for L in cfg.lopt.resolutions:
        if L == top and sample_top:
            with stage(f"Eq. 1 sample {L}^3"):
                if coarse.values is None:
                    fused[L // 2] = coarse = completed(coarse, cfg.fusion.backend)
                s = sampled_eq1(maps, coarse, origin, extent, L, cfg.fusion, cfg.lopt.alpha, cfg.lopt.t)
                sampled[L] = s
            if s.decided and not s.passes:
                frac[L] = s.fraction
                break
        with stage(f"fuse {cfg.sdf} {L}^3"):
            f = fuse(scanset, origin, extent / L, L, cfg.fusion, maps, coarse=coarse,
                     complete=not (defer_finest and L == cfg.lopt.max_res))
            frac[L] = discontinuity_fraction(f.measured, f.voxel_size, cfg.lopt.alpha, f.measured_mask)
        fused[L] = coarse = f
    return origin, extent, fused, frac, sampled


def build_model(scanset: ScanSet, cfg: ModelConfig | None = None, stage=None, progress=None,
                provenance: dict | None = None, keep=None, work_dir=None) -> tuple[Model, dict]:
    """Build the Model; returns (model, summary) with the summary keys of ``furrow model --json``.

    ``stage(name)`` is a context-manager factory used to time stages (furrow.console.StageTimer);
    ``progress(iterable, description)`` wraps loops in a progress bar.  ``keep`` takes every scan a
    stage makes (capture.scan_store.ScanSpill.keep: on disk, read back view by view).
    """
    cfg = cfg or ModelConfig()
    stage = stage or (lambda name: contextlib.nullcontext())
    scanset, surroundings = prepare_scans(scanset, cfg.prepare, stage, progress, keep)  # extent, matte
    scanset, photometric = align_views(scanset, cfg.photometric, stage, progress, keep)
    top = cfg.lopt.max_res
    mesh_res = top if cfg.mesh.level == 0 else min(cfg.mesh.level, top)
    sphere_res = min(top, SPHERE_LEVEL)
    origin, extent, fused, frac, sampled = fuse_levels(scanset, cfg, stage, progress, cfg.defer_finest,
                                                       max(mesh_res, sphere_res))
    l_opt = choose_l_opt(frac, cfg.lopt.t)
    # N_i over the measured voxels (reported only; Eq. 1 divides by L^3, see volume.pyramid)
    per_measured = {L: (frac[L] * L ** 3 / n if (n := int(np.count_nonzero(f.measured_mask))) else 0.0)
                    for L, f in fused.items() if f.measured_mask is not None}
    for L in sorted({mesh_res, sphere_res} | {L for L in fused if L <= l_opt}):
        if fused[L].values is None:
            with stage(f"complete {L}^3"):
                fused[L] = completed(fused[L], cfg.fusion.backend)
    with stage("pyramid"):
        points = ViewPoints(scanset) if cfg.measured_voxels else None
        pyramid: SdfPyramid = build_pyramid({L: f.values for L, f in fused.items() if L <= l_opt}, origin, extent,
                                            l_opt, keep_values=True, points=points)
    with stage("spheres"):
        spheres, sphere_err = fit_spheres(_level(fused[sphere_res], origin), cfg.sphere_error)
    mesh_level = _level(fused[mesh_res], origin)
    with stage(f"mesh {mesh_res}^3"):
        verts, faces = marching_cubes(mesh_level)
        verts, faces = clean_and_decimate(verts, faces, cfg.mesh)
    with stage("rgbz"):
        rgbz, holes = build_rgbz(scanset, verts, faces, mesh_level, cfg.rgbz,
                                 (lambda it: progress(it, "rgbz")) if progress else None,
                                 Path(work_dir) / "rgbz_crops.npz" if work_dir is not None else None)
    with stage("mesh colour"):
        # view by view: the decoded frames are never stacked
        colors = vertex_colors_views(verts, faces, rgbz.cameras, (rgbz.view(n)[:2] for n in range(len(rgbz))),
                                     mesh_level.voxel_size) if len(verts) else None
    if not cfg.keep_values:
        pyramid = build_pyramid({lv.resolution: lv.values for lv in pyramid.levels}, origin, extent, l_opt,
                                keep_values=False, points=points)
    pyramid = SdfPyramid(tuple(replace(lv, values=None) if lv.resolution > cfg.values_max_res else lv
                               for lv in pyramid.levels), l_opt)
    params = {"sdf": cfg.sdf, "lopt": asdict(cfg.lopt), "fusion": asdict(cfg.fusion), "sphere_error": cfg.sphere_error,
              "mesh": asdict(cfg.mesh), "rgbz": asdict(cfg.rgbz), "measured_voxels": cfg.measured_voxels,
              "sphere_level": sphere_res, "mesh_level": mesh_res,
              "eq1_fraction": {str(L): v for L, v in frac.items()},
              "eq1_sampled": {str(L): v.record() for L, v in sampled.items()},
              "eq1_flagged_per_measured": {str(L): v for L, v in per_measured.items()},
              "surroundings": jsonable(surroundings), "photometric": photometric}
    prov = {"scans": len(scanset), "scan_names": [s.name for s in scanset.scans],
            "scanset_metadata": jsonable(scanset.metadata), **(provenance or {})}
    bounds = np.asarray(scanset.bounds, np.float64)
    model = Model(pyramid, rgbz, spheres, verts, faces, colors, bounds, params, prov)
    summary = {
        "l_opt": l_opt,
        "levels": pyramid.resolutions,
        "surface_voxels": {str(lv.resolution): int(len(lv.surface)) for lv in pyramid.levels},
        "eq1_fraction": {str(L): round(v, 6) for L, v in frac.items()},
        "eq1_sampled": {str(L): {k: (round(x, 6) if isinstance(x, float) else x) for k, x in v.record().items()}
                        for L, v in sampled.items()},
        "eq1_flagged_per_measured": {str(L): round(v, 6) for L, v in per_measured.items()},
        "spheres": len(spheres),
        "sphere_error": round(sphere_err, 5),
        "mesh": {"vertices": int(len(verts)), "faces": int(len(faces))},
        "surroundings": jsonable(surroundings),
        "holes": [{k: (round(v, 5) if isinstance(v, float) else v) for k, v in h.items()} for h in holes],
        "photometric": photometric,
    }
    return model, summary


class ViewPoints:
    """The scans' measured world points, one view at a time (back-projected on each pass, never
    all held: volume.pyramid.measured_voxels reads them view by view)."""

    def __init__(self, scanset: ScanSet):
        self.scans = scanset.scans

    def __len__(self) -> int:
        return len(self.scans)

    def __iter__(self):
        return (s.points() for s in self.scans)


def _level(f, origin) -> SdfLevel:
    """The SdfLevel (no surface voxels) of a completed FusedSdf."""
    return SdfLevel(f.resolution, origin, f.voxel_size, np.zeros((0, 3), np.int32), f.values)


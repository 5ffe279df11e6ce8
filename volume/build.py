"""The volume stages of the pipeline (volume/pipeline/stages.py): fuse, pyramid, spheres, mesh,
RGBz (docs/methods.md §1.1, §1.4, §3).

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
``PipelineConfig.reference()`` is the former pipeline (mesh on the finest level, pymeshlab
decimation, every level completed), kept for the side-by-side benchmark (furrow/bench/model.py).

Each stage is ``stage(work, cfg, ctx) -> work`` (volume/pipeline/work.py): it reads what the
earlier stages made from ``work.parts`` and adds its own.
"""

from __future__ import annotations

import contextlib
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from capture.scan import ScanSet
from volume import pyramid as pyr_mod
from volume.agreement import FAILED_AGREEMENT
from volume.fusion import FusionConfig, completed, fuse_consensus, prepare_maps, scan_maps
from volume.grid import cube_for_bounds
from volume.lopt_sample import sampled_eq1
from volume.mesh import clean_and_decimate, colour_spec, marching_cubes, vertex_colors_views
from volume.model import ModelError, SdfLevel, SdfPyramid
from volume.pyramid import build_pyramid, choose_l_opt, discontinuity_fraction
from volume.rgbz import build_rgbz_coloured
from volume.spheres import fit_spheres
from volume.stream import NORMAL_THREADS, native_scale, pack_scans
from volume.tsdf import fuse_tsdf

#: The pyramid's measured voxels (volume.pyramid.measured_voxels_mapped): each view's cells found
#: through the runner's per-view map (its pool: the views back-projected side by side, a view's cells
#: sent back instead of its points); False: every view back-projected in this process
#: (volume.pyramid.measured_voxels_levels, the reference).  The same voxels either way
#: (tests/volume/test_pyramid.py); 72 views at 1280x960: docs/speed.md, round 13.
PYRAMID_CELLS_MAPPED = True
#: The mesh's vertex colours made in the RGBz pass over the views (its workers: each view's share from
#: its crop as made, volume.mesh.view_colour_terms, summed here in view order: volume.rgbz.build_rgbz_coloured)
#: instead of every view's crop read back and decoded again in this process (volume.mesh.vertex_colors_views,
#: the reference, and what a dense store takes).  The same colours bit for bit (tests/volume/test_rgbz_zip.py);
#: 72 views at 1280x960: docs/speed.md, round 13.
MESH_COLOURS_IN_VIEWS = True


@dataclass(frozen=True)
class Fused:
    """The fuse stage's result.

    Attributes:
        origin: (3,) float64 corner of the cube (metres, world).
        extent: the cube's edge (metres).
        levels: L -> volume.fusion.FusedSdf (values completed for the levels later stages read).
        l_opt: the resolution Eq. 1 chose.
    """

    origin: np.ndarray
    extent: float
    levels: dict
    l_opt: int

    def level(self, L: int) -> SdfLevel:
        """The SdfLevel (no surface voxels) of the completed level ``L``."""
        f = self.levels[L]
        return SdfLevel(f.resolution, self.origin, f.voxel_size, np.zeros((0, 3), np.int32), f.values)


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


def fuse_levels(scanset: ScanSet, cfg, stage=None, progress=None, defer_finest: bool = False,
                needed_res: int | None = None):
    """Fuse the levels min_res..max_res (``cfg``: FuseConfig); returns (origin, extent, {L: FusedSdf},
    {L: Eq. 1 fraction}, {L: SampledEq1}).

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
    from volume.pipeline.pool import release_free_memory

    release_free_memory()  # glibc keeps the fusion threads' arenas otherwise
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


def fuse_stage(work, cfg, ctx):
    """The fuse stage (cfg: FuseConfig): every level fused, L_opt chosen by Eq. 1, and the levels
    the pyramid, the spheres and the mesh read completed; one stage-table row per step."""
    pc = ctx.config
    origin, extent, fused, frac, sampled = fuse_levels(work.scanset, cfg, ctx.row, ctx.progress, cfg.defer_finest,
                                                       max(pc.mesh_res, pc.sphere_res))
    l_opt = choose_l_opt(frac, cfg.lopt.t)
    # N_i over the measured voxels (reported only; Eq. 1 divides by L^3, see volume.pyramid)
    per_measured = {L: (frac[L] * L ** 3 / n if (n := int(np.count_nonzero(f.measured_mask))) else 0.0)
                    for L, f in fused.items() if f.measured_mask is not None}
    for L in sorted({pc.mesh_res, pc.sphere_res} | {L for L in fused if L <= l_opt}):
        if fused[L].values is None:
            with ctx.row(f"complete {L}^3"):
                fused[L] = completed(fused[L], cfg.fusion.backend)
    rec = {"l_opt": l_opt, "eq1_fraction": {str(L): v for L, v in frac.items()},
           "eq1_sampled": {str(L): v.record() for L, v in sampled.items()},
           "eq1_flagged_per_measured": {str(L): v for L, v in per_measured.items()}}
    return work.made(fused=Fused(origin, extent, fused, l_opt)).record("fuse", rec)


def pyramid_stage(work, cfg, ctx):
    """The pyramid stage (cfg: PyramidConfig): the levels up to L_opt with their surface voxels
    (and the measured points of >= 2 views), their distances kept up to ``values_max_res``."""
    f = work.parts["fused"]
    volumes = {L: v.values for L, v in f.levels.items() if L <= f.l_opt}
    points = measured = None
    if cfg.measured_voxels and PYRAMID_CELLS_MAPPED and ctx.map_views is not None:
        sizes = pyr_mod.pyramid_sizes(volumes, f.extent, f.l_opt)
        measured = pyr_mod.measured_voxels_mapped(ctx.map_views, work.scans, f.origin, sizes)
    elif cfg.measured_voxels:
        points = ViewPoints(work.scans)
    pyr = build_pyramid(volumes, f.origin, f.extent, f.l_opt, keep_values=cfg.keep_values, points=points,
                        measured=measured)
    pyr = SdfPyramid(tuple(replace(lv, values=None) if lv.resolution > cfg.values_max_res else lv
                           for lv in pyr.levels), f.l_opt)
    if not any(len(lv.surface) for lv in pyr.levels):  # nothing to render: say so instead of saving it
        raise _no_surface(work.scans, f, work.records.get("depth agreement"))
    return work.made(pyramid=pyr)


def _no_surface(scans, fused, agreement: dict | None = None) -> ModelError:
    """The error of a volume with no surface at any level, with what the views' depth says of why, and the
    depth-agreement check's finding (``agreement``: its record) where it found the depth and poses at odds."""
    depths = [np.asarray(s.depth) for s in scans]
    meds = [float(np.median(d[d > 0])) for d in depths if np.any(d > 0)]  # per view: no copy of every view's depth
    n, med = len(meds), float(np.median(meds)) if meds else None
    said = (f"none of the {len(depths)} views has depth left: a capture without depth (no depth_file_path) cannot be "
            "modelled (furrow builds its model from RGB-D views), or the extent stage removed it all as far away "
            "(is the depth's unit right? depth_unit_scale_factor; --no-extent keeps it)"
            if not n else
            f"{n} of {len(depths)} views have depth (median {med:.3g} m) but none of it landed in the volume "
            f"(a cube of {fused.extent:.3g} m): are the depth's units right (depth_unit_scale_factor)?")
    if agreement and agreement.get("status") in FAILED_AGREEMENT:
        said += f"; before that, {agreement['message']}"
    return ModelError(f"the fused volume has no surface at any level: {said}")


def spheres_stage(work, cfg, ctx):
    """The spheres stage (cfg: SpheresConfig): the occluder sphere set fitted on its level to the error target."""
    res = ctx.config.sphere_res
    spheres, err = fit_spheres(work.parts["fused"].level(res), cfg.error)
    return work.made(spheres=spheres).record("spheres", {"count": len(spheres), "error": err, "level": res,
                                                        "target": cfg.error})


def mesh_stage(work, cfg, ctx):
    """The mesh stage (cfg: volume.mesh.MeshConfig): marching cubes on the mesh level, cleaned and decimated."""
    verts, faces = marching_cubes(work.parts["fused"].level(ctx.config.mesh_res))
    verts, faces = clean_and_decimate(verts, faces, cfg)
    return work.made(mesh=(verts, faces))


def rgbz_stage(work, cfg, ctx):
    """The RGBz stage (cfg: volume.rgbz.RgbzConfig): each view's colour, alpha and cleaned depth
    (measured, filled from the mesh; streamed to the spill folder as crops), then the mesh's vertex
    colours from them, view by view; rows "rgbz" and "mesh colour"."""
    verts, faces = work.parts["mesh"]
    level = work.parts["fused"].level(ctx.config.mesh_res)
    spec = colour_spec(verts, faces, level.voxel_size) if MESH_COLOURS_IN_VIEWS and len(verts) else None
    with ctx.row("rgbz"):
        rgbz, holes, colors = build_rgbz_coloured(
            work.scanset, verts, faces, level, cfg, lambda it: ctx.track(it, "rgbz"),
            Path(ctx.work_dir) / "rgbz_crops.npz" if ctx.work_dir is not None else None, ctx.map_views, spec)
    with ctx.row("mesh colour"):
        if colors is None and len(verts):
            colors = vertex_colors_views(verts, faces, rgbz.cameras, (rgbz.view(n)[:2] for n in range(len(rgbz))),
                                         level.voxel_size)
    return work.made(rgbz=rgbz, colors=colors).record("rgbz", {"holes": holes})


class ViewPoints:
    """The scans' measured world points, one view at a time (back-projected on each pass, never
    all held: volume.pyramid.measured_voxels reads them view by view)."""

    def __init__(self, scans):
        self.scans = scans

    def __len__(self) -> int:
        return len(self.scans)

    def __iter__(self):
        return (s.points() for s in self.scans)


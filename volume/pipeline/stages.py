"""The capture-to-model pipeline: every stage, in order, in one list (:data:`STAGES`).

A stage is a function, its config (the field ``key`` of volume/pipeline/config.PipelineConfig)
and one row of this list.  Three kinds, by what the function takes:

* ``per view`` -- ``fn(view, ref, cfg) -> (view, note)``, a plain top-level function (picklable):
  the runner (volume/pipeline/runner.py) runs consecutive per-view stages view by view, each view
  through all of them before the next is read, and keeps each result (memory or disk:
  capture/scan_store.py).  ``before(cfg)`` runs once before the views (its own row, NAME warm-up);
  ``reduce(work, notes, cfg)`` turns the views' notes into the stage's record.  The first five
  are the steps that read a frame (capture/sources.FRAME_STEPS, the same functions in the same
  order), skipped when the scans are given in memory.
* ``cameras`` -- ``fn(refs, cfg) -> (kept indices, record)``: works on the cameras alone, so it
  runs before any image of a dropped view is read, wherever it stands among per-view stages.
* ``whole set`` -- ``fn(work, cfg, ctx) -> work`` (volume/pipeline/work.py): needs every view (or
  what earlier stages made); what it does view by view goes through ``ctx.map_views``.

The runner times every stage (one row each in the stage table, or the rows a stage names itself
when ``rows``), shows the progress bars and decides where the views wait: no stage does.

To add a stage: write its function and its config dataclass (a docstring per field), add the
config as a field of PipelineConfig, and add one line here where it belongs (docs/design.md).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from capture import sources
from volume import agreement, build, photometric, surroundings, views
from volume.pipeline import report

VIEW, CAMERAS, SET = "per view", "cameras", "whole set"


def is_set(cfg) -> bool:
    """A stage whose config is None is off."""
    return cfg is not None


def always(cfg) -> bool:
    return True


@dataclass(frozen=True)
class Stage:
    """One stage of the pipeline (module docstring).

    Attributes:
        name: the stage's name (its stage-table row and report key).
        key: its config's field in PipelineConfig.
        kind: VIEW, CAMERAS or SET.
        fn: the stage's function (signature by kind, module docstring).
        does: what it does, one line (``furrow model --plan``, the docs diagram).
        where: the module that holds the work.
        on: ``on(cfg) -> bool``: whether the stage runs with this config (default: cfg is not None).
        before: VIEW: ``before(cfg)`` once before the views (row "NAME warm-up"), or None.
        reduce: VIEW: ``reduce(work, notes, cfg) -> work`` after the views (notes: stage name -> one per view).
        reads_frame: VIEW: a step that reads a frame from its files (skipped for scans given in memory).
        rows: SET: the stage names its own stage-table rows (``ctx.row``) instead of one row.
        row: the stage-table row's name from the whole PipelineConfig (default: ``name``).
    """

    name: str
    key: str
    kind: str
    fn: Callable
    does: str
    where: str
    on: Callable = is_set
    before: Callable | None = None
    reduce: Callable | None = None
    reads_frame: bool = False
    rows: bool = False
    row: Callable | None = None

    def row_name(self, config) -> str:
        return self.row(config) if self.row is not None else self.name


def _mesh_row(pc) -> str:
    return f"mesh {pc.mesh_res}^3"


#: The pipeline, in order (module docstring).
STAGES: tuple[Stage, ...] = (
    Stage("read", "read", VIEW, sources.read_images, "colour, stored depth and confidence of each frame",
          "capture/sources.py", reads_frame=True),
    Stage("units and confidence", "units", VIEW, sources.depth_units, "depth to metres, low confidence removed",
          "capture/sources.py", reads_frame=True),
    Stage("depth resample", "resample", VIEW, sources.resample_depth,
          "a smaller depth map resampled to the colour", "capture/resample.py", reads_frame=True),
    Stage("matte read", "matte_read", VIEW, sources.read_matte, "the capture's matte: mask file or RGBA alpha",
          "capture/matte_io.py", reads_frame=True),
    Stage("undistort", "undistort", VIEW, sources.undistort, "lens-distorted frames to pinhole cameras",
          "capture/lens.py", reads_frame=True),
    Stage("view selection", "views", CAMERAS, views.select_stage, "near-duplicate views dropped (cameras only)",
          "volume/views.py"),
    Stage("working scale", "scale", SET, views.scale_stage, "views scaled to the pixels the output needs",
          "volume/views.py"),
    Stage("depth agreement", "agreement", SET, agreement.agreement_stage,
          "whether the views' depths agree with their poses (warned when not)", "capture/depth_agreement.py"),
    Stage("extent", "extent", SET, surroundings.extent_stage, "support plane, far depth, clutter, floaters out",
          "capture/extent.py"),
    Stage("background plate", "plate", SET, surroundings.plate_stage,
          "the background behind the object, from other views", "capture/plate.py"),
    Stage("matte", "matte", SET, surroundings.matte_stage, "alpha and the object's colour per view",
          "capture/matting.py", on=always, rows=True),
    Stage("photometric", "photometric", SET, photometric.photometric_stage,
          "exposure and white balance aligned across views", "capture/photometric.py"),
    Stage("fuse", "fuse", SET, build.fuse_stage, "signed distance levels fused, L_opt by Eq. 1", "volume/fusion.py",
          rows=True),
    Stage("pyramid", "pyramid", SET, build.pyramid_stage, "levels up to L_opt and their surface voxels",
          "volume/pyramid.py"),
    Stage("spheres", "spheres", SET, build.spheres_stage, "occluder sphere set", "volume/spheres.py"),
    Stage("mesh", "mesh", SET, build.mesh_stage, "baseline mesh: marching cubes, decimated", "volume/mesh.py",
          row=_mesh_row),
    Stage("RGBz", "rgbz", SET, build.rgbz_stage, "each view's colour, alpha and depth; mesh colours",
          "volume/rgbz.py", rows=True),
    Stage("save", "save", SET, report.save_stage, "the model assembled and written atomically", "volume/model.py"),
)


def stage(name: str) -> Stage:
    """The stage called ``name``."""
    for st in STAGES:
        if st.name == name:
            return st
    raise KeyError(f"no pipeline stage {name!r}; stages: {', '.join(s.name for s in STAGES)}")

"""The pipeline's configuration: one config per stage (a field of :class:`PipelineConfig` named by
the stage's ``key`` in volume/pipeline/stages.py) and the runner's own two settings.

A stage whose config is None is off (``--no-extent``, ``--no-photometric``).  The reading stages'
configs live beside their steps in capture/sources.py; extent, plate, matte and photometric keep the
configs of capture/extent.py, capture/plate.py, capture/matting.py and capture/photometric.py; mesh
and RGBz those of volume/mesh.py and volume/rgbz.py.  The others are here.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

from capture.depth_agreement import AgreementConfig
from capture.extent import ExtentConfig
from capture.matting import MatteConfig
from capture.photometric import PhotometricConfig
from capture.plate import PlateConfig
from capture.scan_store import SPILL_MODES
from capture.sources import MatteReadConfig, ReadConfig, ResampleConfig, UndistortConfig, UnitsConfig
from volume.fusion import FusionConfig
from volume.mesh import MeshConfig
from volume.pyramid import LoptConfig
from volume.rgbz import RgbzConfig

#: Fusion methods: consensus (Wheeler-Sato-Ikeuchi style) and Open3D's TSDF (the peer).
SDF_METHODS = ("consensus", "tsdf")
#: Sphere sets are fitted on this level (or L_opt if coarser): finer levels cost time, not accuracy
#: of the occluder (docs/methods.md §3: tens to hundreds of spheres).
SPHERE_LEVEL = 64
#: Finest level whose signed distances the model stores (the renderers read surface voxels; the
#: relighting's orientation grid reads <= 32^3): a 256^3 level's values are 64 MB, 20x a
#: 640x480 capture of 18 frames, and nothing reads them.
VALUES_MAX_RES = 64


@dataclass(frozen=True)
class ViewsConfig:
    """Settings of the view-selection stage (volume/views.py)."""

    mode: str = "auto"
    """``--views``: 'auto' drops near-duplicate views, 'all' keeps every view, 'N' keeps the N most spread out."""

    def __post_init__(self) -> None:
        if self.mode not in ("auto", "all") and not (self.mode.isdigit() and int(self.mode) >= 1):
            raise ValueError(f"--views must be auto, all or a number of views >= 1, got {self.mode!r}")


@dataclass(frozen=True)
class ScaleConfig:
    """Settings of the working-scale stage (volume/views.py)."""

    output_size: tuple[int, int] | None = None
    """``--output-size`` (W, H) of the frames to be rendered: the views are scaled down so the object
    keeps the pixels it will cover there (never up); None = full resolution (the stage is off)."""


@dataclass(frozen=True)
class FuseConfig:
    """Settings of the fuse stage (volume/build.py): fusion of every level, Eq. 1, L_opt."""

    sdf: str = "consensus"
    """``--sdf``: 'consensus' (Wheeler-Sato-Ikeuchi style) or 'tsdf' (Open3D peer)."""
    lopt: LoptConfig = field(default_factory=LoptConfig)
    """L_opt search (``--max-res``, ``--alpha``, ``--t``; docs/methods.md §1.1 Eq. 1)."""
    fusion: FusionConfig = field(default_factory=FusionConfig)
    """Fusion parameters (``--quorum``; backend 'numba' or the 'numpy' reference)."""
    sample_eq1: bool = True
    """Judge L_max by Eq. 1 on a sample first and fuse it only when Eq. 1 may keep it (volume.lopt_sample)."""
    defer_finest: bool = True
    """Complete the finest fused level's distances only when a later stage reads them."""

    def __post_init__(self) -> None:
        if self.sdf not in SDF_METHODS:
            raise ValueError(f"--sdf must be one of {SDF_METHODS}, got {self.sdf!r}")


@dataclass(frozen=True)
class PyramidConfig:
    """Settings of the pyramid stage (volume/pyramid.py): the levels up to L_opt and their surface voxels."""

    measured_voxels: bool = True
    """Voxels holding measured depth points of >= 2 scans are surface voxels too (volume.pyramid)."""
    keep_values: bool = True
    """Store the levels' signed distance values in the model (not only surface voxels)..."""
    values_max_res: int = VALUES_MAX_RES
    """...up to this resolution (finer levels keep their surface voxels only)."""


@dataclass(frozen=True)
class SpheresConfig:
    """Settings of the spheres stage (volume/spheres.py): the occluder sphere set."""

    error: float = 0.2
    """``--sphere-error``: target 1 - volume IoU of the sphere set (docs/methods.md §3)."""
    level: int = SPHERE_LEVEL
    """Fused level the spheres are fitted on (capped at L_max)."""


@dataclass(frozen=True)
class SaveConfig:
    """Settings of the save stage (volume/model.py): the model assembled, and written when ``out`` is set."""

    out: Path | None = None
    """Model folder written atomically (``furrow model -o``); None = the model stays in memory (``furrow eval``)."""
    capture_env: object | None = None
    """The lighting the scans were taken under (an EnvMap: ``--capture-env*``), stored with the rig's up axis."""
    capture_env_rotation: float = 0.0
    """Rotation of ``capture_env`` about the up axis (degrees)."""
    capture_env_source: str = ""
    """What ``capture_env`` came from (a bundled name or a file), for the model report."""


@dataclass(frozen=True)
class PipelineConfig:
    """Every setting of the capture-to-model pipeline: one field per stage (its ``key`` in
    volume/pipeline/stages.py; None = the stage is off), then the runner's own."""

    read: ReadConfig = field(default_factory=ReadConfig)
    """read: which frames."""
    units: UnitsConfig = field(default_factory=UnitsConfig)
    """units and confidence: the depth in metres, low confidence out."""
    resample: ResampleConfig = field(default_factory=ResampleConfig)
    """depth resample: a smaller depth map brought to the colour camera."""
    matte_read: MatteReadConfig = field(default_factory=MatteReadConfig)
    """matte read: the capture's own matte."""
    undistort: UndistortConfig = field(default_factory=UndistortConfig)
    """undistort: lens-distorted frames to pinhole cameras."""
    views: ViewsConfig = field(default_factory=ViewsConfig)
    """view selection: near-duplicate views dropped."""
    scale: ScaleConfig = field(default_factory=ScaleConfig)
    """working scale: views scaled to the output size."""
    agreement: AgreementConfig | None = field(default_factory=AgreementConfig)
    """depth agreement: whether the views' depths agree with their poses, warned when not (None:
    ``--depth-agreement off``)."""
    extent: ExtentConfig | None = field(default_factory=ExtentConfig)
    """extent: support plane, far depth, clutter and floaters out of the depth (None: ``--no-extent``)."""
    plate: PlateConfig | None = field(default_factory=PlateConfig)
    """background plate: the background behind the object per view, from the capture (None: off)."""
    matte: MatteConfig = field(default_factory=MatteConfig)
    """matte: alpha and the object's colour per view (mode 'off': the binary depth mask)."""
    photometric: PhotometricConfig | None = field(default_factory=PhotometricConfig)
    """photometric: per-view exposure and white balance aligned (None: ``--no-photometric``)."""
    fuse: FuseConfig = field(default_factory=FuseConfig)
    """fuse: signed distance levels, Eq. 1, L_opt."""
    pyramid: PyramidConfig = field(default_factory=PyramidConfig)
    """pyramid: the levels up to L_opt and their surface voxels."""
    spheres: SpheresConfig = field(default_factory=SpheresConfig)
    """spheres: the occluder sphere set."""
    mesh: MeshConfig = field(default_factory=MeshConfig)
    """mesh: the baseline mesh (``--mesh-level``, ``--mesh-faces``)."""
    rgbz: RgbzConfig = field(default_factory=RgbzConfig)
    """RGBz: the views' colour, alpha and depth stored in the model, and the mesh's vertex colours."""
    save: SaveConfig = field(default_factory=SaveConfig)
    """save: the model assembled and written."""
    spill: str = "auto"
    """Runner: where the views wait between stages (``--spill``: auto, always, never; capture/scan_store.py)."""
    workers: int = 1
    """Runner: processes the per-view stages are mapped over (1 = in this process; 0 = the machine's
    cores where the per-view work pays for a pool, else 1: volume/pipeline/pool.workers_for)."""

    def __post_init__(self) -> None:
        if self.spill not in SPILL_MODES:
            raise ValueError(f"--spill must be one of {', '.join(SPILL_MODES)}, got {self.spill!r}")
        if self.workers < 0:
            raise ValueError(f"workers must be >= 1 (or 0: by the pool rule), got {self.workers}")

    @property
    def mesh_res(self) -> int:
        """The fused level the mesh is marched on (MeshConfig.level capped at L_max; 0 = L_max)."""
        top = self.fuse.lopt.max_res
        return top if self.mesh.level == 0 else min(self.mesh.level, top)

    @property
    def sphere_res(self) -> int:
        """The fused level the spheres are fitted on."""
        return min(self.fuse.lopt.max_res, self.spheres.level)

    def reference(self) -> PipelineConfig:
        """The same pipeline with the slow reference paths (``--reference-pipeline``): numpy fusion
        passes, mesh marched on the finest level and decimated by pymeshlab, every fused level
        completed and stored, RGBz geometry depth ray cast by Open3D."""
        return replace(self, fuse=replace(self.fuse, fusion=replace(self.fuse.fusion, backend="numpy"),
                                          defer_finest=False, sample_eq1=False),
                       pyramid=replace(self.pyramid, values_max_res=1 << 30),
                       mesh=replace(self.mesh, level=0, decimator="pymeshlab"),
                       rgbz=replace(self.rgbz, mesh_depth="raycast"))

"""Synthetic turntable captures: render a scene from a rig, add noise, write the scan set + gt/.

On disk (docs/design.md "Scan format on disk", written by ``capture.io.write_transforms``):
``transforms.json``, ``images/``, ``depth/`` and ``gt/`` with ``gt/mesh.ply`` (exact geometry,
world metres, +z up), ``gt/scene.json`` (name, seed, bounds, parameters, counts, rig, lighting,
noise) and, when the poses were perturbed, ``gt/cameras_true.json`` (the unperturbed poses in
the nerfstudio frame format).  Relighting ground truth (``datasets_synthetic.relight``) adds
``relit/<map>/transforms.json``, ``relit/<map>/images/<name>.png`` (every view rendered again
under <map> with the same scene, cameras and exposure; depth shared with the capture's depth/)
and ``relit/<map>/lighting.json``.  Colour images are rendered with the *true* poses; only the
recorded poses carry the pose noise.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from capture.camera import Camera
from capture.io import DEFAULT_PNG_DEPTH_UNIT, write_transforms
from capture.lens import Lens
from capture.scan import Scan, ScanSet, select_indices
from datasets_synthetic.backdrop import SUPPORTS, clutter_background, support_layer, upward_radiance
from datasets_synthetic.geometry import ply_bytes
from datasets_synthetic.lighting import LightingConfig, ambient_residual, background, resolve_env, scene_lighting
from datasets_synthetic.noise import NoiseConfig, depth_noise, grazing_dropout, perturb_pose, random_holes
from datasets_synthetic.pixel_filter import path_tracer_filter
from datasets_synthetic.rig import TurntableRig
from datasets_synthetic.scenes import Scene, build_scene
from datasets_synthetic.sensor import SENSORS, SensorModel, apply_sensor
from datasets_synthetic.synth_renderer import RENDERERS, SceneRenderer

#: Margin added around the scene's tight bounds for the ScanSet bounds (fraction of the diagonal).
BOUNDS_MARGIN = 0.05
#: Reference image width for the hole radii of NoiseConfig (radii scale with width / this).
HOLE_RADIUS_REF_WIDTH = 640
#: Backgrounds of SynthConfig.background.
BACKGROUNDS = ("black", "env", "clutter")
#: The CI-sized capture of ``--small``.
SMALL_RIG = TurntableRig(views_per_ring=12, width=160, height=120)


@dataclass(frozen=True)
class SynthConfig:
    """Everything that defines a synthetic capture (with the scene name and seed)."""

    scene: str = "furball"
    """Scene name (``furball``, ``plant``, ``torus``)."""
    seed: int = 0
    """Seed of the scene geometry and of the noise."""
    rig: TurntableRig = field(default_factory=TurntableRig)
    """Camera rig."""
    lighting: LightingConfig = field(default_factory=LightingConfig)
    """Environment lighting."""
    noise: NoiseConfig = field(default_factory=NoiseConfig)
    """Noise models (default: none)."""
    sensor: SensorModel = field(default_factory=lambda: SENSORS["ideal"])
    """Depth-sensor traits applied after ``noise`` (``datasets_synthetic.sensor``; default exact
    float depth; ``furrow synth`` defaults to the ``d435`` preset)."""
    supersample: int = 3
    """Colour supersampling factor (per axis); thin strands alias badly without it."""
    background: str = "black"
    """What is seen behind the object: 'black', 'env' (the environment map made visible) or
    'clutter' (a room of coloured boxes, ``datasets_synthetic.backdrop``)."""
    support: str = "none"
    """Support under the object, in colour and in depth: 'none', 'disc' (a turntable) or 'table'."""
    background_frames: str | None = None
    """Rig views (slice spec, e.g. '0::2') that show the background and the support; the others are
    over black with the object's depth only, as held-out views of the evaluation captures are
    (None = every view)."""
    scene_params: dict = field(default_factory=dict)
    """Overrides of the scene's parameter dataclass (e.g. ``{"strands": 5000}``)."""
    views: tuple[int, ...] | None = None
    """Render only these indices of the rig's views (None = all); noise seeds follow the index."""
    pixel_filter_px: float = 0.0
    """Film filter of the colour: a Gaussian of this standard deviation in total, like a path
    tracer's (``datasets_synthetic.pixel_filter``; ``furrow synth`` defaults to 0.5); 0 = the
    rasteriser's 1-pixel box."""
    lens: Lens | None = None
    """Lens distortion of every view (datasets_synthetic.camera_traits; None = pinhole)."""
    renderer: str = RENDERERS[0]
    """'gl' (strands as ribbons shaded on the GPU, ``datasets_synthetic.strand_gl``) or 'numpy' (every
    strand a tube of triangles, the hair lobes in numpy: the reference; ``synth_renderer``)."""

    def __post_init__(self) -> None:
        if self.background not in BACKGROUNDS:
            raise ValueError(f"background must be one of {', '.join(BACKGROUNDS)}, got {self.background!r}")
        if self.support not in SUPPORTS:
            raise ValueError(f"support must be one of {', '.join(SUPPORTS)}, got {self.support!r}")
        if self.lens is not None and (self.support != "none" or self.background == "clutter"):
            raise ValueError("a lens is drawn through the object and the environment only: use it with "
                             "background black or env and no support")
        if self.supersample < 1:
            raise ValueError(f"supersample must be >= 1, got {self.supersample}")
        if self.renderer not in RENDERERS:
            raise ValueError(f"renderer must be one of {', '.join(RENDERERS)}, got {self.renderer!r}")
        if not 0 <= self.pixel_filter_px <= 4:
            raise ValueError(f"pixel_filter_px must be in [0, 4], got {self.pixel_filter_px}")


@dataclass(frozen=True)
class Capture:
    """A synthetic capture in memory.

    Attributes:
        scanset: the scans as written (noisy depth / poses when noise is on).
        scene: the scene (exact mesh).
        true_cameras: the cameras the images were rendered with.
        clean_depth: (N, H, W) float32 exact z-depth (before noise).
        normals: (N, H, W, 3) float32 world normals (single-sample pass).
        info: JSON-able description written to gt/scene.json.
    """

    scanset: ScanSet
    scene: Scene
    true_cameras: tuple[Camera, ...]
    clean_depth: np.ndarray
    normals: np.ndarray
    info: dict


def _view_rng(seed: int, view: int, stream: int) -> np.random.Generator:
    return np.random.default_rng([int(seed), int(view), int(stream)])


def synthesize(cfg: SynthConfig, ctx=None, scene: Scene | None = None,
               progress: Callable | None = None) -> Capture:
    """Render ``cfg`` (GL context ``ctx``, or a temporary one).  ``progress(iterable, label)``
    wraps the per-view loop (e.g. ``furrow.console.track``)."""
    from render.gl import gl_context

    if ctx is None:
        with gl_context() as own:
            return synthesize(cfg, own, scene, progress)
    scene = scene if scene is not None else build_scene(cfg.scene, cfg.seed, **cfg.scene_params)
    env = resolve_env(cfg.lighting.env)
    lighting, light_info = scene_lighting(env, cfg.lighting)
    tight = scene.bounds
    diag = float(np.linalg.norm(tight[1] - tight[0]))
    bounds = np.stack([tight[0] - BOUNDS_MARGIN * diag, tight[1] + BOUNDS_MARGIN * diag])
    cams = cfg.rig.cameras(float(np.linalg.norm(scene.mesh.vertices, axis=1).max()))
    nz = cfg.noise
    radius = tuple(r * cfg.rig.width / HOLE_RADIUS_REF_WIDTH for r in nz.hole_radius_px)
    scans, clean, normals, recorded = [], [], [], []
    views = list(enumerate(cams))
    if cfg.views is not None:
        bad = [i for i in cfg.views if not 0 <= i < len(cams)]
        if bad:
            raise ValueError(f"views {bad} out of range for a rig of {len(cams)} views")
        views = [views[i] for i in cfg.views]
    lc = cfg.lighting
    shown = set(select_indices(cfg.background_frames, len(cams)))
    with SceneRenderer(ctx, cfg.renderer, cfg.supersample, scene.mesh, lighting, ambient_residual(env, lc), lc) as rend:
        for i, cam in (progress(views, f"rendering {cfg.scene}") if progress else views):
            res = rend.render(cam, cfg.lens)
            rgb, depth = _surroundings(cfg, env, lighting.exposure, cam, res, scene, i in shown)
            rgb = path_tracer_filter(rgb, cfg.pixel_filter_px)
            # the object's true matte: its supersampled coverage under the same film filter as the colour
            matte = path_tracer_filter(res.alpha[..., None], cfg.pixel_filter_px)[..., 0]
            if nz.grazing_deg > 0:
                depth = grazing_dropout(cam, depth, res.normal, nz.grazing_deg)
            if nz.holes_fraction > 0:
                depth = random_holes(depth, _view_rng(cfg.seed, i, 1), nz.holes_fraction, radius)
            if nz.depth_sigma_at_1m > 0:
                depth = depth_noise(depth, _view_rng(cfg.seed, i, 2), nz.depth_sigma_at_1m)
            depth = apply_sensor(depth, _view_rng(cfg.seed, i, 4), cfg.sensor)
            rec = cam
            if nz.any_pose:
                rec = perturb_pose(cam, _view_rng(cfg.seed, i, 3), nz.pose_rot_deg, nz.pose_trans_frac * diag)
            recorded.append(rec)
            scans.append(Scan(np.clip(rgb, 0, None).astype(np.float32), depth, rec, name=f"{cam.name}.png",
                              alpha=np.clip(matte, 0.0, 1.0)))
            clean.append(res.depth)
            normals.append(res.normal)
    info = {
        "name": scene.name, "seed": scene.seed, "generator": "furrow datasets_synthetic",
        "units": "metres, world +z up", "bounds": tight.tolist(), "scanset_bounds": bounds.tolist(),
        "params": scene.params, "stats": scene.stats, "rig": asdict(cfg.rig), "lighting": light_info,
        "lighting_config": asdict(cfg.lighting), "noise": asdict(nz), "sensor": cfg.sensor.to_json(),
        "supersample": cfg.supersample, "pixel_filter_px": cfg.pixel_filter_px,
        "background": cfg.background, "support": _support_info(cfg, scene),
        "background_frames": cfg.background_frames, "poses_perturbed": nz.any_pose,
        "shadow_maps": rend.shadow_info, "lens": cfg.lens.record() if cfg.lens is not None else None,
        "hair": rend.hair_info, "renderer": cfg.renderer,
    }
    meta = {"generator": "furrow synth", "scene": scene.name, "seed": scene.seed, "noise": asdict(nz),
            "sensor": cfg.sensor.name}
    true_cams = tuple(c for _, c in views)
    if cfg.support != "none":  # a real capture has no bounds: a reader derives them from the depth, support included
        from capture.io import auto_bounds

        bounds = auto_bounds(scans)
    return Capture(ScanSet(tuple(scans), bounds, meta), scene, true_cams, np.stack(clean), np.stack(normals), info)


def _support_info(cfg: SynthConfig, scene: Scene) -> dict:
    """gt/scene.json's record of the support: kind, plane (world +z up, z = z0) and radius."""
    v = scene.mesh.vertices
    return {"kind": cfg.support, "plane_normal": [0.0, 0.0, 1.0], "z0": float(v[:, 2].min()),
            "object_radius": float(np.hypot(v[:, 0], v[:, 1]).max())}


def _surroundings(cfg: SynthConfig, env, exposure: float, cam: Camera, res, scene: Scene, shown: bool):
    """(linear colour (H, W, 3), z-depth (H, W)) of one view: the object over the support over the
    background (``datasets_synthetic.backdrop``; the support also in the depth) on views that show
    them, the object over black with its own depth on the others."""
    if not shown or (cfg.background == "black" and cfg.support == "none"):
        return res.color, res.depth
    a = res.alpha[..., None]
    if cfg.background == "env":
        bg = background(env, cam, exposure, cfg.lighting.rotation_deg)
    elif cfg.background == "clutter":
        bg = clutter_background(cam, upward_radiance(env, exposure), cfg.seed)
    else:
        bg = np.zeros_like(res.color)
    depth = res.depth
    if cfg.support != "none":
        info = _support_info(cfg, scene)
        s_col, s_cov, s_depth = support_layer(cam, cfg.support, info["z0"], info["object_radius"],
                                              upward_radiance(env, exposure), cfg.supersample)
        bg = s_col + (1.0 - s_cov[..., None]) * bg
        depth = np.where(res.depth > 0, res.depth, s_depth).astype(np.float32)
    return res.color + (1.0 - a) * bg, depth


def _cameras_json(cams) -> bytes:
    frames = [{"name": c.name, **c.to_nerfstudio()} for c in cams]
    return json.dumps({"convention": "nerfstudio transform_matrix (camera-to-world, OpenGL axes), "
                       "cx/cy with pixel centres at i + 0.5", "frames": frames}, indent=1).encode()


def gt_files(cap: Capture) -> dict[str, bytes]:
    """The ``gt/`` files of a capture: relative path -> bytes."""
    files = {"gt/mesh.ply": ply_bytes(cap.scene.mesh),
             "gt/scene.json": json.dumps(cap.info, indent=1, default=float).encode()}
    if cap.info.get("poses_perturbed"):
        files["gt/cameras_true.json"] = _cameras_json(cap.true_cameras)
    return files


def write_capture(cap: Capture, out_dir, depth_format: str = "png", overwrite: bool = False,
                  extra_files: dict[str, bytes] | None = None, progress: Callable | None = None,
                  png_depth_unit: float = DEFAULT_PNG_DEPTH_UNIT, depth_size=None) -> Path:
    """Write the scan set (transforms.json, images/, depth/) and gt/ atomically; returns
    the transforms.json path.  ``depth_format``: a ``capture.io.DEPTH_FORMATS`` name (``png``:
    16-bit in units of ``png_depth_unit`` metres, millimetres by default; ``png-0.1mm``; ``exr``).
    ``extra_files`` (relative path -> bytes) go into the same atomic folder, e.g. the relighting
    ground truth ``relit/<map>/{transforms.json, images/*.png, lighting.json}`` from
    ``datasets_synthetic.relight.relit_files``."""
    files = gt_files(cap)
    files.update(extra_files or {})
    lens = cap.info.get("lens")
    lens = Lens(lens["model"], tuple(lens["coeffs"]), lens["source"]) if lens else None
    return write_transforms(cap.scanset, Path(out_dir), depth_format=depth_format, overwrite=overwrite,
                            extra_files=files, progress=progress, png_depth_unit=png_depth_unit, lens=lens,
                            depth_size=depth_size)

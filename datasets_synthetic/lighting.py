"""Environment lighting of the synthetic captures, through ``render.shading`` (never a copy).

The environment is split (``render.shading.lights``) into its K dominant lights, which cast
shadow maps in the rasteriser, and the remainder, whose diffuse irradiance is its exact
irradiance table (``render.shading.irradiance``: within ~1% of the brute-force integral, looked
up by ``env_irradiance`` in the shaded raster mode) attenuated by the per-vertex ambient
occlusion.  (Until 2026-11-22 the remainder was lit by its SH9 projection, which is off by up to
tens of percent on real maps: :func:`ambient_accuracy` measures both against brute force.)
The two add back to the environment's full power.  The lights
are fixed in the world (the object stands still, the cameras circle it), so every view sees
the same lighting.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from capture.camera import Camera
from render.mesh.raster.gl import MAX_LIGHTS, Lighting
from render.shading.envmap import BUNDLED_NAMES, EnvMap, bundled_envmap, load_envmap, procedural_sky
from render.shading.irradiance import irradiance_lookup, irradiance_table
from render.shading.lights import LUMA, dominant_lights, env_minus_lights
from render.shading.sh import irradiance_brute, sh9_irradiance, sh9_project

#: Rows of the environment copy used to find lights and project SH (area-correct resample).
ENV_WORK_HEIGHT = 256
#: Number of random normals used to find the largest irradiance for the exposure.
EXPOSURE_PROBES = 2048
#: Height of the ambient irradiance table (its source is the ENV_WORK_HEIGHT residual map, i.e.
#: src_factor = ENV_WORK_HEIGHT / AMBIENT_TABLE_H).
AMBIENT_TABLE_H = 128


@dataclass(frozen=True)
class LightingConfig:
    """Environment lighting of a synthetic capture."""

    env: str = "studio"
    """Bundled map name (studio, courtyard, forest, sunset), 'procedural', or a .exr/.hdr path."""
    lights: int = 3
    """Dominant lights that cast shadows (<= MAX_LIGHTS)."""
    rotation_deg: float = 0.0
    """Rotation of the environment about +z (degrees)."""
    key: float = 1.1
    """Exposure: radiance of a white Lambertian surface under the largest irradiance."""
    shininess: float = 40.0
    """Blinn-Phong exponent of surfaces."""
    hair_shininess: float = 60.0
    """Kajiya-Kay exponent of strands (``hair_model`` "kajiya-kay")."""
    hair_model: str = "chiang"
    """Strand shading: "chiang" (R / TT / TRT lobes, ``datasets_synthetic.hair_shading``) or
    "kajiya-kay" (the rasteriser's lobe, the generator before 2026-12)."""
    hair_env_lights: int = 32
    """Directional lights (median cut, a power of two) standing for the map minus its dominant
    lights in the "chiang" hair shading."""
    shadows: bool = True
    """Shadow maps for the dominant lights."""

    def __post_init__(self) -> None:
        if not 0 <= self.lights <= MAX_LIGHTS:
            raise ValueError(f"lighting: lights must be in [0, {MAX_LIGHTS}], got {self.lights}")
        if self.key <= 0:
            raise ValueError(f"lighting: key must be > 0, got {self.key}")
        if self.hair_model not in ("chiang", "kajiya-kay"):
            raise ValueError(f"lighting: hair_model must be 'chiang' or 'kajiya-kay', got {self.hair_model!r}")
        n = self.hair_env_lights
        if n < 1 or n & (n - 1):
            raise ValueError(f"lighting: hair_env_lights must be a power of two, got {n}")


def resolve_env(name_or_path: str) -> EnvMap:
    """A bundled map by name, 'procedural', or a file path; clear error otherwise."""
    if name_or_path == "procedural":
        return procedural_sky(128)
    if name_or_path in BUNDLED_NAMES:
        return bundled_envmap(name_or_path)
    p = Path(name_or_path)
    if p.suffix.lower() in (".exr", ".hdr", ".pic", ".rgbe") or p.exists():
        return load_envmap(p)
    raise ValueError(f"unknown environment {name_or_path!r}: use one of {', '.join(BUNDLED_NAMES)}, "
                     "'procedural', or a path to a .exr / .hdr file")


def _split(env: EnvMap, cfg: LightingConfig):
    """(lights, residual map at ENV_WORK_HEIGHT rows) of the (rotated) environment."""
    if not 0 <= cfg.lights <= MAX_LIGHTS:
        raise ValueError(f"lighting: lights must be in [0, {MAX_LIGHTS}], got {cfg.lights}")
    if cfg.rotation_deg:
        env = env.rotated(np.radians(cfg.rotation_deg))
    work = env.resized(min(ENV_WORK_HEIGHT, env.height))
    lights = dominant_lights(work, cfg.lights)
    rest = env_minus_lights(work, cfg.lights) if len(lights.dirs) else work
    return lights, rest


def ambient_residual(env: EnvMap, cfg: LightingConfig) -> EnvMap:
    """The map whose irradiance is the ambient term: ``env`` (rotated) at ENV_WORK_HEIGHT rows
    minus its ``cfg.lights`` dominant lights."""
    return _split(env, cfg)[1]


def _ambient_table(rest: EnvMap) -> np.ndarray:
    h = min(AMBIENT_TABLE_H, rest.height)
    return irradiance_table(rest, h, src_factor=max(1, rest.height // h))


def _probe_normals(n: int, seed: int = 0) -> np.ndarray:
    d = np.random.default_rng(seed).normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def scene_lighting(env: EnvMap, cfg: LightingConfig) -> tuple[Lighting, dict]:
    """Lighting (irradiance table of the environment minus its lights + the lights) and a
    JSON-able summary.  The SH9 projection of the residual is kept in the Lighting too (for
    comparison; the shaded mode uses the table)."""
    lights, rest = _split(env, cfg)
    sh = sh9_project(rest)
    table = _ambient_table(rest)
    # exposure: largest irradiance over many normals, ambient + unshadowed lights
    n = _probe_normals(EXPOSURE_PROBES)
    E = irradiance_lookup(table, n) + np.maximum(n @ lights.dirs.T, 0) @ lights.power
    e_max = float((E @ LUMA).max())
    exposure = cfg.key * np.pi / max(e_max, 1e-12)
    lt = Lighting(sh9=sh, irradiance=table, light_dirs=lights.dirs, light_colors=lights.power,
                  exposure=exposure, shininess=cfg.shininess, hair_shininess=cfg.hair_shininess,
                  shadows=cfg.shadows)
    info = {"env": env.name, "rotation_deg": cfg.rotation_deg, "exposure": exposure,
            "light_dirs": lights.dirs.tolist(), "light_power": lights.power.tolist(),
            "ambient": "irradiance_table", "ambient_table_shape": list(table.shape),
            "sh9_radiance": sh.tolist(), "shadows": cfg.shadows}
    return lt, info


def ambient_accuracy(env: EnvMap, cfg: LightingConfig, normals: int = 500, seed: int = 1) -> dict:
    """Error of the ambient term against the brute-force irradiance of the same residual map
    (``render.shading.sh.irradiance_brute``, every pixel of the ENV_WORK_HEIGHT residual) at
    ``normals`` random unit normals: relative error |E - E_ref| / E_ref per channel (mean, max)
    and error relative to the largest ambient irradiance (max over normals of E_ref luminance),
    for the old SH9 ambient and the irradiance table now used."""
    lights, rest = _split(env, cfg)
    n = _probe_normals(normals, seed)
    ref = irradiance_brute(rest, n)
    peak = float((ref @ LUMA).max())
    out = {"env": env.name, "lights": int(len(lights.dirs)), "normals": int(normals)}
    for name, E in (("sh9", np.maximum(sh9_irradiance(sh9_project(rest), n), 0.0)),
                    ("table", irradiance_lookup(_ambient_table(rest), n))):
        rel = np.abs(E - ref) / np.maximum(ref, 1e-12)
        out[name] = {"mean_rel": float(rel.mean()), "max_rel": float(rel.max()),
                     "max_of_peak": float(np.abs(E - ref).max() / peak)}
    return out


def background(env: EnvMap, camera: Camera, exposure: float, rotation_deg: float = 0.0) -> np.ndarray:
    """(H, W, 3) float32 linear environment radiance seen through every pixel, times exposure."""
    rays = camera.pixel_rays(camera.pixel_grid())
    d = rays @ camera.world_from_cam[:3, :3].T
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    if rotation_deg:
        env = env.rotated(np.radians(rotation_deg))
    return (env.sample(d) * exposure).astype(np.float32)

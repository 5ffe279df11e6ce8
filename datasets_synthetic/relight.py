"""Relighting ground truth (issue 15 item 4): a synthetic capture rendered again under another map.

Same scene, same cameras (the true ones the images were rendered with), same film filter, same exposure (the
capture's, so a brighter map gives brighter, possibly clipped, pixels, as a real camera with
fixed settings would), same hair model and shadows; only the environment changes (its dominant
lights, its ambient irradiance, the median-cut lights of the hair shading, and the background
when the capture shows the environment).

On disk, beside the capture (``write_capture(..., extra_files=relit_files(...))``)::

    relit/<map>/transforms.json   the capture's frames (same names, cameras and intrinsics as the
                                  top-level transforms.json), colour from images/ below, depth
                                  from the capture's ../../depth/ (a scan set furrow reads as is)
    relit/<map>/images/<name>.png the 8-bit sRGB colour of every view under <map>
    relit/<map>/lighting.json     the map, its rotation, the exposure (the capture's), its lights,
                                  and the fraction of foreground pixels clipped at white

``<map>`` is the bundled name (studio, courtyard, forest, sunset, procedural) or a file's stem.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

from capture.io import depth_format_spec
from capture.scan import to_uint8_srgb
from datasets_synthetic.lighting import ambient_residual, background, resolve_env, scene_lighting
from datasets_synthetic.pixel_filter import path_tracer_filter
from datasets_synthetic.synth_renderer import SceneRenderer

#: Linear radiance at or above this (after exposure) is white in 8-bit sRGB (counted as clipped).
CLIP_LEVEL = 1.0


def map_label(env: str) -> str:
    """Folder name of a map: the bundled name, or the stem of a file path."""
    p = Path(env)
    return p.stem if p.suffix else env


def relight_images(cap, cfg, env: str, ctx=None, progress: Callable | None = None) -> tuple[list[np.ndarray], dict]:
    """(per view (H, W, 3) float32 linear colour, lighting info) of capture ``cap`` (made from
    SynthConfig ``cfg``) rendered under ``env`` with the capture's exposure."""
    from render.gl import gl_context

    if ctx is None:
        with gl_context() as own:
            return relight_images(cap, cfg, env, own, progress)
    lc = replace(cfg.lighting, env=env)
    emap = resolve_env(env)
    lighting, info = scene_lighting(emap, lc)
    exposure = float(cap.info["lighting"]["exposure"])
    lighting = replace(lighting, exposure=exposure)
    info["exposure"] = exposure
    images = []
    cams = list(cap.true_cameras)
    with SceneRenderer(ctx, cfg.renderer, cfg.supersample, cap.scene.mesh, lighting, ambient_residual(emap, lc),
                       lc) as rend:
        for cam in (progress(cams, f"relighting under {map_label(env)}") if progress else cams):
            res = rend.render(cam)
            rgb = res.color
            if cfg.background == "env":
                rgb = rgb + (1.0 - res.alpha[..., None]) * background(emap, cam, exposure, lc.rotation_deg)
            images.append(np.clip(path_tracer_filter(rgb, cfg.pixel_filter_px), 0, None).astype(np.float32))
    fg = np.concatenate([im[d > 0] for im, d in zip(images, cap.clean_depth)]) if images else np.zeros((0, 3))
    info["clipped_fraction"] = float(np.mean(np.any(fg >= CLIP_LEVEL, axis=1))) if len(fg) else 0.0
    info["hair"] = rend.hair_info
    return images, info


def relit_files(cap, images: list[np.ndarray], info: dict, env: str, depth_format: str = "png",
                png_depth_unit: float | None = None) -> dict[str, bytes]:
    """The ``relit/<map>/`` files (module docstring) as relative path -> bytes, for
    ``write_capture(extra_files=...)``; ``depth_format`` / ``png_depth_unit`` as given to it."""
    import cv2

    label = map_label(env)
    ext, unit = depth_format_spec(depth_format, *(() if png_depth_unit is None else (png_depth_unit,)))
    base = f"relit/{label}"
    files, frames = {}, []
    for i, (s, im) in enumerate(zip(cap.scanset.scans, images)):
        stem = Path(s.name).stem if s.name else f"frame_{i:04d}"
        ok, buf = cv2.imencode(".png", np.ascontiguousarray(to_uint8_srgb(im)[..., ::-1]))
        if not ok:
            raise RuntimeError(f"could not encode {base}/images/{stem}.png")
        files[f"{base}/images/{stem}.png"] = buf.tobytes()
        frames.append({"file_path": f"images/{stem}.png", "depth_file_path": f"../../depth/{stem}.{ext}",
                       **s.camera.to_nerfstudio()})
    meta = {"camera_model": "PINHOLE", "depth_unit_scale_factor": unit, "frames": frames,
            "furrow": {"bounds": np.asarray(cap.scanset.bounds).tolist(),
                       "metadata": {"relit": label, "capture_env": cap.info["lighting"]["env"]}}}
    files[f"{base}/transforms.json"] = json.dumps(meta, indent=1).encode()
    files[f"{base}/lighting.json"] = json.dumps(info, indent=1, default=float).encode()
    return files

"""Path-traced renders -> furrow scan sets on disk (``capture.io.write_transforms``) with ``gt/``.

A :class:`Layout` says how the rendered views become a capture: which views show the room (the
others: the object over black with the object's depth only, as the evaluation's held-out views),
the exposure (``key``, the rule of ``datasets_synthetic.lighting``), per-view auto exposure on the
kept views (``datasets_synthetic.camera_traits``: gt/exposure.json) and perturbed recorded poses
(``datasets_synthetic.noise.perturb_pose`` with ``furrow synth``'s seeds: gt/cameras_true.json).
Every frame carries ``mask_path``: the true coverage matte (``film.render_view``'s alpha).

On disk, as ``furrow synth`` writes it: transforms.json, images/, depth/ (16-bit millimetres,
z-depth), masks/, gt/scene.json (the render spec, the layout, per-view room turns, the map with its
convention, timings), gt/mesh.ply (the curves as 3-sided tubes, the spheres), gt/cameras_true.json
(perturbed poses only), gt/exposure.json (auto exposure only), maps/<map>.exr (the map that lit the
capture, furrow's layout) and, for relighting truth, relit/<map>/ (``datasets_synthetic.relight``).
"""

from __future__ import annotations

import json
import os
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from capture.camera import Camera
from capture.io import auto_bounds, write_transforms
from capture.scan import Scan, ScanSet, select_indices
from datasets_synthetic.pathtraced.objects import Curves, PathObject, TriangleMesh
from datasets_synthetic.pathtraced.render import RenderSpec, ViewRender

#: Margin around the object's tight bounds for the scan set's bounds (fraction of the diagonal).
BOUNDS_MARGIN = 0.05
#: Exposure key of the captures (``datasets_synthetic.lighting.LightingConfig.key``).
DEFAULT_KEY = 1.1
#: Sides of the tubes of gt/mesh.ply.
MESH_SIDES = 3
#: RNG stream of the pose noise (``datasets_synthetic.synth``'s).
POSE_STREAM = 3
#: What the capture's map convention line says (gt/scene.json, transforms.json metadata).
ENV_NOTE = ("the map is in furrow's layout (render.shading.envmap: u = 0.5 faces +x, u = 0.25 faces +y, top row "
            "+z); Mitsuba's envmap was given the to_world that shows it so (datasets_synthetic.pathtraced.scene."
            "env_to_world): read it with --env-convention furrow (the default), not mitsuba")


@dataclass(frozen=True)
class Layout:
    """How rendered views become one capture (module docstring)."""

    room_frames: str | None = None
    """Views (slice spec, e.g. '0::2') that show the room and the support; the others are over black.
    None = no view shows the room (a black capture); 'all' = every view."""
    key: float = DEFAULT_KEY
    """Exposure: a white Lambertian surface under the map's largest irradiance reaches this."""
    auto_exposure: tuple[float, float] | None = None
    """(sigma EV, white-balance sigma) of the kept views' per-view jitter (None = fixed exposure)."""
    exposure_holdout: int = 2
    """Auto exposure jitters the views i % exposure_holdout == 0 (the ones `--holdout` keeps)."""
    exposure_jump: tuple[float, int] | None = None
    """(EV, count): the exposure jumps by EV in ``count`` of the kept views, the others at 1
    (camera_traits.exposure_jump_gains; instead of ``auto_exposure``)."""
    pose_noise: tuple[float, float] | None = None
    """(RMS degrees, RMS fraction of the object's diagonal) of the recorded poses' error (None = exact)."""
    background_shade: tuple[float, int] | None = None
    """(gain, count): in ``count`` of the kept room views the room behind the object is shaded to ``gain`` of
    its radiance (a cloud over the sunlit wall: the background changes between frames; :func:`shaded_room`),
    the object as rendered; gt/background_shade.json lists the views."""
    shade_side: str = "all"
    """Where the shade falls (background_shade): "all" the whole ellipse; "left" its half left of the object's
    centre (a shadow across one side behind the object), with the same soft edge."""

    def room_views(self, n: int) -> set[int]:
        if self.room_frames is None:
            return set()
        return set(range(n)) if self.room_frames == "all" else set(select_indices(self.room_frames, n))

    def record(self) -> dict:
        return asdict(self)


def recorded_cameras(cams: list[Camera], obj: PathObject, seed: int, pose_noise) -> list[Camera]:
    """The poses written to transforms.json: exact, or perturbed as ``furrow synth`` perturbs them."""
    if pose_noise is None:
        return list(cams)
    from datasets_synthetic.noise import perturb_pose

    b = obj.bounds
    diag = float(np.linalg.norm(b[1] - b[0]))
    return [perturb_pose(c, np.random.default_rng([int(seed), i, POSE_STREAM]), pose_noise[0], pose_noise[1] * diag)
            for i, c in enumerate(cams)]


def _camera_gains(n: int, cams: list[Camera], seed: int, layout: Layout) -> tuple[np.ndarray, dict]:
    """((n, 3) the camera's gain per view, {gt/exposure.json: its record} or {}): the layout's auto exposure or its
    exposure jump (datasets_synthetic.camera_traits), else 1 everywhere."""
    from datasets_synthetic.camera_traits import EXPOSURE_FILE, exposure_gains, exposure_jump_gains, exposure_record

    if layout.auto_exposure is not None:
        sig, wb = layout.auto_exposure
        gains = exposure_gains(n, sig, wb, seed, layout.exposure_holdout)
    elif layout.exposure_jump is not None:
        sig, wb = 0.0, 0.0
        gains = exposure_jump_gains(n, *layout.exposure_jump, seed, layout.exposure_holdout)
    else:
        return np.ones((n, 3)), {}
    names = [f"{c.name}.png" for c in cams]
    return gains, {EXPOSURE_FILE: exposure_record(names, gains, sig, wb, layout.exposure_holdout)}


def build_scanset(renders: list[ViewRender], cams: list[Camera], obj: PathObject, spec: RenderSpec,
                  layout: Layout, exposure: float, meta: dict) -> tuple[ScanSet, dict]:
    """(scan set, extra gt files) of the renders under ``layout`` (module docstring)."""
    n = len(renders)
    shown = layout.room_views(n)
    gains, extra = _camera_gains(n, cams, spec.seed, layout)
    rec = recorded_cameras(cams, obj, spec.seed, layout.pose_noise)
    scans = []
    shaded = shade_views(n, shown, spec.seed, layout)
    if shaded:
        extra["gt/background_shade.json"] = json.dumps({"gain": layout.background_shade[0], "views": shaded,
                                                        "names": [f"{cams[i].name}.png" for i in shaded]}).encode()
    for i, (v, cam) in enumerate(zip(renders, rec, strict=True)):
        room = i in shown
        colour = shaded_room(v, layout.background_shade[0], layout.shade_side) if i in shaded else \
            v.room if room else v.black
        rgb = colour * np.float32(exposure) * gains[i].astype(np.float32)
        depth = v.depth_room if room else v.depth_object
        scans.append(Scan(np.clip(rgb, 0, None).astype(np.float32), depth, cam, f"{cam.name}.png", v.alpha))
    if spec.support != "none" and shown:
        bounds = auto_bounds(scans)  # a real capture has no bounds: derived from the depth, support included
    else:
        b = obj.bounds
        diag = float(np.linalg.norm(b[1] - b[0]))
        bounds = np.stack([b[0] - BOUNDS_MARGIN * diag, b[1] + BOUNDS_MARGIN * diag])
    if layout.pose_noise is not None:
        extra["gt/cameras_true.json"] = cameras_json(cams)
    return ScanSet(tuple(scans), bounds, meta), extra


#: RNG stream of the shaded views (Layout.background_shade).
SHADE_STREAM = 7
#: The shaded region: an ellipse around the object's box (alpha > SHADE_ALPHA) with semi-axes this multiple
#: of the box's half sides, its edge falling off over SHADE_SOFT of the ellipse's radius.
SHADE_ALPHA, SHADE_GROW, SHADE_SOFT = 0.01, 1.6, 0.3


def shade_views(n: int, shown: set, seed: int, layout: Layout) -> list[int]:
    """The room views whose background is shaded (Layout.background_shade; chosen by ``seed``), sorted."""
    if layout.background_shade is None:
        return []
    kept = sorted(shown)
    count = int(layout.background_shade[1])
    if not 0 <= count <= len(kept):
        raise ValueError(f"background shade: count must be 0..{len(kept)} (the room views), got {count}")
    rng = np.random.default_rng([int(seed), SHADE_STREAM])
    return sorted(int(i) for i in rng.choice(kept, count, replace=False))


def shaded_room(v: ViewRender, gain: float, side: str = "all") -> np.ndarray:
    """(H, W, 3) the view's room colour with the room behind the object shaded to ``gain`` inside a soft
    ellipse around the object (``side`` "left": its half left of the object's centre; Layout.shade_side),
    the object's own light as rendered: black + k (room - black), where room - black = (1 - alpha) B is
    the room seen through and around the object."""
    a = np.asarray(v.alpha)
    y, x = np.nonzero(a > SHADE_ALPHA)
    if not len(y):
        return v.room
    cy, cx = (y.min() + y.max()) / 2, (x.min() + x.max()) / 2
    ry, rx = SHADE_GROW * max(1.0, (y.max() - y.min()) / 2), SHADE_GROW * max(1.0, (x.max() - x.min()) / 2)
    yy, xx = np.mgrid[:a.shape[0], :a.shape[1]]
    rho = np.sqrt(((yy - cy) / ry) ** 2 + ((xx - cx) / rx) ** 2)
    t = np.clip((rho - (1 - SHADE_SOFT)) / SHADE_SOFT, 0, 1)
    if side == "left":  # the edge at the centre line as soft as the ellipse's
        t = np.maximum(t, np.clip((xx - cx) / (SHADE_SOFT * rx) + 0.5, 0, 1))
    elif side != "all":
        raise ValueError(f"shade side must be 'all' or 'left', got {side!r}")
    k = (gain + (1 - gain) * t * t * (3 - 2 * t)).astype(np.float32)[..., None]  # smoothstep to 1 outside
    return v.black + k * (v.room - v.black)


def cameras_json(cams: list[Camera]) -> bytes:
    """gt/cameras_true.json (``datasets_synthetic.synth``'s format)."""
    frames = [{"name": c.name, **c.to_nerfstudio()} for c in cams]
    return json.dumps({"convention": "nerfstudio transform_matrix (camera-to-world, OpenGL axes), "
                       "cx/cy with pixel centres at i + 0.5", "frames": frames}, indent=1).encode()


def gt_mesh_bytes(obj: PathObject) -> bytes:
    """gt/mesh.ply: every curve as a 3-sided tube along its (evaluated) centre line, spheres as UV spheres, triangle
    meshes as they are."""
    from datasets_synthetic.geometry import ellipsoid, merge, ply_bytes, transformed, tube_sweep
    from render.mesh.raster.gl import RasterMesh

    meshes = []
    for p in obj.parts:
        if isinstance(p, TriangleMesh):
            meshes.append(RasterMesh(p.vertices, p.faces, np.full((len(p.vertices), 3), 0.5)))
            continue
        if not isinstance(p, Curves):
            meshes.append(transformed(ellipsoid([p.radius] * 3, 24, 48, (0.5, 0.5, 0.5)), np.eye(3), p.centre))
            continue
        albedo = obj.materials[p.material].get("reflectance", {}).get("value", (0.35, 0.22, 0.12))
        groups: dict[int, list] = {}
        for pts, rad in p.polylines():
            groups.setdefault(len(pts), []).append((pts, rad))
        for lines in groups.values():
            paths = np.stack([q for q, _ in lines])
            meshes.append(tube_sweep(paths, np.stack([r for _, r in lines]), MESH_SIDES,
                                     np.broadcast_to(np.asarray(albedo, float), (len(lines), 3)).copy()))
    return ply_bytes(merge(meshes))


def partiality(renders: list[ViewRender], views: list[int] | None = None, room_frames: set | None = None) -> dict:
    """Partiality of the true mattes as written (8-bit): the fraction of object pixels (alpha > 0) with
    alpha < 1; the alpha MSE of the binary mask alpha > 0.5 over the object pixels; the MSE of the
    binary depth mask (depth > 0, the object's depth) over object-or-depth pixels; and the object's
    share of the frame."""
    idx = range(len(renders)) if views is None else views
    part, mse_a, mse_d, frac = [], [], [], []
    for i in idx:
        v = renders[i]
        a = np.round(np.clip(v.alpha, 0, 1) * 255) / 255
        obj = a > 0
        if not obj.any():
            continue
        d = v.depth_object > 0
        part.append(float(np.mean(a[obj] < 1)))
        mse_a.append(float(np.mean(((a > 0.5) - a)[obj] ** 2)))
        mse_d.append(float(np.mean((d - a)[obj | d] ** 2)))
        frac.append(float(obj.mean()))
    return {"partial_fraction": float(np.mean(part)), "binary_alpha_mse": float(np.mean(mse_a)),
            "depth_mask_alpha_mse": float(np.mean(mse_d)), "object_frame_fraction": float(np.mean(frac))}


def write_case(out: Path, scanset: ScanSet, extra: dict, spec: RenderSpec, files: dict | None = None) -> Path:
    """Write the capture (atomic; an existing folder is replaced); returns transforms.json's path."""
    extra = {**extra, **(files or {})}
    return write_transforms(scanset, Path(out), depth_format="png", overwrite=True, extra_files=extra,
                            lens=spec.lens)


def write_alias(src: Path, out: Path, cams: list[Camera], files: dict[str, bytes]) -> Path:
    """A capture folder ``out`` whose transforms.json reuses ``src``'s images, depth and masks (paths
    relative to ``out``) with the poses of ``cams`` (same order); ``files`` go beside it (gt/...)."""
    from capture.atomic import atomic_dir

    src, out = Path(src), Path(out)
    meta = json.loads((src / "transforms.json").read_text())
    rel = os.path.relpath(src.resolve(), out.resolve())
    frames = []
    for fr, cam in zip(meta["frames"], cams, strict=True):
        fr = dict(fr)
        for k in ("file_path", "depth_file_path", "mask_path"):
            if k in fr:
                fr[k] = f"{rel}/{fr[k]}"
        fr.update(cam.to_nerfstudio())
        frames.append(fr)
    meta["frames"] = frames
    meta.setdefault("furrow", {}).setdefault("metadata", {})["images_from"] = str(src.name)
    with atomic_dir(out) as tmp:
        (tmp / "transforms.json").write_text(json.dumps(meta, indent=1))
        for relp, data in files.items():
            (tmp / relp).parent.mkdir(parents=True, exist_ok=True)
            (tmp / relp).write_bytes(data)
    return out / "transforms.json"


def exr_bytes(data: np.ndarray) -> bytes:
    """An RGB float EXR file's bytes (``capture.imageio.write_exr`` through a temporary file)."""
    import tempfile

    from capture.imageio import write_exr

    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "map.exr"
        write_exr(p, np.asarray(data, np.float32))
        return p.read_bytes()

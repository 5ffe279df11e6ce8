"""The Model bundle: signed distance pyramid, RGBz images, occluder spheres and mesh.

This is the one data model passed from ``volume`` to ``render`` (docs/methods.md §1.1, §1.4, §3).
Every type is a frozen dataclass validated on construction; arrays are made read-only.

On disk a model is a folder::

    MODEL/
      model.json     schema name + version, units, bounds, cameras (nerfstudio convention,
                     see Camera.to_nerfstudio), levels, spheres / mesh counts,
                     every parameter used, input provenance
      pyramid.npz    level_<L>_surface (N,3) int32, level_<L>_values (L,L,L) float32 (optional;
                     float16 above VALUES_FULL_MAX_RES), compressed
      rgbz.npz       compact (version 2, volume.rgbz_store): per view a crop around the object,
                     8-bit sRGB, 16-bit depth over the view's range, 8-bit alpha, bool
                     measured (where the depth is the capture's, not the fill; optional),
                     compressed, read view by view; or dense (version 1): rgb (N,H,W,3) float16
                     linear, depth (N,H,W) float16 metres (float32 read too), alpha (N,H,W)
                     float16, measured (N,H,W) bool (optional)
      spheres.npz    centers (N,3) float64, radii (N,) float64
      mesh.npz       vertices (V,3) float32, faces (F,3) int32, colors (V,3) float32 (optional)
      capture_env.npz  radiance (H,2H,3) float32 linear: the capture's lighting (optional; only
                     a model with it can be relit, issue 15; model.json "capture_env" says how
                     the map sits in the world)

:func:`save_model` writes into a temporary folder beside the target and renames it into
place, so an interrupted run never leaves a half model; :func:`load_model` checks the schema
and version and fails with an error naming the folder and file.
"""

from __future__ import annotations

import json
import os
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from capture.atomic import atomic_dir
from capture.camera import Camera
from capture.sampling import voxel_centres
from volume.rgbz_store import RGBZ_STORAGE, CropFile, ModelError, RgbzImages, is_compact, save_crops

__all__ = ["RGBZ_STORAGE", "ModelError", "RgbzImages", "SdfLevel", "SdfPyramid", "SphereSet", "CaptureLighting",
           "Model", "save_model", "load_model"]

#: Schema name written into model.json.
SCHEMA = "furrow.model"
#: Version of the on-disk layout written when the RGBz images are compact crops (issue 24).
SCHEMA_VERSION = 2
#: Versions load_model reads: 1 (dense float16 rgbz.npz, still written for dense RGBz) and 2.
READ_VERSIONS = (1, 2)
#: Relative tolerance when checking that all levels of a pyramid span the same cube.
EXTENT_RTOL = 1e-6
#: Levels up to this resolution keep their signed distances as float32 in pyramid.npz; finer ones
#: are stored as float16 (read back as float32: within 2^-11 of the distance, under 0.25 mm for a
#: cube under 1 m, finer near the surface; 32 MB instead of 64 MB at 256^3 before compression).
#: Nothing reads the fine levels' values at full precision (relighting reads <= 32^3).
VALUES_FULL_MAX_RES = 64
#: The array files of a model folder.
ARRAY_FILES = ("pyramid.npz", "rgbz.npz", "spheres.npz", "mesh.npz")
#: The optional file holding the capture lighting (CaptureLighting); models written before it
#: existed lack it and load with ``capture_env=None``.
CAPTURE_ENV_FILE = "capture_env.npz"
#: Tolerance on |up| = 1 of a CaptureLighting.
UP_NORM_TOL = 1e-6


def _ro(a: np.ndarray) -> np.ndarray:
    a = np.array(a, copy=True)
    a.setflags(write=False)
    return a


def _is_pow2(n: int) -> bool:
    return n >= 1 and (n & (n - 1)) == 0


# ---------------------------------------------------------------------------- types
@dataclass(frozen=True)
class SdfLevel:
    """One level of the signed distance pyramid: a cube of L^3 voxels (docs/methods.md §1.1).

    Attributes:
        resolution: L, voxels per side (a power of two inside a pyramid).
        origin: (3,) float64 world position (metres) of the cube's minimum corner.
        voxel_size: w, voxel edge length in metres; the cube spans origin + [0, L*w]^3.
        surface: (N, 3) int32 voxel indices (i, j, k) in x, y, z order of the surface
            voxels, |signed distance| <= half a voxel diagonal (docs/methods.md §1.1 step 2).
        values: (L, L, L) float32 signed distance in metres at voxel centres, indexed
            [i, j, k] (x, y, z), positive outside; or None when not kept.
    """

    resolution: int
    origin: np.ndarray
    voxel_size: float
    surface: np.ndarray
    values: np.ndarray | None = None

    def __post_init__(self) -> None:
        L = int(self.resolution)
        if L < 1:
            raise ModelError(f"SdfLevel: resolution must be >= 1, got {self.resolution}")
        origin = np.asarray(self.origin, dtype=np.float64)
        if origin.shape != (3,) or not np.all(np.isfinite(origin)):
            raise ModelError(f"SdfLevel {L}: origin must be a finite (3,) vector, got {origin!r}")
        w = float(self.voxel_size)
        if not (np.isfinite(w) and w > 0):
            raise ModelError(f"SdfLevel {L}: voxel_size must be finite and > 0, got {w}")
        surf = np.asarray(self.surface)
        if surf.size == 0:
            surf = np.zeros((0, 3), np.int32)
        if surf.ndim != 2 or surf.shape[1] != 3 or not np.issubdtype(surf.dtype, np.integer):
            raise ModelError(f"SdfLevel {L}: surface must be an (N, 3) integer array, got {surf.shape} {surf.dtype}")
        if len(surf) and (surf.min() < 0 or surf.max() >= L):
            raise ModelError(f"SdfLevel {L}: surface voxel index outside [0, {L})")
        values = self.values
        if values is not None:
            values = np.asarray(values)
            if values.shape != (L, L, L) or values.dtype != np.float32:
                raise ModelError(f"SdfLevel {L}: values must be ({L},{L},{L}) float32, "
                                 f"got {values.shape} {values.dtype}")
            if not np.all(np.isfinite(values)):
                raise ModelError(f"SdfLevel {L}: values contain NaN or inf")
            values = _ro(values)
        object.__setattr__(self, "resolution", L)
        object.__setattr__(self, "origin", _ro(origin))
        object.__setattr__(self, "voxel_size", w)
        object.__setattr__(self, "surface", _ro(surf.astype(np.int32)))
        object.__setattr__(self, "values", values)

    def centers(self) -> np.ndarray:
        """(N, 3) float64 world centres (metres) of the surface voxels: origin + (ijk + 0.5) w."""
        return voxel_centres(self.surface, self.origin, self.voxel_size)

    @property
    def extent(self) -> float:
        """Side of the cube in metres (L * w)."""
        return self.resolution * self.voxel_size


@dataclass(frozen=True)
class SdfPyramid:
    """Signed distance levels, coarse -> fine, every power of two up to ``l_opt`` (docs/methods.md §1.1, §1.7).

    Attributes:
        levels: SdfLevel tuple, strictly increasing power-of-two resolutions, all spanning
            the same cube (same origin and L*w); the finest has resolution ``l_opt``.
        l_opt: the resolution chosen by Eq. 1.
    """

    levels: tuple[SdfLevel, ...]
    l_opt: int

    def __post_init__(self) -> None:
        levels = tuple(self.levels)
        if not levels:
            raise ModelError("SdfPyramid: needs at least one level")
        res = [lv.resolution for lv in levels]
        if any(not _is_pow2(r) for r in res):
            raise ModelError(f"SdfPyramid: resolutions must be powers of two, got {res}")
        if any(b <= a for a, b in zip(res, res[1:])):
            raise ModelError(f"SdfPyramid: resolutions must increase coarse -> fine, got {res}")
        if int(self.l_opt) != res[-1]:
            raise ModelError(f"SdfPyramid: finest level {res[-1]} must equal l_opt {self.l_opt}")
        o, e = levels[0].origin, levels[0].extent
        for lv in levels[1:]:
            if not np.allclose(lv.origin, o, rtol=0, atol=EXTENT_RTOL * e) or abs(lv.extent - e) > EXTENT_RTOL * e:
                raise ModelError(f"SdfPyramid: level {lv.resolution} spans a different cube than level {res[0]}")
        object.__setattr__(self, "levels", levels)
        object.__setattr__(self, "l_opt", int(self.l_opt))

    @property
    def resolutions(self) -> list[int]:
        return [lv.resolution for lv in self.levels]

    def level(self, resolution: int) -> SdfLevel:
        for lv in self.levels:
            if lv.resolution == resolution:
                return lv
        raise KeyError(f"no level with resolution {resolution} (have {self.resolutions})")


@dataclass(frozen=True)
class SphereSet:
    """Occluder approximation by spheres (docs/methods.md §3).

    Attributes:
        centers: (N, 3) float64 world centres in metres.
        radii: (N,) float64 radii in metres, > 0.
    """

    centers: np.ndarray
    radii: np.ndarray

    def __post_init__(self) -> None:
        c = np.asarray(self.centers, dtype=np.float64).reshape(-1, 3) if np.size(self.centers) == 0 else \
            np.asarray(self.centers, dtype=np.float64)
        r = np.asarray(self.radii, dtype=np.float64).reshape(-1)
        if c.ndim != 2 or c.shape[1] != 3:
            raise ModelError(f"SphereSet: centers must be (N, 3), got {c.shape}")
        if r.shape != (len(c),):
            raise ModelError(f"SphereSet: radii must be ({len(c)},), got {r.shape}")
        if not (np.all(np.isfinite(c)) and np.all(np.isfinite(r))) or np.any(r <= 0):
            raise ModelError("SphereSet: centers and radii must be finite, radii > 0")
        object.__setattr__(self, "centers", _ro(c))
        object.__setattr__(self, "radii", _ro(r))

    def __len__(self) -> int:
        return len(self.radii)


@dataclass(frozen=True)
class CaptureLighting:
    """The environment the capture was lit by (issue 15): what relighting divides out.

    Attributes:
        radiance: (H, 2H, 3) float32 linear HDR radiance (>= 0, finite), equirectangular in the
            convention of ``render.shading.envmap`` (the map's own +z up).
        up: (3,) unit world direction of the map's +z (the rig's up, ``capture.orbit.estimate_up``).
        rotation_deg: turn of the map about its up axis in degrees (as ``EnvMap.rotated``).
        source: where it came from (a file, a bundled name, a fisheye or mirror-ball photo).
    """

    radiance: np.ndarray
    up: np.ndarray
    rotation_deg: float = 0.0
    source: str = ""

    def __post_init__(self) -> None:
        r = np.asarray(self.radiance)
        if r.ndim != 3 or r.shape[2] != 3 or r.shape[1] != 2 * r.shape[0] or r.shape[0] < 1 or r.dtype != np.float32:
            raise ModelError(f"CaptureLighting: radiance must be (H, 2H, 3) float32, got {r.shape} {r.dtype}")
        if not np.all(np.isfinite(r)) or r.min() < 0:
            raise ModelError("CaptureLighting: radiance must be finite and >= 0")
        if not r.max() > 0:
            raise ModelError("CaptureLighting: radiance is black (nothing lit the capture)")
        up = np.asarray(self.up, np.float64)
        if up.shape != (3,) or not np.all(np.isfinite(up)) or abs(np.linalg.norm(up) - 1) > UP_NORM_TOL:
            raise ModelError(f"CaptureLighting: up must be a unit (3,) vector, got {up!r}")
        if not np.isfinite(float(self.rotation_deg)):
            raise ModelError(f"CaptureLighting: rotation_deg must be finite, got {self.rotation_deg}")
        object.__setattr__(self, "radiance", _ro(r))
        object.__setattr__(self, "up", _ro(up))
        object.__setattr__(self, "rotation_deg", float(self.rotation_deg))
        object.__setattr__(self, "source", str(self.source))

    def record(self) -> dict:
        """The model.json entry (the radiance itself goes to CAPTURE_ENV_FILE)."""
        return {"file": CAPTURE_ENV_FILE, "shape": list(self.radiance.shape), "up": self.up.tolist(),
                "rotation_deg": self.rotation_deg, "source": self.source}


@dataclass(frozen=True)
class Model:
    """Everything the renderers need, built by ``furrow model``.

    Attributes:
        pyramid: signed distance levels and their surface voxels (docs/methods.md §1.1).
        rgbz: RGBz images, one per input camera (docs/methods.md §1.4).
        spheres: occluder sphere set (docs/methods.md §3).
        mesh_vertices: (V, 3) float32 world positions (metres) of the baseline mesh.
        mesh_faces: (F, 3) int32 vertex indices, counter-clockwise seen from outside.
        mesh_colors: (V, 3) float32 linear vertex colours, or None.
        bounds: (2, 3) float64 [min, max] object box in metres (world).
        params: every parameter used to build the model (JSON-serialisable).
        provenance: input description (source path, frames, generator, ...; JSON-serialisable).
        capture_env: the capture's lighting (:class:`CaptureLighting`), or None: such a model
            cannot be relit.
    """

    pyramid: SdfPyramid
    rgbz: RgbzImages
    spheres: SphereSet
    mesh_vertices: np.ndarray
    mesh_faces: np.ndarray
    mesh_colors: np.ndarray | None
    bounds: np.ndarray
    params: dict = field(default_factory=dict)
    provenance: dict = field(default_factory=dict)
    capture_env: CaptureLighting | None = None

    def __post_init__(self) -> None:
        if self.capture_env is not None and not isinstance(self.capture_env, CaptureLighting):
            raise ModelError("Model: capture_env must be a CaptureLighting or None")
        if not isinstance(self.pyramid, SdfPyramid):
            raise ModelError("Model: pyramid must be an SdfPyramid")
        if not isinstance(self.rgbz, RgbzImages):
            raise ModelError("Model: rgbz must be RgbzImages")
        if not isinstance(self.spheres, SphereSet):
            raise ModelError("Model: spheres must be a SphereSet")
        v = np.asarray(self.mesh_vertices, dtype=np.float32).reshape(-1, 3) if np.size(self.mesh_vertices) == 0 \
            else np.asarray(self.mesh_vertices)
        f = np.asarray(self.mesh_faces).reshape(-1, 3) if np.size(self.mesh_faces) == 0 else np.asarray(self.mesh_faces)
        if v.ndim != 2 or v.shape[1] != 3 or v.dtype != np.float32 or not np.all(np.isfinite(v)):
            raise ModelError(f"Model: mesh_vertices must be finite (V, 3) float32, got {v.shape} {v.dtype}")
        if f.ndim != 2 or f.shape[1] != 3 or not np.issubdtype(f.dtype, np.integer):
            raise ModelError(f"Model: mesh_faces must be (F, 3) integers, got {f.shape} {f.dtype}")
        if len(f) and (f.min() < 0 or f.max() >= len(v)):
            raise ModelError("Model: mesh_faces index a vertex that does not exist")
        c = self.mesh_colors
        if c is not None:
            c = np.asarray(c)
            if c.shape != v.shape or c.dtype != np.float32 or not np.all(np.isfinite(c)):
                raise ModelError(f"Model: mesh_colors must be finite ({len(v)}, 3) float32 or None, "
                                 f"got {c.shape} {c.dtype}")
            c = _ro(c)
        b = np.asarray(self.bounds, dtype=np.float64)
        if b.shape != (2, 3) or not np.all(np.isfinite(b)) or np.any(b[1] <= b[0]):
            raise ModelError(f"Model: bounds must be a finite (2, 3) [min, max] box, got {b.tolist()}")
        for name in ("params", "provenance"):
            try:
                json.dumps(getattr(self, name))
            except (TypeError, ValueError) as e:
                raise ModelError(f"Model: {name} must be JSON-serialisable ({e})") from None
        object.__setattr__(self, "mesh_vertices", _ro(v))
        object.__setattr__(self, "mesh_faces", _ro(f.astype(np.int32)))
        object.__setattr__(self, "mesh_colors", c)
        object.__setattr__(self, "bounds", _ro(b))


# ---------------------------------------------------------------------------- disk
def _camera_json(cam: Camera) -> dict:
    return {"name": cam.name, **cam.to_nerfstudio()}


def save_model(model: Model, folder) -> Path:
    """Write ``model`` to ``folder`` (created or replaced) atomically; returns the folder.

    Everything is written into a temporary folder in the same parent and renamed into place
    (``capture.atomic.atomic_dir``), so an interrupted save leaves either the old folder or nothing.
    """
    if not isinstance(model, Model):
        raise ModelError("save_model: expected a Model")
    folder = Path(folder)
    if folder.exists() and not (folder / "model.json").exists() and any(folder.iterdir()):
        raise ModelError(f"{folder}: exists, is not empty and is not a furrow model; refusing to replace it")
    with atomic_dir(folder) as tmp:
        pyr = model.pyramid
        arrays = {}
        for lv in pyr.levels:
            arrays[f"level_{lv.resolution}_surface"] = lv.surface
            if lv.values is not None:
                half = lv.resolution > VALUES_FULL_MAX_RES
                arrays[f"level_{lv.resolution}_values"] = lv.values.astype(np.float16) if half else lv.values
        np.savez_compressed(tmp / "pyramid.npz", **arrays)
        if model.rgbz.crop_file is not None:  # crops streamed to a file while the model was built, or loaded
            shutil.copyfile(model.rgbz.crop_file, tmp / "rgbz.npz")
        elif model.rgbz.compact:
            save_crops(tmp / "rgbz.npz", (model.rgbz.encoded(n) for n in range(len(model.rgbz))),
                       model.rgbz.has_alpha)
        else:
            rgbz = {"rgb": model.rgbz.rgb, "depth": model.rgbz.depth}
            for k in ("alpha", "measured"):
                if getattr(model.rgbz, k) is not None:
                    rgbz[k] = getattr(model.rgbz, k)
            np.savez(tmp / "rgbz.npz", **rgbz)
        np.savez(tmp / "spheres.npz", centers=model.spheres.centers, radii=model.spheres.radii)
        mesh = {"vertices": model.mesh_vertices, "faces": model.mesh_faces}
        if model.mesh_colors is not None:
            mesh["colors"] = model.mesh_colors
        np.savez(tmp / "mesh.npz", **mesh)
        files = list(ARRAY_FILES)
        if model.capture_env is not None:
            np.savez(tmp / CAPTURE_ENV_FILE, radiance=model.capture_env.radiance)
            files.append(CAPTURE_ENV_FILE)
        meta = {
            "schema": SCHEMA,
            "version": SCHEMA_VERSION if model.rgbz.compact else 1,
            "units": {"length": "metres", "colour": "8-bit sRGB crops" if model.rgbz.compact else "linear float16",
                      "depth": "z-depth metres (16-bit over each view's range)" if model.rgbz.compact else
                      "z-depth metres (float16), 0 = none",
                      "sdf": "metres, positive outside", "camera_convention": "nerfstudio transform_matrix "
                      "(camera-to-world, OpenGL axes), pixel centres at i + 0.5"},
            "bounds": model.bounds.tolist(),
            "l_opt": pyr.l_opt,
            "levels": [{"resolution": lv.resolution, "origin": lv.origin.tolist(), "voxel_size": lv.voxel_size,
                        "surface_voxels": int(len(lv.surface)), "has_values": lv.values is not None}
                       for lv in pyr.levels],
            "cameras": [_camera_json(c) for c in model.rgbz.cameras],
            "spheres": len(model.spheres),
            "mesh": {"vertices": int(len(model.mesh_vertices)), "faces": int(len(model.mesh_faces)),
                     "colors": model.mesh_colors is not None},
            "params": model.params,
            "provenance": model.provenance,
            "files": files,
        }
        if model.capture_env is not None:
            meta["capture_env"] = model.capture_env.record()
        with open(tmp / "model.json", "w") as fh:
            json.dump(meta, fh, indent=1)
            fh.flush()
            os.fsync(fh.fileno())
    return folder


def _npz(folder: Path, name: str) -> dict:
    path = folder / name
    if not path.is_file():
        raise ModelError(f"{path}: missing model file")
    try:
        with np.load(path, allow_pickle=False) as z:
            return {k: z[k] for k in z.files}
    except Exception as e:  # corrupt / truncated zip
        raise ModelError(f"{path}: cannot read ({type(e).__name__}: {e})") from None


def _rgbz(path: Path, cams) -> RgbzImages:
    """The RGBz images of rgbz.npz: a compact file is opened for reading view by view."""
    if not path.is_file():
        raise ModelError(f"{path}: missing model file")
    try:
        compact = is_compact(path)
    except Exception as e:
        raise ModelError(f"{path}: cannot read ({type(e).__name__}: {e})") from None
    if compact:
        return RgbzImages.from_crops(cams, CropFile(path))
    rz = _npz(path.parent, path.name)
    return RgbzImages(rz["rgb"], rz["depth"], cams, rz.get("alpha"), measured=rz.get("measured"))


def load_model(folder) -> Model:
    """Read and validate a model folder written by :func:`save_model`.

    Raises ModelError naming the file on a missing folder or file, a wrong schema or
    version, or arrays that do not match model.json.
    """
    folder = Path(folder)
    mj = folder / "model.json"
    if not folder.is_dir():
        raise ModelError(f"{folder}: no such model folder")
    if not mj.is_file():
        raise ModelError(f"{mj}: missing (not a furrow model folder)")
    try:
        meta = json.loads(mj.read_text())
    except (OSError, ValueError) as e:
        raise ModelError(f"{mj}: not valid JSON ({e})") from None
    if not isinstance(meta, dict) or meta.get("schema") != SCHEMA:
        raise ModelError(f"{mj}: not a furrow model "
                         f"(schema {meta.get('schema') if isinstance(meta, dict) else None!r})")
    if meta.get("version") not in READ_VERSIONS:
        raise ModelError(f"{mj}: model version {meta.get('version')!r} is not supported (this furrow reads versions "
                         f"{', '.join(map(str, READ_VERSIONS))}); rebuild it with `furrow model`")
    try:
        cams = tuple(Camera.from_nerfstudio(c["transform_matrix"], c["fl_x"], c["fl_y"], c["cx"], c["cy"], c["w"],
                                            c["h"], c.get("name", "")) for c in meta["cameras"])
        pyr = _npz(folder, "pyramid.npz")
        levels = []
        for lvm in meta["levels"]:
            L = int(lvm["resolution"])
            key = f"level_{L}_surface"
            if key not in pyr:
                raise ModelError(f"{folder / 'pyramid.npz'}: missing array {key}")
            if len(pyr[key]) != lvm["surface_voxels"]:
                raise ModelError(f"{folder / 'pyramid.npz'}: {key} has {len(pyr[key])} voxels, model.json says "
                                 f"{lvm['surface_voxels']}")
            vals = pyr.get(f"level_{L}_values") if lvm.get("has_values") else None
            vals = vals.astype(np.float32) if vals is not None and vals.dtype == np.float16 else vals
            if lvm.get("has_values") and vals is None:
                raise ModelError(f"{folder / 'pyramid.npz'}: missing array level_{L}_values")
            levels.append(SdfLevel(L, np.array(lvm["origin"]), float(lvm["voxel_size"]), pyr[key], vals))
        pyramid = SdfPyramid(tuple(levels), int(meta["l_opt"]))
        rgbz = _rgbz(folder / "rgbz.npz", cams)
        sp = _npz(folder, "spheres.npz")
        me = _npz(folder, "mesh.npz")
        cap = meta.get("capture_env")
        capture_env = None
        if cap is not None:
            capture_env = CaptureLighting(_npz(folder, CAPTURE_ENV_FILE)["radiance"], np.array(cap["up"], np.float64),
                                          float(cap.get("rotation_deg", 0.0)), str(cap.get("source", "")))
        return Model(pyramid=pyramid, rgbz=rgbz,
                     spheres=SphereSet(sp["centers"], sp["radii"]), mesh_vertices=me["vertices"],
                     mesh_faces=me["faces"], mesh_colors=me.get("colors"), bounds=np.array(meta["bounds"]),
                     params=meta.get("params", {}), provenance=meta.get("provenance", {}),
                     capture_env=capture_env)
    except ModelError as e:
        if str(folder) in str(e):
            raise
        raise ModelError(f"{folder}: invalid model: {e}") from None
    except (KeyError, TypeError, ValueError) as e:
        raise ModelError(f"{folder}: invalid model ({type(e).__name__}: {e})") from None

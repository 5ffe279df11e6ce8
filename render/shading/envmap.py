"""Environment maps: linear HDR radiance on an equirectangular grid, and THE one
direction <-> pixel mapping of the whole project (docs/design.md "EnvMap"; docs/methods.md §2, §3).

Convention (world +z up, same as Blender's world equirect, so the bundled studio lights look
the way Blender shows them and the image is not mirrored when seen from inside the sphere):

* ``u in [0, 1)`` is azimuth, ``v in [0, 1]`` is the polar angle from +z:
  ``theta = pi * v`` (``v = 0``: straight up, +z; ``v = 1``: straight down, -z),
  ``phi = pi * (1 - 2 u)`` = the azimuth atan2(y, x) around +z, so ``u = 0.5`` looks along +x,
  ``u = 0.25`` along +y, ``u = 0.75`` along -y and ``u = 0 / 1`` along -x (u increases when turning
  clockwise seen from above, i.e. to the right for a viewer standing inside).
* ``dir = (sin theta cos phi, sin theta sin phi, cos theta)``.
* Pixel (row i, column j) of an ``(H, W=2H)`` map covers ``u in [j/W, (j+1)/W)``,
  ``v in [i/H, (i+1)/H)``; its centre is ``((j + 0.5)/W, (i + 0.5)/H)``. Row 0 is the top (+z).
  Continuous pixel coordinates are ``x = u W - 0.5``, ``y = v H - 0.5``.

**The stated orientation** (ORIENTATION, repeated in every ``--help`` that takes a map): the map's +z
is the rig's up (``capture.orbit.estimate_up``), and its other axes are the world's turned by the
smallest rotation taking +z to that up (``render.shading.transfer.world_to_env``; the world's own axes
when the rig is level, as in every synthetic capture).  So the middle column (u = 0.5) looks towards
the capture's +x, u = 0.25 towards +y, and row v at polar angle pi v from up.

Other layouts are read by a *change of axes* applied once when a map is loaded, never by a second
direction <-> pixel map (:data:`ENV_CONVENTIONS`, :func:`oriented`): ``furrow`` (above), ``blender``
(the same: Cycles' ``direction_to_equirectangular``, u = 0.5 - atan2(y, x) / 2 pi, v = 1 - acos(z) /
pi counted from the bottom of Blender's bottom-up images, world +z up) and ``mitsuba`` (Mitsuba 3's
``envmap`` emitter: dir = (sin 2 pi u sin pi v, cos pi v, -cos 2 pi u sin pi v), +y up, so u = 0.25 faces
+x; with the world's +y as the rig's up that is furrow's layout turned a quarter turn about up).

Radiance is linear float32 RGB (W m^-2 sr^-1 up to an arbitrary scale). Tiny negative values that
lossy EXR compression (DWAB) leaves are clamped to 0 on load.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from capture.imageio import read_exr_rgb, write_exr
from capture.sampling import cell_centres, from_texcoord, nearest_pixel, sample_image

#: Folder of the bundled CC0 environment maps (package data of datasets_synthetic, found by path
#: so that render/ does not import datasets_synthetic).
BUNDLED_DIR = Path(__file__).resolve().parents[2] / "datasets_synthetic" / "envmaps"
#: Names of the bundled maps (Blender studio lights, CC0, 1024x512 EXR).
BUNDLED_NAMES = ("courtyard", "forest", "studio", "sunset")


class EnvMapError(ValueError):
    """An environment-map file is missing, unreadable or not a 2:1 equirect HDR image; the message names it."""


class EnvMapNotFound(EnvMapError, FileNotFoundError):
    """The environment-map file does not exist."""


@dataclass(frozen=True)
class EnvMap:
    """Linear HDR environment radiance.

    data: (H, 2H, 3) float32, finite, >= 0, equirectangular in the convention of this module.
    name: a label (file stem, "procedural", ...).
    """

    data: np.ndarray
    name: str = "env"

    def __post_init__(self):
        d = np.asarray(self.data)
        if d.ndim != 3 or d.shape[2] != 3 or d.shape[1] != 2 * d.shape[0] or d.shape[0] < 1:
            raise ValueError(f"EnvMap {self.name!r}: data must be (H, 2H, 3), got {d.shape}")
        if d.dtype != np.float32:
            d = d.astype(np.float32)
        if not np.all(np.isfinite(d)):
            raise ValueError(f"EnvMap {self.name!r}: data has NaN or inf")
        if np.any(d < 0):
            raise ValueError(f"EnvMap {self.name!r}: negative radiance (min {float(d.min())})")
        d = np.ascontiguousarray(d)
        d.setflags(write=False)
        object.__setattr__(self, "data", d)

    @property
    def height(self) -> int:
        return int(self.data.shape[0])

    @property
    def width(self) -> int:
        return int(self.data.shape[1])

    # -- geometry -----------------------------------------------------------------------------
    def pixel_directions(self) -> np.ndarray:
        """(H, W, 3) float64 unit directions of the pixel centres."""
        h, w = self.height, self.width
        uu, vv = np.meshgrid(cell_centres(w, 0.0, 1.0), cell_centres(h, 0.0, 1.0))
        return uv_to_dir(np.stack([uu, vv], -1))

    def pixel_solid_angles(self) -> np.ndarray:
        """(H, W) float64 exact solid angle of each pixel (sr); sums to 4 pi."""
        return pixel_solid_angles(self.height)

    def sample(self, dirs) -> np.ndarray:
        """Bilinear radiance lookup (wrap in u, clamp in v). dirs (..., 3) -> (..., 3) float64."""
        return sample_equirect(self.data, dir_to_uv(dirs))

    def rotated(self, angle_z: float) -> EnvMap:
        """The environment turned by ``angle_z`` radians about +z (right-handed):
        ``rotated(a).sample(Rz(a) @ d) == sample(d)``. Exact for multiples of 2 pi / W, linear
        interpolation between columns otherwise."""
        w = self.width
        # phi -> phi + a  <=>  u -> u - a / (2 pi); new[:, j] = old at column j + a W / (2 pi)
        shift = float(angle_z) * w / (2 * np.pi)
        y, x = np.meshgrid(np.arange(self.height), np.arange(w) + shift, indexing="ij")
        out = sample_image(self.data.astype(np.float64), x, y, "linear", ("clamp", "wrap"))
        return EnvMap(out.astype(np.float32), self.name)

    def resized(self, h: int) -> EnvMap:
        """Area-correct resampling to (h, 2h): each new pixel is the solid-angle-weighted mean of
        the old radiance it overlaps, so the total power (sum of L * Omega) is preserved."""
        h = int(h)
        if h < 1:
            raise ValueError(f"resized: height must be >= 1, got {h}")
        if h == self.height:
            return self
        H, W = self.height, self.width
        # rows: overlap measured in cos(theta) (solid angle per unit azimuth)
        R = _overlap_matrix(np.cos(np.pi * np.arange(H + 1) / H), np.cos(np.pi * np.arange(h + 1) / h))
        C = _overlap_matrix(np.arange(W + 1) / W, np.arange(2 * h + 1) / (2 * h))
        d = self.data.astype(np.float64)
        out = np.einsum("ai,ijc,bj->abc", R, d, C, optimize=True)
        return EnvMap(np.maximum(out, 0).astype(np.float32), self.name)

    def total_power(self) -> np.ndarray:
        """(3,) float64: integral of radiance over the sphere, sum L * Omega."""
        return np.einsum("hwc,hw->c", self.data.astype(np.float64), self.pixel_solid_angles())


def _overlap_matrix(old_edges: np.ndarray, new_edges: np.ndarray) -> np.ndarray:
    """M[a, i] = |new cell a ∩ old cell i| / |new cell a| for monotone edge arrays (either
    direction)."""
    s = 1.0 if old_edges[-1] > old_edges[0] else -1.0
    o = s * np.asarray(old_edges, np.float64)
    n = s * np.asarray(new_edges, np.float64)
    lo = np.maximum(n[:-1, None], o[None, :-1])
    hi = np.minimum(n[1:, None], o[None, 1:])
    ov = np.clip(hi - lo, 0, None)
    return ov / (n[1:] - n[:-1])[:, None]


def pixel_solid_angles(h: int) -> np.ndarray:
    """(h, 2h) float64 exact solid angles of the pixels of an equirect map of height h."""
    w = 2 * h
    c = np.cos(np.pi * np.arange(h + 1) / h)
    row = (c[:-1] - c[1:]) * (2 * np.pi / w)
    return np.repeat(row[:, None], w, axis=1)


def pixel_centre_polar(h: int) -> np.ndarray:
    """(h,) float64 polar angle theta (from +z) of the pixel-centre rows of an equirect map of
    height h: pi (i + 0.5) / h."""
    return cell_centres(h, 0.0, np.pi)


def pixel_centre_azimuth(w: int) -> np.ndarray:
    """(w,) float64 azimuth phi (atan2(y, x)) of the pixel-centre columns of an equirect map of
    width w: pi (1 - 2 (j + 0.5) / w)."""
    return np.pi * (1.0 - 2.0 * cell_centres(w, 0.0, 1.0))


def equirect_nearest(uv, h: int) -> tuple[np.ndarray, np.ndarray]:
    """(rows, columns) int64 of the pixels of an (h, 2h) equirect map whose centres are nearest
    to (..., 2) uv (columns wrap, rows clamp; capture.sampling.nearest_pixel: ties go up)."""
    uv = np.asarray(uv, np.float64)
    rows = np.clip(nearest_pixel(from_texcoord(uv[..., 1], h)), 0, h - 1)
    cols = nearest_pixel(from_texcoord(uv[..., 0], 2 * h)) % (2 * h)
    return rows, cols


def dir_to_uv(dirs) -> np.ndarray:
    """(..., 3) directions (need not be unit, must be non-zero) -> (..., 2) float64 (u, v),
    u in [0, 1), v in [0, 1]. See the module docstring for the convention."""
    d = np.asarray(dirs, np.float64)
    if d.shape[-1] != 3:
        raise ValueError(f"dir_to_uv: expected (..., 3), got {d.shape}")
    rxy = np.hypot(d[..., 0], d[..., 1])
    if np.any((rxy == 0) & (d[..., 2] == 0)):
        raise ValueError("dir_to_uv: zero-length direction")
    phi = np.arctan2(d[..., 1], d[..., 0])
    theta = np.arctan2(rxy, d[..., 2])  # accurate everywhere, unlike arccos near the poles
    u = np.mod(0.5 - phi / (2 * np.pi), 1.0)
    u = np.where(u >= 1.0, 0.0, u)  # mod can round up to exactly 1.0
    return np.stack([u, theta / np.pi], -1)


def uv_to_dir(uv) -> np.ndarray:
    """(..., 2) (u, v) -> (..., 3) float64 unit directions (inverse of :func:`dir_to_uv`)."""
    uv = np.asarray(uv, np.float64)
    if uv.shape[-1] != 2:
        raise ValueError(f"uv_to_dir: expected (..., 2), got {uv.shape}")
    phi = np.pi * (1.0 - 2.0 * uv[..., 0])
    theta = np.pi * uv[..., 1]
    st = np.sin(theta)
    return np.stack([st * np.cos(phi), st * np.sin(phi), np.cos(theta)], -1)


def sample_equirect(data: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear lookup of an (H, W, C) equirect array at (..., 2) uv: wrap in u, clamp in v
    (GL_LINEAR, REPEAT in s, CLAMP_TO_EDGE in t; capture.sampling). float64."""
    data = np.asarray(data)
    H, W = data.shape[:2]
    d = data.astype(np.float64) if data.dtype != np.float64 else data
    return sample_image(d, from_texcoord(uv[..., 0], W), from_texcoord(uv[..., 1], H), "linear", ("clamp", "wrap"))


# -- procedural fallback ----------------------------------------------------------------------
#: Procedural sky: direction of the sun (unit, elevation ~35 degrees, azimuth 40 degrees).
SUN_DIR = np.array([np.cos(np.radians(35)) * np.cos(np.radians(40)),
                    np.cos(np.radians(35)) * np.sin(np.radians(40)), np.sin(np.radians(35))])
#: Procedural sky: angular radius of the sun disc (radians) and its radiance (linear RGB).
SUN_RADIUS = np.radians(3.0)
SUN_RADIANCE = np.array([400.0, 360.0, 300.0])


# -- layouts ------------------------------------------------------------------------------------
#: One sentence for ``--help`` and the docs: which pixel faces which direction of the capture.
ORIENTATION = ("equirect maps: the middle column (u = 0.5) faces the capture's +x and u = 0.25 its +y, the top "
               "row the rig's up (estimated from the cameras; +x, +y turned level with it), as Blender's world "
               "mapping; --env-convention mitsuba reads Mitsuba 3's (+y up, u = 0.25 facing +x)")


def _turn_about_up(deg: float) -> np.ndarray:
    a = np.radians(deg)
    return np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])


#: Equirect layouts: Q such that pixel uv of a map in that layout shows the direction Q @ uv_to_dir(uv)
#: of furrow's map frame (+z = the rig's up).  blender: identity (module doc); mitsuba: Mitsuba's
#: (b, c, a) for furrow's (a, b, c) at the same uv, taken to +z up by the rotation of +y onto +z
#: (x, y, z) -> (x, -z, y), i.e. (b, -a, c): a quarter turn clockwise about up.
ENV_CONVENTIONS = {"furrow": np.eye(3), "blender": np.eye(3), "mitsuba": _turn_about_up(-90.0)}
#: Layout of a map unless told otherwise.
DEFAULT_CONVENTION = "furrow"
#: A change of axes counts as a turn about up when its zz entry is this close to 1.
_TURN_TOL = 1e-12


def convention_axes(convention: str) -> np.ndarray:
    """(3, 3) change of axes Q of a layout (:data:`ENV_CONVENTIONS`); an unknown name is a ValueError."""
    if convention not in ENV_CONVENTIONS:
        raise ValueError(f"unknown environment-map convention {convention!r}; use one of {', '.join(ENV_CONVENTIONS)}")
    return ENV_CONVENTIONS[convention]


def oriented(env: EnvMap, convention: str = DEFAULT_CONVENTION, rotation_deg: float = 0.0) -> EnvMap:
    """``env`` (laid out in ``convention``) in furrow's layout, then turned by ``rotation_deg`` about up
    (right-handed, as :meth:`EnvMap.rotated`): the one place a layout or a rotation flag acts.  A turn
    about up shifts columns (exact for multiples of 360 / W degrees); any other change of axes resamples
    through :func:`uv_to_dir` / :func:`dir_to_uv`."""
    q = _turn_about_up(float(rotation_deg)) @ convention_axes(convention)
    if abs(q[2, 2] - 1.0) < _TURN_TOL:
        a = float(np.arctan2(q[1, 0], q[0, 0]))
        return env.rotated(a) if a != 0.0 else env
    d = env.pixel_directions() @ q  # rows: Q^T e, the direction in the map's own layout
    return EnvMap(np.maximum(sample_equirect(env.data, dir_to_uv(d)), 0).astype(np.float32), env.name)


def procedural_sky(h: int = 64) -> EnvMap:
    """A tiny deterministic fallback environment: blue sky gradient above, brownish ground below,
    a bright sun disc of radius :data:`SUN_RADIUS` at :data:`SUN_DIR` (supersampled 4x4)."""
    h = int(h)
    ss = 4
    w = 2 * h
    d = uv_to_dir(np.stack(np.meshgrid(cell_centres(w * ss, 0.0, 1.0), cell_centres(h * ss, 0.0, 1.0)), -1))
    z = d[..., 2:3]
    zenith = np.array([0.25, 0.45, 0.9])
    horizon = np.array([0.9, 0.95, 1.0])
    ground = np.array([0.25, 0.2, 0.15])
    t = np.clip(z, 0, 1) ** 0.5
    sky = horizon * (1 - t) + zenith * t
    img = np.where(z >= 0, sky, ground * (1 + 0.5 * np.clip(-z, 0, 1)))
    sun = (d @ SUN_DIR) >= np.cos(SUN_RADIUS)
    img = np.where(sun[..., None], SUN_RADIANCE, img)
    img = img.reshape(h, ss, w, ss, 3).mean(axis=(1, 3))
    return EnvMap(img.astype(np.float32), "procedural")


# -- I/O ----------------------------------------------------------------------------------------
def bundled_envmap(name: str) -> EnvMap:
    """One of the bundled CC0 maps (:data:`BUNDLED_NAMES`), full resolution (512x1024)."""
    path = BUNDLED_DIR / f"{name}.exr"
    if not path.is_file():
        raise FileNotFoundError(f"bundled environment map {path} not found "
                                f"(bundled: {', '.join(BUNDLED_NAMES)})")
    return load_envmap(path)


#: File extensions read as HDR images (.exr, Radiance RGBE).
HDR_EXTENSIONS = (".exr", ".hdr", ".pic", ".rgbe")


def named_envmap(name_or_path: str, convention: str = DEFAULT_CONVENTION, rotation_deg: float = 0.0) -> EnvMap:
    """A bundled map (:data:`BUNDLED_NAMES`) or an equirect .exr / .hdr file: the one reading of an
    ``--env MAP`` / ``--relight MAP`` argument (an unknown name is a ValueError naming it), laid out in
    ``convention`` and turned by ``rotation_deg`` about up (:func:`oriented`; the bundled maps are in
    furrow's layout whatever ``convention`` says)."""
    convention_axes(convention)  # an unknown layout fails for bundled maps too
    p = Path(name_or_path)
    if name_or_path in BUNDLED_NAMES and p.suffix == "":
        return oriented(bundled_envmap(name_or_path), DEFAULT_CONVENTION, rotation_deg)
    if p.suffix.lower() in HDR_EXTENSIONS:
        return oriented(load_envmap(p), convention, rotation_deg)
    raise ValueError(f"unknown environment map {name_or_path!r}: use a .exr/.hdr file or one of "
                     f"{', '.join(BUNDLED_NAMES)}")


def load_envmap(path) -> EnvMap:
    """Read an equirect HDR map (.exr: ``capture.imageio.read_exr_rgb``, .hdr/.pic Radiance RGBE).
    The image must be 2:1; every failure is an :class:`EnvMapError` naming the file."""
    path = Path(path)
    if not path.is_file():
        raise EnvMapNotFound(f"environment map {path} not found")
    ext = path.suffix.lower()
    try:
        if ext == ".exr":
            data = read_exr_rgb(path)
        elif ext in (".hdr", ".pic", ".rgbe"):
            from render.shading.rgbe import read_rgbe
            data = read_rgbe(path)
        else:
            raise ValueError(f"unsupported extension {ext!r} (use .exr or .hdr)")
    except (ValueError, OSError, KeyError, RuntimeError, MemoryError) as e:  # OpenEXR raises RuntimeError
        raise EnvMapError(f"cannot read environment map {path}: {e}") from None
    if data.ndim != 3 or data.shape[0] < 1 or data.shape[1] != 2 * data.shape[0]:
        raise EnvMapError(f"environment map {path}: expected a 2:1 equirect image, got "
                          f"{data.shape[1]}x{data.shape[0]}")
    if not np.all(np.isfinite(data)):
        raise EnvMapError(f"environment map {path}: contains NaN or inf")
    return EnvMap(np.maximum(data, 0).astype(np.float32), path.stem)


def save_envmap(env: EnvMap, path) -> Path:
    """Write ``env`` as a float32 RGB EXR (``capture.imageio.write_exr``: ZIP compression,
    lossless, atomic)."""
    path = Path(path)
    if path.suffix.lower() != ".exr":
        raise ValueError(f"save_envmap: {path}: only .exr is written")
    write_exr(path, env.data)
    return path

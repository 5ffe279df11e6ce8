"""Render the views of a path-traced capture (Mitsuba 3), each view once, cached on disk per view.

A :class:`RenderSpec` is everything that decides the pixels: the object (name, seed, parameters),
the room (map, its base turn, support), the motion, the cameras (a ``TurntableRig``), the lens, the
samples, the path depth and the film filter.  :func:`render_views` renders what is not already in
the cache folder (``<cache>/<spec key>/view_NNN.npz``: the ``room`` and ``black`` colour in linear
radiance *before* exposure, the true matte, the z-depth with and without the support), so an
interrupted run resumes and two captures made from the same pixels (a room capture and its black
twin, a fixed-exposure capture and its auto-exposed copy, poses perturbed twice) render once.

Motions (the recorded cameras are the rig's ring either way, in the object's frame):

* ``turntable``: the camera stands still in the room and the object turns; in the object's frame the
  room (map and table) turns with the camera, by the view's azimuth, so every frame sees the same
  background behind the object (``gt/scene.json`` records each view's ``room_rotation_deg``);
* ``orbit``: the camera circles a still object in a still room: the background moves with the view.
"""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from capture.camera import Camera
from capture.lens import Lens
from datasets_synthetic.pathtraced.film import DEPTH_SUBSAMPLES, FILTERS, render_view, z_depth
from datasets_synthetic.pathtraced.objects import PathObject, build_object
from datasets_synthetic.pathtraced.scene import SUPPORTS, PathScene, Room
from datasets_synthetic.rig import TurntableRig

#: Camera motions (module docstring).
MOTIONS = ("turntable", "orbit")
#: Version of the cached pixels: bump when the renderer changes what a spec renders.
CACHE_VERSION = 2


@dataclass(frozen=True)
class RenderSpec:
    """Everything that decides a path-traced capture's pixels."""

    object: str = "conifer"
    """Object name (``datasets_synthetic.pathtraced.objects.OBJECTS``)."""
    seed: int = 0
    """Seed of the object's geometry and of the samples."""
    object_params: tuple = ()
    """Overrides of the object's parameters, as sorted (name, value) pairs."""
    env: str = "courtyard"
    """The map: a bundled name or an .exr / .hdr path (furrow's layout)."""
    env_rotation_deg: float = 0.0
    """The map's turn about +z at turntable angle 0 (furrow's ``EnvMap.rotated``)."""
    support: str = "none"
    """'none' or 'table' (``scene.SUPPORTS``)."""
    motion: str = "turntable"
    """'turntable' or 'orbit' (module docstring)."""
    rig: TurntableRig = field(default_factory=TurntableRig)
    """The cameras (ring of views in the object's frame)."""
    lens: Lens | None = None
    """An OPENCV lens every view is rendered through (None = pinhole)."""
    spp: int = 64
    """Samples per pixel."""
    max_depth: int = 8
    """Longest path (Mitsuba's ``max_depth``)."""
    rfilter: str = "gaussian"
    """Film reconstruction filter (``film.FILTERS``)."""
    depth_samples: int = 1
    """Sub-rays per pixel side of the depth (1 = the pixel centre; ``film.z_depth``)."""

    def __post_init__(self) -> None:
        if self.motion not in MOTIONS:
            raise ValueError(f"motion must be one of {', '.join(MOTIONS)}, got {self.motion!r}")
        if self.support not in SUPPORTS:
            raise ValueError(f"support must be one of {', '.join(SUPPORTS)}, got {self.support!r}")
        if self.rfilter not in FILTERS:
            raise ValueError(f"filter must be one of {', '.join(FILTERS)}, got {self.rfilter!r}")
        if self.spp < 1 or self.max_depth < 1 or not 1 <= self.depth_samples <= 2 * DEPTH_SUBSAMPLES + 1:
            raise ValueError(f"spp and max_depth must be >= 1, depth_samples in 1..{2 * DEPTH_SUBSAMPLES + 1}")

    def record(self) -> dict:
        """JSON-able description (gt/scene.json, the cache key)."""
        d = asdict(self)
        d["object_params"] = dict(self.object_params)
        d["rig"] = asdict(self.rig)
        d["lens"] = self.lens.record() if self.lens is not None else None
        return d

    def key(self) -> str:
        """Cache folder name: object, motion, size, spp and a hash of the whole record."""
        blob = json.dumps({"v": CACHE_VERSION, **self.record()}, sort_keys=True, default=float).encode()
        r = self.rig
        return (f"{self.object}_{self.motion}_{r.width}x{r.height}_{self.spp}spp_"
                f"{hashlib.sha1(blob).hexdigest()[:10]}")

    def build_object(self) -> PathObject:
        return build_object(self.object, self.seed, **dict(self.object_params))

    def cameras(self, obj: PathObject) -> list[Camera]:
        return self.rig.cameras(obj.radius)

    def room_turn(self, view: int, cams: list[Camera]) -> float:
        """The room's turn (degrees about +z) in the object's frame at ``view``: the view's azimuth from
        the first view on a turntable, 0 on an orbit."""
        if self.motion == "orbit":
            return 0.0
        c0, c = cams[0].center, cams[view].center
        return float(np.degrees(np.arctan2(c[1], c[0]) - np.arctan2(c0[1], c0[0])))


@dataclass(frozen=True)
class ViewRender:
    """One rendered view (linear radiance before exposure; see the module docstring).

    room, black: (H, W, 3) float32; alpha: (H, W) float32; depth_room: (H, W) float32 z-depth of the
    object and the support; depth_object: (H, W) float32 z-depth of the object alone; seconds: render time;
    attempt: the retry whose samples these are (0 = the view's own seed; ``view_seed``).
    """

    room: np.ndarray
    black: np.ndarray
    alpha: np.ndarray
    depth_room: np.ndarray
    depth_object: np.ndarray
    seconds: float
    attempt: int = 0


def _load(path: Path) -> ViewRender | None:
    try:
        with np.load(path) as z:
            return ViewRender(z["room"].astype(np.float32), z["black"].astype(np.float32),
                              z["alpha"].astype(np.float32), z["depth_room"], z["depth_object"], float(z["seconds"]),
                              int(z["attempt"]) if "attempt" in z else 0)
    except (OSError, KeyError, ValueError):
        return None


def _save(path: Path, v: ViewRender) -> None:
    from capture.atomic import atomic_write

    with atomic_write(path) as tmp, open(tmp, "wb") as f:
        np.savez_compressed(f, room=v.room.astype(np.float16), black=v.black.astype(np.float16),
                            alpha=v.alpha.astype(np.float16), depth_room=v.depth_room,
                            depth_object=v.depth_object, seconds=np.float64(v.seconds), attempt=np.int64(v.attempt))


def view_seed(seed: int, view: int, attempt: int = 0) -> int:
    """The sample seed of one view (distinct per view and per capture seed; a retry after a crash
    draws other samples, ``attempt``)."""
    return (int(seed) * 100_003 + int(view) * 7 + 1 + int(attempt) * 7_777_777) & 0xFFFFFFFF


#: Renders of one view that may die (a crash inside Mitsuba's kernels) before the view is given up.
MAX_ATTEMPTS = 3


def _attempt(folder: Path, view: int) -> int:
    """How many times view ``view`` was started and never finished (a marker file counts them), and
    mark one more start.  A view whose samples crash the renderer is retried with other samples."""
    marker = folder / f"view_{view:03d}.started"
    n = int(marker.read_text() or 0) if marker.is_file() else 0
    if n >= MAX_ATTEMPTS:
        raise RuntimeError(f"{folder}: view {view} crashed the renderer {n} times; remove {marker.name} to retry")
    marker.write_text(str(n + 1))
    return n


def render_views(spec: RenderSpec, env_map, cache: Path, views: list[int] | None = None,
                 progress: Callable | None = None) -> tuple[list[ViewRender], PathObject, list[Camera]]:
    """(renders, object, true cameras) of ``spec``'s views (all, or ``views``), from the cache folder
    ``cache / spec.key()`` when there, else rendered and stored.  ``env_map``: the EnvMap ``spec.env``
    names (furrow's layout).  ``progress(view, total, seconds, cached)`` after each view."""
    obj = spec.build_object()
    cams = spec.cameras(obj)
    idx = list(range(len(cams))) if views is None else list(views)
    folder = Path(cache) / spec.key()
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "spec.json").write_text(json.dumps(spec.record(), indent=1, default=float))
    out: dict[int, ViewRender] = {i: v for i in idx if (v := _load(folder / f"view_{i:03d}.npz")) is not None}
    todo = [i for i in idx if i not in out]
    for i in idx:
        if i in out and progress is not None:
            progress(i, len(idx), out[i].seconds, True)
    if todo:
        with PathScene(obj, Room(env_map, spec.env_rotation_deg, spec.support), spec.seed) as ps:
            for i in todo:
                t0 = time.perf_counter()
                attempt = _attempt(folder, i)
                ps.turn(spec.room_turn(i, cams))
                im = render_view(ps, cams[i], spec.spp, view_seed(spec.seed, i, attempt), spec.lens, spec.max_depth,
                                 spec.rfilter)
                dr = z_depth(ps, cams[i], spec.lens, spec.depth_samples, with_table=True)
                do = z_depth(ps, cams[i], spec.lens, spec.depth_samples, with_table=False) \
                    if spec.support != "none" else dr
                v = ViewRender(im.room, im.black, im.alpha, dr, do, time.perf_counter() - t0, attempt)
                _save(folder / f"view_{i:03d}.npz", v)
                (folder / f"view_{i:03d}.started").unlink(missing_ok=True)
                out[i] = _load(folder / f"view_{i:03d}.npz")  # what a later run reads (float16 colour)
                if progress is not None:
                    progress(i, len(idx), v.seconds, False)
    return [out[i] for i in idx], obj, [cams[i] for i in idx]

"""Small analytic scenes for registration tests and benchmarks (ray-cast, exact depth).

Used until / besides ``datasets_synthetic``: an asymmetric "control" object (tilted torus +
sphere + box, no rotational symmetry), a turntable ring of ``look_at`` cameras, and a
different object (a cone) to mix in as an impostor scan.
"""

from __future__ import annotations

import numpy as np

from capture.camera import Camera
from capture.orbit import focal_for_fov
from capture.orbit import ring_cameras as ring
from capture.registration.perturb import rotation
from capture.registration.raycast import raycast_scan
from capture.scan import ScanSet, bounds_from_points


def _o3d_mesh_arrays(m) -> tuple[np.ndarray, np.ndarray]:
    return np.asarray(m.vertices).copy(), np.asarray(m.triangles).copy()


def control_object() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(vertices (V,3) m, faces (F,3), vertex colours (V,3) linear): ~0.25 m across, centred at 0."""
    import open3d as o3d

    parts = []
    t = o3d.geometry.TriangleMesh.create_torus(torus_radius=0.08, tube_radius=0.03, radial_resolution=60,
                                               tubular_resolution=30)
    t.rotate(rotation([1, 0.3, 0], np.radians(35)), center=(0, 0, 0))
    parts.append(t)
    s = o3d.geometry.TriangleMesh.create_sphere(radius=0.045, resolution=30)
    s.translate((0.06, -0.05, 0.07))
    parts.append(s)
    b = o3d.geometry.TriangleMesh.create_box(0.05, 0.09, 0.04)
    b.translate((-0.11, 0.0, -0.07))
    parts.append(b)
    V, F, off = [], [], 0
    for m in parts:
        m = m.subdivide_midpoint(1) if len(m.vertices) < 500 else m
        v, f = _o3d_mesh_arrays(m)
        V.append(v)
        F.append(f + off)
        off += len(v)
    v = np.concatenate(V)
    f = np.concatenate(F)
    return v, f, texture(v)


def impostor_object() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A different object of similar size: an upright cone."""
    import open3d as o3d

    m = o3d.geometry.TriangleMesh.create_cone(radius=0.09, height=0.2, resolution=60, split=4)
    m.translate((0, 0, -0.1))
    v, f = _o3d_mesh_arrays(m)
    return v, f, texture(v)


def texture(v: np.ndarray) -> np.ndarray:
    """A smooth procedural colour pattern (linear RGB in [0.05, 0.95]) over world positions."""
    x, y, z = v[:, 0], v[:, 1], v[:, 2]
    c = np.stack([0.5 + 0.45 * np.sin(60 * x + 20 * z), 0.5 + 0.45 * np.sin(50 * y - 30 * x),
                  0.5 + 0.45 * np.cos(70 * z + 10 * y)], axis=1)
    return c.astype(np.float32)


def noise_texture(p: np.ndarray, seed: int = 0, n: int = 24) -> np.ndarray:
    """A feature-rich solid texture (sum of random plane waves, 1.5-10 cm wavelengths), linear RGB
    in [0.03, 0.97]: gives SIFT something to match (the SfM tests)."""
    rng = np.random.default_rng(seed)
    p = np.asarray(p, dtype=np.float64)
    out = np.zeros((len(p), 3))
    for _ in range(n):
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        k = 2 * np.pi / rng.uniform(0.015, 0.1)
        out += rng.normal(size=3) * np.sin(k * (p @ d) + rng.uniform(0, 2 * np.pi))[:, None]
    out /= np.sqrt(n / 2)
    return (0.5 + 0.47 * np.tanh(2 * out)).astype(np.float32)


def ring_cameras(n: int, radius: float = 0.5, elevation_deg: float = 20.0, width: int = 160, height: int = 120,
                 fov_deg: float = 45.0, start_deg: float = 0.0, target=(0.0, 0.0, 0.0)) -> list[Camera]:
    """``n`` turntable cameras evenly spaced in azimuth around +z, looking at ``target``."""
    az = [np.radians(start_deg + 360.0 * k / n) for k in range(n)]
    return ring(n, width, height, focal_for_fov(width, fov_deg), radius, (elevation_deg,), az, target, "view{:03d}")


def render_set(mesh, cameras: list[Camera], impostor_at: int | None = None, rich_texture: bool = False) -> ScanSet:
    """Ray-cast ``mesh`` (v, f, colours) into every camera; scan ``impostor_at`` sees the impostor
    instead; ``rich_texture`` paints :func:`noise_texture` instead of the vertex colours."""
    v, f, c = mesh
    scans = []
    imp = impostor_object() if impostor_at is not None else None
    tex = noise_texture if rich_texture else None
    for k, cam in enumerate(cameras):
        vv, ff, cc = imp if k == impostor_at else (v, f, c)
        scans.append(raycast_scan(vv, ff, cam, cc, name=cam.name, texture_fn=tex))
    return ScanSet(tuple(scans), bounds_from_points(v, margin=0.02), {"generator": "capture.registration.scenes"})


#: White margin of the synthetic board's paper around the printed pattern (metres).
BOARD_MARGIN_M = 0.04


def board_set(cameras: list[Camera], spec=None, with_object: bool = True) -> ScanSet:
    """The control object standing on a ChArUco board (``board.BoardSpec``), ray-cast."""
    from capture.registration.board import BoardSpec, board_texture_fn

    spec = spec or BoardSpec()
    w, h = spec.size_m
    z = spec.z_m
    m = BOARD_MARGIN_M  # white paper around the printed board
    pv = np.array([[-w / 2 - m, -h / 2 - m, z], [w / 2 + m, -h / 2 - m, z],
                   [w / 2 + m, h / 2 + m, z], [-w / 2 - m, h / 2 + m, z]])
    pf = np.array([[0, 1, 2], [0, 2, 3]])
    parts_v, parts_f = [pv], [pf]
    if with_object:
        v, f, _ = control_object()
        v = v + [0, 0, z - v[:, 2].min()]  # rest the object on the board
        parts_v.append(v)
        parts_f.append(f + 4)
    V = np.concatenate(parts_v)
    F = np.concatenate(parts_f)
    board_tex = board_texture_fn(spec)

    def tex(p):
        on_board = np.abs(p[:, 2] - z) < 1e-5
        out = texture(p)
        if on_board.any():
            out[on_board] = board_tex(p[on_board])
        return out

    scans = [raycast_scan(V, F, cam, None, name=cam.name, texture_fn=tex) for cam in cameras]
    return ScanSet(tuple(scans), bounds_from_points(V[4:] if with_object else V, margin=0.02), {"board": str(spec)})


# ------------------------------------------------------------------ sensor traits (issue 16)
#: Metres per unit of a consumer RGB-D sensor's 16-bit depth (RealSense, Kinect, Azure Kinect: mm).
SENSOR_UNIT_M = 1e-3
#: z^2 noise: sigma = k z^2 with k in metres at 1 m (structured light / active stereo; about
#: 1 mm at 0.7 m, the order of a RealSense D4xx at that range).
SENSOR_SIGMA_AT_1M = 0.002
#: Fraction of the pixels on a depth edge (a 4-neighbour further by more than
#: ``SENSOR_EDGE_FRAC`` of depth, or empty) that become flying pixels.
SENSOR_FLYING_FRACTION = 0.5
#: A depth step larger than this fraction of depth between 4-neighbours is a depth edge.
SENSOR_EDGE_FRAC = 0.05
#: A flying pixel next to empty space trails up to this fraction of its depth behind the surface.
SENSOR_FLYING_TAIL = 0.15


def sensor_depth(depth: np.ndarray, rng: np.random.Generator, unit: float = SENSOR_UNIT_M,
                 sigma_at_1m: float = SENSOR_SIGMA_AT_1M, flying: float = SENSOR_FLYING_FRACTION) -> np.ndarray:
    """Exact z-depth (H, W) metres -> what a consumer RGB-D sensor delivers (H, W) float32 metres.

    In order: flying pixels (a random ``flying`` fraction of the pixels on either side of a
    depth edge takes a depth uniformly between the near and the far side; next to empty space
    the far side is ``SENSOR_FLYING_TAIL`` of the depth behind, and empty pixels next to the
    surface can gain such a sample too), z^2 Gaussian noise, then quantisation to ``unit``
    (the 16-bit integer a sensor writes; 0 = no data).  ``unit`` <= 0 skips the quantisation.
    """
    d = np.asarray(depth, dtype=np.float64)
    valid = d > 0
    near = np.where(valid, d, np.inf)
    far = np.where(valid, d, 0.0)
    nb_min = np.full(d.shape, np.inf)
    nb_max = np.zeros(d.shape)
    empty_nb = np.zeros(d.shape, bool)
    H, W = d.shape
    pn, pf = np.pad(near, 1, constant_values=np.inf), np.pad(far, 1)
    pv = np.pad(valid, 1, constant_values=True)  # beyond the image is not empty space
    for dy, dx in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        sl = (slice(1 + dy, 1 + dy + H), slice(1 + dx, 1 + dx + W))
        nb_min = np.minimum(nb_min, pn[sl])
        nb_max = np.maximum(nb_max, pf[sl])
        empty_nb |= ~pv[sl]
    lo = np.where(valid, np.minimum(d, nb_min), nb_min)
    hi = np.where(valid, np.maximum(d, nb_max), 0.0)
    step = valid & (hi - lo > SENSOR_EDGE_FRAC * lo)
    rim = valid & empty_nb
    outside = ~valid & np.isfinite(nb_min)
    edge = step | rim | outside
    hi = np.where(rim | outside, np.maximum(hi, lo * (1 + SENSOR_FLYING_TAIL)), hi)
    fly = edge & (rng.uniform(size=d.shape) < flying)
    lo_f = np.where(np.isfinite(lo), lo, 0.0)
    out = np.where(fly, lo_f + rng.uniform(size=d.shape) * (hi - lo_f), d)
    has = out > 0
    out = np.where(has, out + rng.standard_normal(d.shape) * sigma_at_1m * out**2, 0.0)
    if unit > 0:
        out = np.rint(out / unit) * unit
    return np.where(has & (out > 0), out, 0.0).astype(np.float32)


def with_sensor(scanset: ScanSet, seed: int = 0, **kw) -> ScanSet:
    """The scan set with :func:`sensor_depth` applied to every scan (seeded per scan)."""
    from capture.scan import Scan

    scans = tuple(Scan(s.rgb, sensor_depth(s.depth, np.random.default_rng([seed, k]), **kw), s.camera, s.name)
                  for k, s in enumerate(scanset.scans))
    return ScanSet(scans, scanset.bounds, {**scanset.metadata, "sensor": {"seed": seed, **kw}})


# ------------------------------------------------------------------ a near-symmetric object (issue 31)
#: Radius of the symmetric test ball (metres).
BALL_RADIUS = 0.09


def symmetric_object() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(vertices, faces, colours): a ball about +z painted in latitude bands only: it looks the same
    from every turntable angle (the uniform fur ball of issue 31, without the fur)."""
    rows, cols = 48, 96
    th = np.linspace(0, np.pi, rows + 1)[1:-1]
    ph = np.linspace(0, 2 * np.pi, cols, endpoint=False)
    T, P = np.meshgrid(th, ph, indexing="ij")
    ring = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], axis=-1).reshape(-1, 3)
    v = BALL_RADIUS * np.concatenate([[[0, 0, 1]], ring, [[0, 0, -1]]])
    idx = 1 + np.arange((rows - 1) * cols).reshape(rows - 1, cols)
    nxt = np.roll(idx, -1, axis=1)
    quads = [np.stack([idx[:-1], idx[1:], nxt[1:]], -1), np.stack([idx[:-1], nxt[1:], nxt[:-1]], -1)]
    f = np.concatenate([q.reshape(-1, 3) for q in quads]
                       + [np.stack([np.zeros(cols, int), idx[0], nxt[0]], -1),
                          np.stack([np.full(cols, len(v) - 1), nxt[-1], idx[-1]], -1)])
    return v, f, band_texture(v)


def band_texture(p: np.ndarray) -> np.ndarray:
    """Latitude bands (a function of height only): linear RGB in [0.1, 0.8]."""
    z = np.asarray(p, np.float64)[:, 2]
    t = 0.5 + 0.5 * np.sin(z * 90.0)
    return np.stack([0.2 + 0.6 * t, 0.15 + 0.3 * t, 0.1 + 0.1 * t], axis=1).astype(np.float32)


def symmetric_set(cameras: list[Camera], highlight: float = 0.0) -> ScanSet:
    """Ray-cast :func:`symmetric_object` into every camera.  ``highlight`` > 0 adds a white
    specular highlight of that strength from a light that turns with the camera (a turntable: the
    object turns, camera and lights stand still): neighbouring views then look most alike at a
    relative angle of zero, the wrong one."""
    from capture.registration.raycast import raycast_scan

    v, f, _ = symmetric_object()
    scans = []
    for cam in cameras:
        def tex(p, cam=cam):
            col = band_texture(p).astype(np.float64)
            if highlight > 0:
                n = p / np.linalg.norm(p, axis=1, keepdims=True)
                light = cam.world_from_cam[:3, :3] @ np.array([0.4, -0.4, -1.0]) / np.sqrt(1.32)
                view = cam.center - p
                view /= np.linalg.norm(view, axis=1, keepdims=True)
                h = view + light
                h /= np.linalg.norm(h, axis=1, keepdims=True)
                col += highlight * np.clip(np.sum(n * h, axis=1), 0, 1)[:, None] ** 40
            return np.clip(col, 0, 1)
        scans.append(raycast_scan(v, f, cam, None, name=cam.name, texture_fn=tex))
    return ScanSet(tuple(scans), bounds_from_points(v, margin=0.02), {"generator": "capture.registration.scenes"})

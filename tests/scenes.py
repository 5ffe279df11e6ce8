"""Analytic test scenes shared by the capture, volume and render tests (exact SDFs, exact depth).

Independent of the code under test: ray-sphere and ray-capsule intersections in closed form,
the torus by sphere tracing its exact SDF to 1e-7 m.  Cameras come from capture.camera.look_at
on turntable rings around +z (world +z up, metres).

* :class:`Scene` and the scenes: :func:`sphere_scene`, :func:`torus_scene`,
  :func:`furball_scene` (a sphere with capsule strands) and :func:`spheres_scene` (three
  textured spheres, the renderer tests' object).
* :func:`ring_cameras` (one turntable ring; :data:`scan_ring` is the volume tests' preset).
* :func:`render_depth` / :func:`render_rgbz`: exact z-depth and colour per pixel;
  :func:`make_scanset`: scans with optional noise, holes and outliers.
* :func:`surface_pyramid`, :func:`mesh`, :func:`build_model`: an exact :class:`volume.model.Model`
  of the spheres scene, so renderer tests do not depend on the volume stage.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

import numpy as np

from capture import orbit
from capture.camera import Camera
from capture.scan import Scan, ScanSet
from volume.model import Model, RgbzImages, SdfLevel, SdfPyramid, SphereSet


@dataclass(frozen=True)
class Scene:
    """A scene with an exact signed distance function (metres, positive outside)."""

    name: str
    sdf: Callable[[np.ndarray], np.ndarray]  # (N,3) world -> (N,) signed distance
    raycast: Callable[[np.ndarray, np.ndarray], np.ndarray]  # origins (P,3), unit dirs (P,3) -> t (P,) (inf = miss)
    bounds: np.ndarray
    color: Callable[[np.ndarray], np.ndarray] | None = None  # (N,3) points -> (N,3) linear rgb


# ------------------------------------------------------------------ primitives
def sphere_sdf(c, r):
    c = np.asarray(c, float)
    return lambda p: np.linalg.norm(p - c, axis=-1) - r


def ray_sphere(o, d, c, r):
    """Nearest hit t > 0 of unit rays (o, d) with the sphere (c, r); inf where they miss."""
    oc = o - np.asarray(c, float)
    b = np.sum(oc * d, axis=-1)
    cc = np.sum(oc * oc, axis=-1) - r * r
    h = b * b - cc
    t = -b - np.sqrt(np.maximum(h, 0))
    return np.where((h >= 0) & (t > 0), t, np.inf)


def torus_sdf(R, r):
    def f(p):
        q = np.stack([np.hypot(p[..., 0], p[..., 1]) - R, p[..., 2]], axis=-1)
        return np.linalg.norm(q, axis=-1) - r
    return f


def sphere_trace(sdf, o, d, t_max=5.0, iters=300, eps=1e-7):
    t = np.zeros(len(o))
    alive = np.ones(len(o), bool)
    for _ in range(iters):
        idx = np.nonzero(alive)[0]
        if len(idx) == 0:
            break
        s = sdf(o[idx] + t[idx, None] * d[idx])
        t[idx] += s
        done = s < eps
        gone = t[idx] > t_max
        alive[idx[done | gone]] = False
    t[t > t_max] = np.inf
    return t


def capsules_sdf(a, b, r):
    a = np.asarray(a, float)
    b = np.asarray(b, float)

    def f(p, chunk=64):
        out = np.full(len(p), np.inf)
        for s in range(0, len(a), chunk):
            aa, bb = a[s:s + chunk], b[s:s + chunk]
            pa = p[:, None, :] - aa[None]
            ba = bb - aa
            h = np.clip(np.sum(pa * ba, -1) / np.sum(ba * ba, -1), 0, 1)
            d = np.linalg.norm(pa - h[..., None] * ba, axis=-1) - r
            out = np.minimum(out, d.min(1))
        return out
    return f


def ray_capsules(o, d, a, b, r, chunk=64):
    """Closed-form ray/capsule intersection (Quilez), min over capsules; d unit.

    Pairs are culled first with each capsule's bounding sphere (exact: a ray that misses the
    bounding sphere misses the capsule)."""
    t_best = np.full(len(o), np.inf)
    centre = 0.5 * (a + b)
    rb = 0.5 * np.linalg.norm(b - a, axis=1) + r
    for s in range(0, len(a), chunk):
        oc = centre[s:s + chunk][None] - o[:, None]
        tc = np.einsum("psk,pk->ps", oc, d)
        d2 = np.einsum("psk,psk->ps", oc, oc) - tc * tc
        pi, si = np.nonzero(d2 <= rb[s:s + chunk][None] ** 2)
        if len(pi) == 0:
            continue
        si = si + s
        ro, rd = o[pi], d[pi]
        A, B = a[si], b[si]
        ba = B - A
        oa = ro - A
        baba = np.sum(ba * ba, -1)
        bard = np.sum(ba * rd, -1)
        baoa = np.sum(ba * oa, -1)
        rdoa = np.sum(rd * oa, -1)
        oaoa = np.sum(oa * oa, -1)
        qa = baba - bard * bard
        qb = baba * rdoa - baoa * bard
        qc = baba * oaoa - baoa * baoa - r * r * baba
        h = qb * qb - qa * qc
        with np.errstate(invalid="ignore", divide="ignore"):
            t = (-qb - np.sqrt(np.maximum(h, 0))) / qa
        y = baoa + t * bard
        body = (h >= 0) & (y > 0) & (y < baba) & (t > 0)
        oc2 = np.where((y <= 0)[..., None], oa, ro - B)
        cb = np.sum(rd * oc2, -1)
        cc = np.sum(oc2 * oc2, -1) - r * r
        ch = cb * cb - cc
        tcap = -cb - np.sqrt(np.maximum(ch, 0))
        cap = (h >= 0) & ~body & (ch > 0) & (tcap > 0)
        tt = np.where(body, t, np.where(cap, tcap, np.inf))
        np.minimum.at(t_best, pi, tt)
    return t_best


# ------------------------------------------------------------------ scenes
def sphere_scene(r=0.07) -> Scene:
    return Scene("sphere", sphere_sdf([0, 0, 0], r), lambda o, d: ray_sphere(o, d, [0, 0, 0], r),
                 np.array([[-0.1] * 3, [0.1] * 3]))


def torus_scene(R=0.06, r=0.025) -> Scene:
    f = torus_sdf(R, r)
    return Scene("torus", f, lambda o, d: sphere_trace(f, o, d), np.array([[-0.1, -0.1, -0.05], [0.1, 0.1, 0.05]]))


def furball_scene(core=0.05, n=400, length=(0.02, 0.04), radius=0.0008, seed=0) -> Scene:
    """A sphere with ``n`` thin straight strands (capsules) pointing outward."""
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    jitter = rng.normal(scale=0.35, size=(n, 3))
    dirs = u + jitter
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    dirs = np.where(np.sum(dirs * u, 1, keepdims=True) < 0.3, u, dirs)
    a = u * (core - 0.002)
    b = a + dirs * rng.uniform(*length, size=(n, 1))
    fs, fc = sphere_sdf([0, 0, 0], core), capsules_sdf(a, b, radius)

    def sdf(p):
        return np.minimum(fs(p), fc(p))

    def rc(o, d):
        return np.minimum(ray_sphere(o, d, [0, 0, 0], core), ray_capsules(o, d, a, b, radius))

    ext = core + length[1] + 0.005
    return Scene("furball", sdf, rc, np.array([[-ext] * 3, [ext] * 3]))


#: The renderer tests' object: three overlapping spheres (x, y, z, radius) in a cube of side 0.256 m.
SPHERES = np.array([[0.0, 0.0, 0.0, 0.07], [0.055, 0.03, 0.045, 0.04], [-0.05, -0.04, -0.03, 0.045]])
BOUNDS = np.array([[-0.128, -0.128, -0.128], [0.128, 0.128, 0.128]])


def colour_at(p: np.ndarray) -> np.ndarray:
    """(N, 3) linear colour of world points (smooth stripes, different per channel)."""
    p = np.asarray(p, dtype=np.float64)
    r = 0.15 + 0.7 * (0.5 + 0.5 * np.sin(70 * p[:, 0] + 20 * p[:, 2]))
    g = 0.1 + 0.6 * (0.5 + 0.5 * np.sin(55 * p[:, 1] - 30 * p[:, 0]))
    b = 0.1 + 0.5 * (0.5 + 0.5 * np.cos(90 * p[:, 2]))
    return np.stack([r, g, b], axis=1)


def spheres_scene() -> Scene:
    """The union of :data:`SPHERES`, coloured by :func:`colour_at`, in the cube :data:`BOUNDS`."""
    def sdf(p):
        p = np.asarray(p, dtype=np.float64).reshape(-1, 3)
        return (np.linalg.norm(p[:, None, :] - SPHERES[None, :, :3], axis=2) - SPHERES[None, :, 3]).min(axis=1)

    def rc(o, d):
        return np.min([ray_sphere(o, d, s[:3], s[3]) for s in SPHERES], axis=0)

    return Scene("spheres", sdf, rc, BOUNDS, colour_at)


# ------------------------------------------------------------------ capture
def ring_cameras(n: int, width: int = 96, height: int = 72, *, radius: float = 0.45,
                 elevations: tuple[float, ...] = (15.0,), focal: float | None = None, fov_deg: float | None = None,
                 phase_deg: float = 0.0, azimuths=None, name: str = "cam_{:03d}.png") -> list[Camera]:
    """n cameras on a turntable ring around +z looking at the origin (capture.orbit.ring_cameras).

    Camera i sits at azimuth ``phase_deg + 360 i / n`` (or ``azimuths[i]``, degrees) and elevation
    ``elevations[i % len(elevations)]`` (degrees), ``radius`` metres from the origin.  Focal length:
    ``focal`` pixels, else from the horizontal field of view ``fov_deg``, else 1.1 * width.
    OpenCV principal point at the image centre ((w - 1) / 2, (h - 1) / 2); names ``name.format(i)``.
    """
    if focal is not None:
        f = float(focal)
    elif fov_deg is not None:
        f = orbit.focal_for_fov(width, fov_deg)
    else:
        f = 1.1 * width
    az = np.radians(phase_deg) + 2 * np.pi * np.arange(n) / n if azimuths is None else np.radians(azimuths)
    return orbit.ring_cameras(len(az), width, height, f, radius, tuple(elevations), az, name=name)


#: The volume tests' capture ring: alternating elevations (above / below) and a 32 degree field of view.
scan_ring = partial(ring_cameras, elevations=(15.0, -10.0), fov_deg=32.0)


def _hits(scene: Scene, cam: Camera):
    """World hit points (P, 3), z-depth (P,) (0 = miss) and hit mask of every pixel's ray."""
    rays_c = cam.pixel_rays(cam.pixel_grid().reshape(-1, 2))
    dirs_c = rays_c / np.linalg.norm(rays_c, axis=1, keepdims=True)
    d = dirs_c @ cam.world_from_cam[:3, :3].T
    o = np.broadcast_to(cam.center, d.shape).copy()
    t = scene.raycast(o, d)
    hit = np.isfinite(t)
    tt = np.where(hit, t, 0.0)
    return o + tt[:, None] * d, tt * dirs_c[:, 2], hit


def render_depth(scene: Scene, cam: Camera) -> np.ndarray:
    """Exact z-depth map (H, W) float32 metres, 0 where the ray misses."""
    _, z, _ = _hits(scene, cam)
    return z.reshape(cam.height, cam.width).astype(np.float32)


def render_rgbz(cam: Camera, scene: Scene | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Exact (H, W, 3) linear colour (black background) and (H, W) z-depth (0 = background)
    of ``scene`` (default: :func:`spheres_scene`), which must have a colour function."""
    scene = spheres_scene() if scene is None else scene
    pts, z, hit = _hits(scene, cam)
    col = np.where(hit[:, None], scene.color(pts), 0.0)
    H, W = cam.height, cam.width
    return col.reshape(H, W, 3).astype(np.float32), z.reshape(H, W).astype(np.float32)


def make_scanset(scene: Scene, cams, noise=0.0, holes=0.0, outliers=0.0, seed=1, depth_hook=None) -> ScanSet:
    """Scans of ``scene``: Gaussian z-noise (metres), a fraction of pixels in hole blobs, outliers."""
    rng = np.random.default_rng(seed)
    scans = []
    for i, cam in enumerate(cams):
        z = render_depth(scene, cam)
        valid = z > 0
        if noise:
            z = np.where(valid, z + rng.normal(scale=noise, size=z.shape), 0).astype(np.float32)
        if holes:
            # blobs: random centres, radius ~3 px, until the target fraction of valid pixels is gone
            H, W = z.shape
            yy, xx = np.mgrid[0:H, 0:W]
            target = holes * valid.sum()
            gone = np.zeros_like(valid)
            while (gone & valid).sum() < target:
                cy, cx = rng.integers(0, H), rng.integers(0, W)
                gone |= (yy - cy) ** 2 + (xx - cx) ** 2 <= rng.uniform(1.5, 4) ** 2
            z = np.where(gone, 0, z).astype(np.float32)
        if outliers:
            m = valid & (rng.random(z.shape) < outliers)
            z = np.where(m, z * rng.uniform(0.7, 1.3, size=z.shape), z).astype(np.float32)
        if depth_hook is not None:
            z = depth_hook(i, z)
        shade = np.clip(0.3 + 0.5 * (z > 0), 0, 1).astype(np.float32)
        rgb = np.repeat(shade[..., None], 3, axis=2) * np.array([0.8, 0.5, 0.3], np.float32)
        scans.append(Scan(rgb.astype(np.float32), z, cam, cam.name))
    return ScanSet(tuple(scans), scene.bounds, {"scene": scene.name})


# ------------------------------------------------------------------ exact models (renderer tests)
def _cube(scene: Scene) -> tuple[np.ndarray, float]:
    """Origin corner and side of the cube over the scene's bounds (their largest extent)."""
    b = np.asarray(scene.bounds, np.float64)
    return b[0], float((b[1] - b[0]).max())


def surface_pyramid(resolutions=(4, 8, 16, 32), empty: tuple[int, ...] = (), scene: Scene | None = None) -> SdfPyramid:
    """Surface voxels |sdf| <= half a voxel diagonal (docs/methods.md §1.1) on every level; levels in
    ``empty`` get none.  Default scene: :func:`spheres_scene`."""
    scene = spheres_scene() if scene is None else scene
    origin, extent = _cube(scene)
    levels = []
    for L in resolutions:
        w = extent / L
        ijk = np.stack(np.meshgrid(*[np.arange(L)] * 3, indexing="ij"), -1).reshape(-1, 3)
        d = scene.sdf(origin + (ijk + 0.5) * w)
        surf = ijk[np.abs(d) <= 0.5 * np.sqrt(3) * w] if L not in empty else np.zeros((0, 3), int)
        levels.append(SdfLevel(L, origin, w, surf.astype(np.int32)))
    return SdfPyramid(tuple(levels), resolutions[-1])


def mesh(resolution: int = 48, scene: Scene | None = None):
    """Marching-cubes mesh (vertices (V, 3) float32, faces (F, 3) int32) of the scene's SDF."""
    from skimage.measure import marching_cubes

    scene = spheres_scene() if scene is None else scene
    origin, extent = _cube(scene)
    w = extent / resolution
    g = (np.arange(resolution) + 0.5) * w
    X, Y, Z = np.meshgrid(g, g, g, indexing="ij")
    vals = scene.sdf(origin + np.stack([X, Y, Z], -1).reshape(-1, 3)).reshape(X.shape)
    verts, faces, _, _ = marching_cubes(vals, 0.0, spacing=(w, w, w))
    verts = verts + origin + 0.5 * w
    return verts.astype(np.float32), faces[:, ::-1].astype(np.int32)


def build_model(cameras, resolutions=(4, 8, 16, 32), empty=()) -> Model:
    """The exact Model of :func:`spheres_scene` seen by ``cameras`` (RGBz ray-cast in float64)."""
    rgb, depth = zip(*[render_rgbz(c) for c in cameras])
    v, f = mesh()
    return Model(pyramid=surface_pyramid(resolutions, empty),
                 rgbz=RgbzImages(np.stack(rgb), np.stack(depth), tuple(cameras)),
                 spheres=SphereSet(SPHERES[:, :3], SPHERES[:, 3]), mesh_vertices=v, mesh_faces=f,
                 mesh_colors=colour_at(v).astype(np.float32), bounds=BOUNDS, params={}, provenance={"scene": "spheres"})


def soft_matte(depth: np.ndarray, ramp_px: float = 3.0, seed: int | None = 0) -> np.ndarray:
    """(N, H, W) float32 seeded soft matte over (N, H, W) z-depth: 0 where there is no depth, inside a
    ramp to 1 over ``ramp_px`` pixels from the silhouette times (with a ``seed``) a random opacity
    in [0.6, 1] per pixel (fur-like partial pixels everywhere), so every alpha path has fractional
    values to carry; ``seed=None``: the ramp alone (about the same matte from every view)."""
    from scipy.ndimage import distance_transform_edt

    rng = np.random.default_rng(seed)
    out = np.zeros(np.shape(depth), np.float32)
    for i, d in enumerate(np.asarray(depth)):
        ramp = np.clip(distance_transform_edt(d > 0) / ramp_px, 0.0, 1.0)
        out[i] = ramp * (1.0 if seed is None else rng.uniform(0.6, 1.0, d.shape))
    return out


def with_alpha(model: Model, alpha: np.ndarray | None) -> Model:
    """``model`` with its RGBz images carrying the straight matte ``alpha`` (N, H, W) (or none)."""
    from dataclasses import replace

    r = model.rgbz
    return replace(model, rgbz=RgbzImages(r.rgb, r.depth, r.cameras, alpha))


def compact(model: Model, margin: int | None = None) -> Model:
    """``model`` with its RGBz images in a compact store (volume.rgbz_store.RgbzCrop per view, the
    object's footprint grown by ``margin`` pixels; default the store's own margin)."""
    from dataclasses import replace

    from volume.rgbz_store import RgbzCrop

    r = model.rgbz
    m = r.measured
    crops = [RgbzCrop.encode(*r.view(n), margin=margin, measured=None if m is None else m[n]) for n in range(len(r))]
    return replace(model, rgbz=RgbzImages.from_crops(r.cameras, crops))


def densified(model: Model) -> Model:
    """``model`` with its RGBz images as the dense float16 stacks its store decodes to."""
    from dataclasses import replace

    r = model.rgbz
    return replace(model, rgbz=RgbzImages(r.rgb, r.depth, r.cameras, r.alpha, measured=r.measured))


def sun_sky_env(h: int = 32, sun=(0.6, -0.3, 0.75), ambient: float = 0.3, sky: float = 0.2, power: float = 40.0,
                sharpness: float = 60.0):
    """An (h, 2h) EnvMap of a bluish sky (``ambient`` + ``sky`` x the elevation's sine above the horizon) and a
    warm sun of peak ``power`` at direction ``sun``, falling off as exp(sharpness (cos - 1))."""
    from render.shading.envmap import EnvMap

    d = EnvMap(np.zeros((h, 2 * h, 3), np.float32)).pixel_directions()
    s = np.asarray(sun, np.float64) / np.linalg.norm(sun)
    blue = ambient + sky * np.maximum(d[..., 2:3], 0) * np.array([0.6, 0.8, 1.0])
    disc = power * np.exp(sharpness * (d @ s - 1))[..., None] * np.array([1.0, 0.9, 0.7])
    return EnvMap((blue + disc).astype(np.float32), "sun")


def agreement_samples(scans, points: int) -> list:
    """capture.depth_agreement.view_sample of each scan (``points`` points), seeded by its index: the depth checks'
    tests' inputs."""
    from capture.depth_agreement import view_sample

    return [view_sample(s.depth, s.camera, points, i) for i, s in enumerate(scans)]


def pair_hit_cases(scans, points: int, pairs, scales: np.ndarray, rel: float):
    """(i, j, view i's sample, view j's sample, capture.depth_agreement.pair_hits of i's points in j) for each
    pair (i, j): what the depth checks' compiled or reshaped hit counts are held against."""
    from capture.depth_agreement import pair_hits

    smp = agreement_samples(scans, points)
    for i, j in pairs:
        a, b = smp[i], smp[j]
        yield i, j, a, b, pair_hits(a[0], scans[i].camera, scans[j].camera, b[1], b[2], scales, rel)[0]


def agreement_inputs(scans, cfg) -> tuple[list, list, float]:
    """(:func:`agreement_samples`, the cameras, the best depth scale of capture.depth_agreement's search) of
    ``scans`` under the AgreementConfig ``cfg``."""
    from capture.depth_agreement import agreement, verdict

    samples, cams = agreement_samples(scans, cfg.points), [s.camera for s in scans]
    g, share, share_all, _, _ = agreement(samples, cams, cfg)
    return samples, cams, float(verdict(g, share, share_all)["best_scale"])

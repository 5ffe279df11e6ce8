"""Analytic test scenes: exact depth maps by ray casting primitives in numpy, exact SDFs.

Independent of the code under test: ray-sphere and ray-capsule intersections in closed form,
the torus by sphere tracing its exact SDF to 1e-7 m.  Cameras come from capture.camera.look_at
on a turntable ring around +z (world +z up, metres).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from capture import orbit
from capture.camera import Camera
from capture.scan import Scan, ScanSet


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


# ------------------------------------------------------------------ capture
def ring_cameras(n=24, w=80, h=60, dist=0.45, elevations=(15.0, -10.0), fov_deg=32.0, azimuths=None):
    """Turntable ring(s) around +z looking at the origin; alternating elevations."""
    az = np.linspace(0, 2 * np.pi, n, endpoint=False) if azimuths is None else np.radians(azimuths)
    return orbit.ring_cameras(len(az), w, h, orbit.focal_for_fov(w, fov_deg), dist, elevations, az, name="cam{:03d}")


def render_depth(scene: Scene, cam: Camera) -> np.ndarray:
    """Exact z-depth map (H, W) float32 metres, 0 where the ray misses."""
    uv = cam.pixel_grid().reshape(-1, 2)
    rays_c = cam.pixel_rays(uv)
    dirs_c = rays_c / np.linalg.norm(rays_c, axis=1, keepdims=True)
    R = cam.world_from_cam[:3, :3]
    d = dirs_c @ R.T
    o = np.broadcast_to(cam.center, d.shape).copy()
    t = scene.raycast(o, d)
    z = np.where(np.isfinite(t), t * dirs_c[:, 2], 0.0)
    return z.reshape(cam.height, cam.width).astype(np.float32)


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

"""Other environment layouts <-> the equirect EnvMap: geodesic domes (docs/methods.md §2 §3.4, Table 2),
cube maps, the angular fisheye of an upward camera (seed 004: 185 degrees) and a mirror-ball
light probe. All conversions sample the source bilinearly at the target's pixel directions
(resample the source to about the target's resolution first when shrinking a lot).

Conventions (world +z up, see envmap.py):
* cube map: (6, n, n, 3) faces in OpenGL order +X, -X, +Y, -Y, +Z, -Z with the OpenGL face
  orientation (the major-axis table of the GL spec), rows top-down as images.
* fisheye (equidistant / angular): square image, optical axis = +z (looking up), image +x =
  world +x, image rows downwards = world -y (a camera lying on its back, top of the image
  towards +y); radius r (fraction of the half size) <-> polar angle theta = r * fov / 2.
* mirror ball: square crop of the ball's silhouette seen orthographically; ``cam_to_world``
  (3x3) maps camera axes (x right, y up, z towards the viewer) to world.
"""

from __future__ import annotations

import numpy as np

from capture.sampling import cell_centres, from_texcoord, sample_grid, sample_image
from render.shading.envmap import EnvMap

#: docs/methods.md §2 Table 2: equirect width -> geodesic dome vertices (frequency nu = 9 W / 64).
DOME_TABLE2 = {512: 51842, 256: 12962, 128: 3242, 64: 812}


def _icosahedron():
    t = (1 + 5**0.5) / 2
    v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t], [0, 1, -t],
                  [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], np.float64)
    f = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2],
                  [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5],
                  [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]])
    return v / np.linalg.norm(v, axis=1, keepdims=True), f


def geodesic_dome(freq: int):
    """Class-I geodesic sphere of frequency ``freq``: (V, 3) unit vertices (V = 10 freq^2 + 2)
    and (20 freq^2, 3) int triangles (counter-clockwise seen from outside)."""
    nu = int(freq)
    if nu < 1:
        raise ValueError(f"geodesic_dome: frequency must be >= 1, got {freq}")
    iv, ifc = _icosahedron()
    ii, jj = np.meshgrid(np.arange(nu + 1), np.arange(nu + 1), indexing="ij")
    keep = ii + jj <= nu
    ii, jj = ii[keep], jj[keep]
    local = {(a, b): k for k, (a, b) in enumerate(zip(ii, jj))}
    tri_local = []
    for a in range(nu):
        for b in range(nu - a):
            tri_local.append((local[a, b], local[a + 1, b], local[a, b + 1]))
            if a + b + 1 < nu:
                tri_local.append((local[a + 1, b], local[a + 1, b + 1], local[a, b + 1]))
    tri_local = np.array(tri_local)
    pts, tris = [], []
    for f in ifc:
        A, B, C = iv[f]
        p = A + np.outer(ii / nu, B - A) + np.outer(jj / nu, C - A)
        tris.append(tri_local + sum(len(q) for q in pts))
        pts.append(p / np.linalg.norm(p, axis=1, keepdims=True))
    allp = np.concatenate(pts)
    key = np.round(allp * 1e9).astype(np.int64)
    uniq, inv = np.unique(key, axis=0, return_inverse=True)
    verts = np.zeros((len(uniq), 3))
    verts[inv.ravel()] = allp
    faces = inv.ravel()[np.concatenate(tris)]
    return verts, faces


def dome_frequency_for_width(width: int) -> int:
    """Frequency whose vertex count matches the thesis' Table 2 pairing (nu = 9 W / 64)."""
    return max(1, int(round(9 * width / 64)))


def spherical_triangle_areas(verts, faces) -> np.ndarray:
    """(F,) solid angles of spherical triangles (Van Oosterom-Strackee)."""
    a, b, c = (verts[faces[:, k]] for k in range(3))
    num = np.abs(np.einsum("ij,ij->i", a, np.cross(b, c)))
    den = 1 + np.einsum("ij,ij->i", a, b) + np.einsum("ij,ij->i", b, c) + np.einsum("ij,ij->i", c, a)
    return 2 * np.arctan2(num, den)


def dome_solid_angles(verts, faces) -> np.ndarray:
    """(V,) solid angle per vertex: a third of each adjacent spherical triangle (sums to 4 pi)."""
    area = spherical_triangle_areas(verts, faces)
    out = np.zeros(len(verts))
    for k in range(3):
        np.add.at(out, faces[:, k], area / 3)
    return out


def dome_from_equirect(env: EnvMap, freq: int):
    """(verts (V,3), radiance (V,3) float64, solid angles (V,)): the map resampled on a dome
    (source area-resampled to about the dome's resolution first, then bilinear)."""
    verts, faces = geodesic_dome(freq)
    h = max(4, min(env.height, int(round(freq * 64 / 9 / 2))))
    src = env.resized(h) if h < env.height else env
    return verts, src.sample(verts), dome_solid_angles(verts, faces)


# -- cube maps -------------------------------------------------------------------------------------
def _cube_dirs(n: int) -> np.ndarray:
    """(6, n, n, 3) unit directions of the cube-map texel centres (OpenGL face table)."""
    s = cell_centres(n, -1.0, 1.0)
    sc, tc = np.meshgrid(s, s)  # sc along columns, tc along rows (rows top-down = +t down)
    one = np.ones_like(sc)
    faces = [np.stack([one, -tc, -sc], -1), np.stack([-one, -tc, sc], -1), np.stack([sc, one, tc], -1),
             np.stack([sc, -one, -tc], -1), np.stack([sc, -tc, one], -1), np.stack([-sc, -tc, -one], -1)]
    d = np.stack(faces)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def cubemap_from_equirect(env: EnvMap, n: int) -> np.ndarray:
    """(6, n, n, 3) float32 cube map of ``env`` (see module conventions)."""
    return env.sample(_cube_dirs(int(n))).astype(np.float32)


def sample_cubemap(cube, dirs) -> np.ndarray:
    """Bilinear lookup of a cube map at (..., 3) directions (within the face, clamped at its
    edges; GL's seamless filtering differs only within half a texel of an edge)."""
    cube = np.asarray(cube, np.float64)
    n = cube.shape[1]
    d = np.asarray(dirs, np.float64)
    shape = d.shape[:-1]
    d = d.reshape(-1, 3)
    ax = np.abs(d).argmax(1)
    sign = np.take_along_axis(d, ax[:, None], 1)[:, 0] > 0
    face = 2 * ax + (~sign)
    ma = np.abs(np.take_along_axis(d, ax[:, None], 1)[:, 0])
    x, y, z = d.T
    conds = [face == k for k in range(6)]
    sc = np.select(conds, [-z, z, x, x, x, -x]) / ma
    tc = np.select(conds, [-y, -y, z, -z, -y, -y]) / ma
    px, py = from_texcoord((sc + 1) / 2, n), from_texcoord((tc + 1) / 2, n)
    v = sample_grid(cube, np.stack([face, py, px], -1), "linear", "clamp")  # face exact: weight 0 beyond it
    return v.reshape(shape + (cube.shape[-1],))


def equirect_from_cubemap(cube, h: int, name: str = "cubemap") -> EnvMap:
    """EnvMap (h, 2h) sampled from a cube map with :func:`sample_cubemap`."""
    d = EnvMap(np.zeros((h, 2 * h, 3), np.float32)).pixel_directions()
    return EnvMap(np.maximum(sample_cubemap(cube, d), 0).astype(np.float32), name)


# -- fisheye and mirror ball ---------------------------------------------------------------------
def fisheye_from_equirect(env: EnvMap, size: int, fov_deg: float = 185.0) -> np.ndarray:
    """(size, size, 3) angular fisheye image of ``env`` looking up (+z); outside the circle 0."""
    c = cell_centres(size, -1.0, 1.0)
    X, Y = np.meshgrid(c, c)  # Y grows downwards
    r = np.hypot(X, Y)
    theta = r * np.radians(fov_deg) / 2
    phi = np.arctan2(-Y, X)
    d = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], -1)
    out = env.sample(d)
    out[r > 1] = 0
    return out.astype(np.float32)


def equirect_from_fisheye(img, h: int, fov_deg: float = 185.0, below: float = 0.0,
                          name: str = "fisheye") -> EnvMap:
    """EnvMap (h, 2h) from an angular fisheye image looking up (+z); directions outside the
    field of view get the constant ``below`` (the fisheye of seed 004 sees no ground)."""
    img = np.asarray(img, np.float64)
    S = img.shape[0]
    if img.shape[1] != S:
        raise ValueError(f"equirect_from_fisheye: image must be square, got {img.shape[:2]}")
    d = EnvMap(np.zeros((h, 2 * h, 3), np.float32)).pixel_directions()
    theta = np.arctan2(np.hypot(d[..., 0], d[..., 1]), d[..., 2])
    r = theta / (np.radians(fov_deg) / 2)
    phi = np.arctan2(d[..., 1], d[..., 0])
    px = from_texcoord((r * np.cos(phi) + 1) / 2, S)
    py = from_texcoord((-r * np.sin(phi) + 1) / 2, S)
    v = sample_image(img, px, py, "linear", "clamp")
    v[r > 1] = below
    return EnvMap(np.maximum(v, 0).astype(np.float32), name)


def mirror_ball_from_equirect(env: EnvMap, size: int, cam_to_world=None) -> np.ndarray:
    """(size, size, 3) orthographic image of a mirror ball reflecting ``env``; outside 0."""
    c = cell_centres(size, -1.0, 1.0)
    X, Y = np.meshgrid(c, -c)  # camera x right, y up
    r2 = X**2 + Y**2
    nz = np.sqrt(np.clip(1 - r2, 0, None))
    n = np.stack([X, Y, nz], -1)
    view = np.array([0.0, 0.0, 1.0])
    refl = 2 * nz[..., None] * n - view
    if cam_to_world is None:
        cam_to_world = np.eye(3)
    d = refl @ np.asarray(cam_to_world, np.float64).T
    out = env.sample(d)
    out[r2 > 1] = 0
    return out.astype(np.float32)


def equirect_from_mirror_ball(img, h: int, cam_to_world=None, name: str = "mirrorball") -> EnvMap:
    """EnvMap (h, 2h) from a mirror-ball image (see module conventions). The direction straight
    behind the ball maps to its rim and is the least reliable."""
    img = np.asarray(img, np.float64)
    S = img.shape[0]
    d = EnvMap(np.zeros((h, 2 * h, 3), np.float32)).pixel_directions()
    if cam_to_world is None:
        cam_to_world = np.eye(3)
    dc = d @ np.asarray(cam_to_world, np.float64)  # world -> camera (rows of R^T)
    n = dc + np.array([0.0, 0.0, 1.0])
    nn = np.linalg.norm(n, axis=-1, keepdims=True)
    n = np.where(nn > 1e-12, n / np.maximum(nn, 1e-12), np.array([1.0, 0.0, 0.0]))
    px, py = from_texcoord((n[..., 0] + 1) / 2, S), from_texcoord((-n[..., 1] + 1) / 2, S)
    return EnvMap(np.maximum(sample_image(img, px, py, "linear", "clamp"), 0).astype(np.float32), name)


__all__ = ["DOME_TABLE2", "geodesic_dome", "dome_frequency_for_width", "dome_solid_angles", "dome_from_equirect",
           "spherical_triangle_areas", "cubemap_from_equirect", "equirect_from_cubemap", "sample_cubemap",
           "fisheye_from_equirect", "equirect_from_fisheye", "mirror_ball_from_equirect", "equirect_from_mirror_ball"]

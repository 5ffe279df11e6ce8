"""Hair shading of the synthetic strands: the R / TT / TRT lobes under the HDR environment.

For ``LightingConfig.hair_model == "chiang"`` the numpy renderer (``--synth-renderer numpy``, the
reference) shades every strand vertex (a vertex with a tangent: fur, needles) here in numpy, once
per view, and hands it to the rasteriser as per-vertex radiance (``MeshRasterizer.set_emission``;
its own strand shading is switched off by giving those vertices zero albedo and specular).
Surfaces (skin, pot, leaves) keep the rasteriser's shading.  The GL renderer
(``datasets_synthetic.strand_gl``, the default) evaluates the same sum in GLSL
(``shaders/strand_lobes.glsl``) with the lights of :func:`hair_lights`.

Lights: the K dominant lights of the map (``Lighting.light_dirs``) plus the rest of the map as
``env_lights`` directional lights of equal energy (median cut, ``render.shading.median_cut``),
each with shadow-map visibility at every strand point (``MeshRasterizer.light_visibility``), so a
strand deep in the coat or behind the body is not lit from there.

Radiance of a strand point towards the eye wo:

    L = sum_l power_l vis_l [ S_far(wo, d_l)  +  max(c - rho_b, 0) / pi * sin(T, d_l) ]

* S_far: the width-averaged single-scattering lobes R, TT, TRT (+ residual) of Chiang et al. 2016
  (``render.shading.hair``), absorption sigma_a from the strand's colour c by their inversion.
* the second term stands in for multiple scattering between fibres, which gives a coat its colour
  c: a Kajiya-Kay diffuse term carrying the energy c minus what single scattering already sends
  back (rho_b = R + TRT + residual at normal incidence, ``back_albedo``).  This is an
  approximation in the spirit of Karis 2016 ("Physically Based Hair Shading in Unreal", SIGGRAPH
  course), not dual scattering (Zinke et al. 2008) and not path tracing.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from render.mesh.raster.gl import SHADOW_MAP_SIZE, Lighting, RasterMesh
from render.shading.envmap import EnvMap
from render.shading.hair import HairParams, back_albedo, fibre_radiance, sigma_a_from_colour
from render.shading.median_cut import median_cut_lights

#: Scale of the angular variance given to each median-cut light (1 = a uniform disc of its solid
#: angle); chosen by the brute-force comparison in tests/datasets_synthetic/test_hair_shading.py.
SPREAD_SCALE = 1.0
#: Shadow-map size of the median-cut lights (each stands for a wide region: soft shadows; the
#: dominant lights keep the rasteriser's SHADOW_MAP_SIZE).
ENV_SHADOW_MAP_SIZE = 1024
#: Strand shading models: the rasteriser's Kajiya-Kay lobe, or the lobes of this module.
HAIR_MODELS = ("chiang", "kajiya-kay")
#: A vertex is a strand vertex when its tangent is at least this long.
STRAND_TANGENT_MIN = 0.5
#: Width quadrature nodes of the synthetic hair (0.9 % of the lobe peak from the converged width
#: average, tests/render/shading/test_hair.py; 16 nodes cost the same within noise but 12 keep the
#: temporaries smaller).
WIDTH_NODES_SYNTH = 12


@dataclass(frozen=True)
class StrandPoints:
    """Strand vertices grouped into points (the ring of a tube around one centre-line point).

    group: (V,) int, the point of each vertex, -1 for non-strand vertices.
    centres (P, 3) metres, tangents (P, 3) unit, colours (P, 3) linear albedo.
    """

    group: np.ndarray
    centres: np.ndarray
    tangents: np.ndarray
    colours: np.ndarray


def strand_points(mesh: RasterMesh) -> StrandPoints:
    """Runs of consecutive strand vertices with equal tangent and colour are one point (``tube_sweep``
    writes the ``sides`` vertices of a ring together, with the same tangent and colour)."""
    V = len(mesh.vertices)
    T = mesh.tangents if mesh.tangents is not None else np.zeros((V, 3), np.float32)
    hair = np.linalg.norm(T, axis=1) >= STRAND_TANGENT_MIN
    idx = np.nonzero(hair)[0]
    group = np.full(V, -1, np.int64)
    if len(idx) == 0:
        z = np.zeros((0, 3))
        return StrandPoints(group, z, z, z)
    key = np.concatenate([T[idx], mesh.colors[idx]], axis=1)
    start = np.ones(len(idx), bool)
    start[1:] = (np.diff(idx) != 1) | np.any(key[1:] != key[:-1], axis=1)
    gid = np.cumsum(start) - 1
    group[idx] = gid
    n = int(gid[-1]) + 1
    count = np.bincount(gid, minlength=n)[:, None]
    centres = np.stack([np.bincount(gid, mesh.vertices[idx, k], n) for k in range(3)], 1) / count
    first = idx[start]
    tang = T[first].astype(np.float64)
    return StrandPoints(group, centres, tang / np.linalg.norm(tang, axis=1, keepdims=True),
                        mesh.colors[first].astype(np.float64))


def without_strand_shading(mesh: RasterMesh, pts: StrandPoints) -> RasterMesh:
    """The mesh with zero albedo and specular on strand vertices (the rasteriser then adds only
    the emission there)."""
    hair = pts.group >= 0
    col = np.where(hair[:, None], 0.0, mesh.colors)
    spec = None if mesh.specular is None else np.where(hair, 0.0, mesh.specular)
    return RasterMesh(mesh.vertices, mesh.faces, col, mesh.normals, mesh.tangents, mesh.occlusion, spec)


@dataclass(frozen=True)
class HairLighting:
    """Everything view-independent of the hair shading of one scene under one lighting.

    points: the strand points; dirs (L, 3) / power (L, 3): the lights (dominant first, then the
    median-cut rest); visibility (P, L); sigma_a (P, 3); ms_weight (P, 3) = max(c - rho_b, 0) / pi;
    params: the fibre parameters; nodes: width quadrature nodes; spread (L,): angular variance of
    each light's region (``fibre_radiance``'s ``light_spread``; 0 for the dominant lights).
    """

    points: StrandPoints
    dirs: np.ndarray
    power: np.ndarray
    visibility: np.ndarray
    sigma_a: np.ndarray
    ms_weight: np.ndarray
    params: HairParams
    nodes: int
    spread: np.ndarray

    def info(self) -> dict:
        """JSON-able summary for gt/scene.json."""
        mean = self.visibility.mean(0) if len(self.visibility) else np.zeros(0)
        return hair_info(len(self.points.centres), self.dirs, self.power, mean, self.params, self.nodes)


def hair_info(points: int, dirs, power, mean_visibility, params: HairParams, nodes: int) -> dict:
    """The gt/scene.json record of the chiang hair shading (either renderer)."""
    return {"model": "chiang2016+diffuse-ms", "strand_points": int(points), "lights": int(len(dirs)),
            "light_dirs": np.asarray(dirs).tolist(), "light_power": np.asarray(power).tolist(),
            "mean_visibility": np.asarray(mean_visibility).tolist(), "beta_m": params.beta_m,
            "beta_n": params.beta_n, "alpha_deg": params.alpha_deg, "eta": params.eta, "width_nodes": nodes}


def hair_lights(lighting: Lighting, residual: EnvMap, env_lights: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(dirs (L, 3), power (L, 3), spread (L,)) of the hair shading: ``lighting``'s dominant lights
    (spread 0) then the ``residual`` map cut into ``env_lights`` lights (a power of two; median
    cut), each with the angular variance of its region (``fibre_radiance``'s ``light_spread``)."""
    if env_lights < 1 or env_lights & (env_lights - 1):
        raise ValueError(f"hair: env_lights must be a power of two, got {env_lights}")
    cut = median_cut_lights(residual, int(np.log2(env_lights)))
    dom = np.asarray(lighting.light_dirs, np.float64).reshape(-1, 3)
    dirs = np.concatenate([dom, cut.dirs])
    power = np.concatenate([np.asarray(lighting.light_colors, np.float64).reshape(-1, 3), cut.power])
    # a region of solid angle Omega as a disc: radius sqrt(Omega / pi), variance per axis Omega / (4 pi)
    spread = np.concatenate([np.zeros(len(dom)), cut.solid_angle / (4 * np.pi) * SPREAD_SCALE])
    return dirs, power, spread


def hair_lighting(pts: StrandPoints, lighting: Lighting, residual: EnvMap, env_lights: int, visibility,
                  params: HairParams = HairParams(), nodes: int = WIDTH_NODES_SYNTH, shadows: bool = True,
                  dominant_visibility: np.ndarray | None = None) -> HairLighting:
    """Prepare the hair shading of the strand points ``pts``: the light set (``lighting``'s dominant
    lights + the ``residual`` map cut into ``env_lights`` lights, a power of two), their visibility
    (``dominant_visibility`` (P, K) when given, e.g. the rasteriser's per-vertex shadow lookups at
    each point's first vertex; the rest from ``visibility(dirs, points, map_size) -> (P, n)``,
    ``MeshRasterizer.light_visibility``; all 1 when ``shadows`` is off), absorption and the
    multiple-scattering weight."""
    dirs, power, spread = hair_lights(lighting, residual, env_lights)
    K = len(np.asarray(lighting.light_dirs).reshape(-1, 3))
    P = len(pts.centres)
    if shadows and P:
        vd = (np.asarray(dominant_visibility, np.float64) if dominant_visibility is not None
              else np.asarray(visibility(dirs[:K], pts.centres, SHADOW_MAP_SIZE), np.float64).reshape(P, K))
        ve = np.asarray(visibility(dirs[K:], pts.centres, ENV_SHADOW_MAP_SIZE), np.float64)
        vis = np.concatenate([vd, ve], 1)
    else:
        vis = np.ones((P, len(dirs)))
    sa = sigma_a_from_colour(pts.colours, params.beta_n)
    ms = np.maximum(pts.colours - back_albedo(sa, params, nodes), 0.0) / np.pi
    return HairLighting(pts, dirs, power, vis, sa, ms, params, nodes, spread)


def strand_radiance(hl: HairLighting, eye) -> np.ndarray:
    """(P, 3) radiance of every strand point towards the camera at ``eye`` (module docstring)."""
    c = hl.points.centres
    if len(c) == 0:
        return np.zeros((0, 3))
    wo = np.asarray(eye, np.float64) - c
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    single = fibre_radiance(hl.points.tangents, wo, hl.dirs, hl.power, hl.visibility, hl.sigma_a, hl.params, hl.nodes,
                            hl.spread)
    sin_tl = np.sqrt(np.maximum(1 - (hl.points.tangents @ hl.dirs.T) ** 2, 0))       # (P, L)
    diffuse = (hl.visibility * sin_tl) @ hl.power                                      # (P, 3)
    return single + hl.ms_weight * diffuse


def vertex_emission(hl: HairLighting, eye) -> np.ndarray:
    """(V, 3) float32 per-vertex radiance for ``MeshRasterizer.set_emission`` (0 off the strands)."""
    g = hl.points.group
    out = np.zeros((len(g), 3), np.float32)
    hair = g >= 0
    out[hair] = strand_radiance(hl, eye)[g[hair]]
    return out


def prepare_hair(rast, mesh: RasterMesh, lighting: Lighting, residual: EnvMap, model: str, env_lights: int,
                 shadows: bool = True) -> HairLighting | None:
    """Give ``rast`` the mesh and lighting; for ``model`` "chiang" with the strands' own shading
    switched off, returning the :class:`HairLighting` whose :func:`vertex_emission` the caller
    sets per view; for "kajiya-kay" the rasteriser's own strand shading, returning None."""
    if model not in HAIR_MODELS:
        raise ValueError(f"hair model must be one of {', '.join(HAIR_MODELS)}, got {model!r}")
    if model == "kajiya-kay":
        rast.set_mesh(mesh)
        rast.set_lighting(lighting)
        return None
    pts = strand_points(mesh)
    rast.set_mesh(without_strand_shading(mesh, pts))
    rast.set_lighting(lighting)
    if len(pts.centres) == 0:  # nothing to shade here (the torus)
        return None
    first = np.nonzero(np.r_[True, np.diff(pts.group) != 0] & (pts.group >= 0))[0]
    dom_vis = rast.vertex_visibility[first] if rast.vertex_visibility.shape[1] == len(lighting.light_dirs) else None
    return hair_lighting(pts, lighting, residual, env_lights, rast.light_visibility, shadows=shadows,
                         dominant_visibility=dom_vis)

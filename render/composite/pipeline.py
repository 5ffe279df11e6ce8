"""Compositing a captured object into an environment (docs/methods.md §3 seed 004 Eq. 16-17, §4 glare).

Pipeline of :func:`composite_frame` (GL; numpy twins beside every pass):

1. **Background** from the environment map for the camera: the world direction of each pixel
   looked up with the ONE equirect mapping (``render.shading.envmap``; GLSL twin
   ``shading_envmap.glsl``).
2. **Ground shadow** (seed 004 Eq. 16-17; ``render.composite.ground_shadow``): the ratio of the ground's
   irradiance with the object to that without it, from the sphere set's SSDF under an SG fit of
   the environment, on a grid around the object, multiplied onto the background pixels whose ray
   meets the ground.
3. **Object** over the background with its matte: premult + (1 - alpha) background in linear
   light (without a matte the object pixels, depth > 0, replace it); optionally with the
   light-reflection map (``render.shading.glare_maps``) of a specular-parameter map added.
4. **Exposure** (a linear factor), **glare** (``render.shading.glare``: the excess above the
   display white becomes streaks, energy kept) and **tone mapping** (``render.composite.tonemap``).

Passes 1-3 run in the GL owner ``render.composite.gl.Compositor`` (numpy twin
``render.composite.reference.composite_reference``); glare in ``render.composite.glare_layer.GlareLayer``.
"""

from __future__ import annotations

import time

import numpy as np

from capture.camera import Camera
from capture.depth_normals import depth_normals
from capture.rotations import rotation_between
from render.composite.gl import Compositor
from render.composite.ground_shadow import GroundPlane, ground_from_spheres, shadow_sg_fit
from render.composite.tonemap import TONE_WHITE, display_white, tonemap
from render.shading.envmap import EnvMap

#: Blinn-Phong exponent for the streak shape where no specular-parameter map is given.
GLARE_DEFAULT_N = 100.0


def normals_from_depth(depth, camera: Camera) -> np.ndarray:
    """(H, W, 3) world unit normals of a z-depth map (``capture.depth_normals``, central
    differences of the back-projected points, facing the camera); 0 where a neighbour is empty."""
    dep = np.asarray(depth, np.float64)
    P = camera.unproject(camera.pixel_grid(), dep)
    return depth_normals(P, dep > 0, "central", eye=camera.center)[0]


def rotation_to_z(up) -> np.ndarray:
    """(3, 3) rotation taking the unit vector ``up`` to +z (the smallest one; a half turn about x
    for up = -z)."""
    try:
        return rotation_between(up, (0.0, 0.0, 1.0))
    except ValueError:
        raise ValueError(f"rotation_to_z: up must be a non-zero 3-vector, got {up!r}") from None


def _turned_to_env_up(up, camera: Camera, spheres, normals):
    """The camera, spheres and normals turned so that the capture's ``up`` is the environment's
    +z (:func:`rotation_to_z`); unchanged when it already is."""
    R = rotation_to_z(up)
    if np.allclose(R, np.eye(3)):
        return camera, spheres, normals
    T = np.eye(4)
    T[:3, :3] = R.T
    camera = Camera(camera.K, camera.cam_from_world @ T, camera.width, camera.height, camera.name)
    if spheres is not None:
        spheres = type(spheres)(np.asarray(spheres.centers) @ R.T, spheres.radii)
    if normals is not None:
        normals = np.asarray(normals, np.float64) @ R.T
    return camera, spheres, normals


def _specular_inputs(specular, normals, dep: np.ndarray, camera: Camera):
    """(normals (H, W, 3), spec (H, W, 2) zero off the object / where no normal) for the
    light-reflection map, or (None, None) without a specular-parameter map."""
    if specular is None:
        return None, None
    H, W = dep.shape
    spec = np.asarray(specular, np.float64)
    if spec.shape != (H, W, 2):
        raise ValueError(f"composite_frame: specular must be ({H}, {W}, 2), got {spec.shape}")
    nrm = normals_from_depth(dep, camera) if normals is None else np.asarray(normals, np.float64)
    if nrm.shape != (H, W, 3):
        raise ValueError(f"composite_frame: normals must be ({H}, {W}, 3), got {nrm.shape}")
    return nrm, np.where(((dep > 0) & (np.linalg.norm(nrm, axis=-1) > 0))[..., None], spec, 0.0)


def _ground_plane(ground, spheres) -> GroundPlane | None:
    """The shadow's ground (see :func:`composite_frame`'s ``ground``), None for no shadow."""
    if ground is False or spheres is None or not len(spheres):
        return None
    if isinstance(ground, GroundPlane):
        return ground
    return ground_from_spheres(spheres, None if ground is None else float(ground))


def composite_frame(ctx, rgb_linear, depth, camera: Camera, env: EnvMap, spheres=None, ground=None,
                    exposure: float = 1.0, glare: bool = True, specular=None, normals=None, up=(0.0, 0.0, 1.0),
                    tone: str = "reinhard", white: float = TONE_WHITE, output: str = "display",
                    sg_fit=None, glare_config=None, stats: dict | None = None, compositor=None,
                    alpha=None) -> np.ndarray:
    """Composite a captured object into an environment (see the module doc).

    rgb_linear (H, W, 3) linear object colour: straight over the object (depth > 0) without
    ``alpha``; with an (H, W) soft matte ``alpha`` in [0, 1] premultiplied by it (a
    render.frame.Frame's rgb and alpha), composited as premult + (1 - alpha) background;
    depth (H, W) z-depth in metres, 0 = empty;
    camera: the view (its size must match); env: the environment (its +z is up).
    up: the capture world's up direction: the world is turned so that ``up`` is the environment's
        +z (cameras, spheres, normals rotated by :func:`rotation_to_z`); the ground plane is
        perpendicular to it and its height is measured along it.
    spheres: the object's ``volume.model.SphereSet`` (shadow caster) or None (no shadow).
    ground: None = under the spheres (lowest sphere point along ``up``); a float = the plane height
        along ``up`` (m); a :class:`GroundPlane` (in the turned frame: +z = up); False = no shadow.
    exposure: linear factor applied to everything before glare / tone mapping.
    glare: draw streaks for pixels brighter than the display white (energy moved, not added).
    specular: (H, W, 2) specular-parameter map (k_s, n) -> the light-reflection map of the
        environment's light sources is added to the object (normals: (H, W, 3) world, else from
        the depth); its n also shapes the streaks.
    tone / white: the tone map (:func:`tonemap`). output: "display" (tone-mapped linear in
        [0, 1]) or "linear" (exposed HDR with glare, before tone mapping).
    sg_fit: the environment's SG fit (render.shading.sg_fit.SGFit); fitted by
        render.composite.ground_shadow.shadow_sg_fit when needed and None. stats: filled with timings /
        counts when given.
    compositor: a :class:`Compositor` to reuse across frames (programs compiled once, the
        environment uploaded once); by default one is made and released per call.
    Returns (H, W, 3) float32.
    """
    if output not in ("display", "linear"):
        raise ValueError(f"composite_frame: output must be 'display' or 'linear', got {output!r}")
    H, W = camera.height, camera.width
    rgb = np.asarray(rgb_linear, np.float64)
    dep = np.asarray(depth, np.float64)
    if rgb.shape != (H, W, 3) or dep.shape != (H, W):
        raise ValueError(f"composite_frame: rgb {rgb.shape} / depth {dep.shape} do not match the camera {H}x{W}")
    dep = np.where(np.isfinite(dep), dep, 0.0)
    camera, spheres, normals = _turned_to_env_up(up, camera, spheres, normals)
    st = stats if stats is not None else {}
    t0 = time.perf_counter()
    nrm, spec = _specular_inputs(specular, normals, dep, camera)
    gp = _ground_plane(ground, spheres)
    comp = Compositor(ctx) if compositor is None else compositor
    try:
        sources = comp.light_sources(env) if spec is not None else None
        if sources is not None:
            st["light_sources"] = len(sources.dirs)
        if gp is not None:
            if sg_fit is None:
                sg_fit = shadow_sg_fit(env)
                st["sg_fit_s"] = sg_fit.seconds
            t1 = time.perf_counter()
            comp.shadow_grid(spheres, sg_fit, gp)
            st["shadow_ms"] = 1e3 * (time.perf_counter() - t1)
        t1 = time.perf_counter()
        hdr = comp.composite(rgb, dep, camera, env, exposure, gp, nrm, spec, sources, alpha=alpha).astype(np.float64)
        st["composite_ms"] = 1e3 * (time.perf_counter() - t1)
        if glare:
            hdr = apply_glare_gl(ctx, hdr, display_white(tone, white), spec=specular, config=glare_config, stats=st,
                                 layer=comp.glare_layer(W, H))
    finally:
        if compositor is None:
            comp.release()
    st["total_ms"] = 1e3 * (time.perf_counter() - t0)
    if output == "linear":
        return hdr.astype(np.float32)
    return tonemap(hdr, 1.0, tone, white).astype(np.float32)


def apply_glare_gl(ctx, hdr, display_max: float, spec=None, config=None, mask=None, stats: dict | None = None,
                   supersample: int | None = None, layer=None):
    """Energy-preserving glare on an exposed HDR image (H, W, 3): the excess of the pixels above
    ``display_max`` (render.shading.glare_maps.glare_sources) is removed and redrawn as streak pairs
    (make_streaks) by render.composite.glare_layer.GlareLayer; n per pixel from ``spec`` (H, W, 2) or
    GLARE_DEFAULT_N. config: render.shading.glare.GlareConfig. layer: a GlareLayer of this size to
    reuse (else one is made for the call). Returns float64 (H, W, 3)."""
    from render.composite.glare_layer import GLARE_SUPERSAMPLE, GlareLayer
    from render.shading.glare import GlareConfig
    from render.shading.glare_maps import glare_sources, make_streaks, remove_excess

    cfg = config if config is not None else GlareConfig(display_max=display_max)
    H, W = hdr.shape[:2]
    t0 = time.perf_counter()
    src = glare_sources(hdr, display_max, mask=mask, spec=spec, default_n=GLARE_DEFAULT_N)
    streaks = make_streaks(src, cfg)
    if layer is not None:
        light = layer.render(streaks)
    else:
        with GlareLayer(ctx, W, H, GLARE_SUPERSAMPLE if supersample is None else supersample) as own:
            light = own.render(streaks)
    if stats is not None:
        stats.update(glare_ms=1e3 * (time.perf_counter() - t0), bright_pixels=len(src.centres),
                     streak_pairs=len(streaks), glare_excess=src.excess.sum(0).tolist(),
                     glare_drawn=light.sum((0, 1)).astype(float).tolist())
    return remove_excess(hdr, src) + light

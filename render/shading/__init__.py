"""Environment shading shared by every module (docs/design.md; docs/methods.md §2-§4).

- envmap: EnvMap, the one equirect direction <-> pixel mapping, EXR/HDR I/O, bundled maps
- sh: real SH, SH9 irradiance (GLSL twin sh9.glsl)
- irradiance: exact irradiance table (<= 1% diffuse; GLSL twin env_irradiance in shading_envmap.glsl)
- lights: dominant light regions (directional sources) and the map without them
- brdf: energy-preserving Blinn-Phong (GLSL twin shading_brdf.glsl)
- sg, sg_fit, sg_env: spherical Gaussians, f_h, BRDF lobes, environment fit, prefiltered
  Gamma(p, lambda) pyramid (GLSL twin shading_sg.glsl)
- projections: geodesic domes, cube maps, fisheye, mirror ball
- msem, msem_video: multi-scale environment map (GLSL twin shading_msem.glsl), per-frame
  build + streaming into one 3-D texture
- ssdf: SSDF visibility from spheres + ground plane, ray-cast reference (GLSL twin shading_ssdf.glsl)
- glare: glare streak shape and energy (Eq. 6-12; drawn by render/composite/glare_layer.py)
"""

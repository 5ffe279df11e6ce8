"""Environment shading shared by every module (DESIGN.md; METHODS §2-§4).

- envmap: EnvMap, the one equirect direction <-> pixel mapping, EXR/HDR I/O, bundled maps
- sh: real SH, SH9 irradiance (GLSL twin sh9.glsl)
- irradiance: exact irradiance table (<= 1% diffuse; GLSL twin env_irradiance in shading_envmap.glsl)
- lights: dominant light regions (directional sources) and the map without them
- brdf: energy-preserving Blinn-Phong (GLSL twin shading_brdf.glsl)
"""

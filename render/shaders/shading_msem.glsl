// Multi-scale environment map lookup (docs/methods.md §2 §3.3). Twin of render/shading/msem.py
// msem_lookup: t = r * smoothness, texture coordinate (t + 1) / 2, trilinear (LINEAR, clamp).
// The texture comes from render.shading.msem.msem_texture (voxel [i, j, k] = x, y, z).
#ifndef FURROW_SHADING_MSEM_GLSL
#define FURROW_SHADING_MSEM_GLSL
// r: unit reflection vector (world, +z up); smoothness in [0, 1] (1 = mirror, 0 = roughest).
vec3 msem_radiance(sampler3D msem, vec3 r, float smoothness) {
    vec3 t = r * clamp(smoothness, 0.0, 1.0);
    return texture(msem, t * 0.5 + 0.5).rgb;
}
#endif

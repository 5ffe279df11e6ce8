#version 430
// Glossy mesh renderer (render/mesh/glossy/gl.py): Phong reflection with non-uniform roughness from the
// multi-scale environment map, one trilinear 3-D texture fetch per pixel (docs/methods.md §2 §3.3):
// L = k_r F(r, lambda), r the reflection of the view about the normal, lambda the smoothness per
// vertex (interpolated) or per texel (u_smooth_map, bilinear). Numpy twin: render/mesh/glossy/reference.py.
#include "shading_msem.glsl"

in vec3 v_world;
in vec3 v_normal;
in float v_smooth;
in vec2 v_uv;
in float v_eyez;

uniform vec3 u_eye;             // camera centre, world
uniform sampler3D u_msem;       // render.shading.msem.msem_texture
uniform sampler2D u_smooth_map; // per-texel smoothness (R32F, LINEAR)
uniform int u_use_map;          // 1: smoothness from u_smooth_map, 0: per vertex
uniform vec3 u_kr;              // specular reflectance k_r

layout(location = 0) out vec4 f_color;  // linear radiance, alpha = coverage
layout(location = 1) out vec4 f_aux;    // (smoothness, z-depth m, n.v, 1)

void main() {
    vec3 V = normalize(u_eye - v_world);
    vec3 N = v_normal;
    float l = length(N);
    N = l > 0.0 ? N / l : V;
    if (dot(N, V) < 0.0) N = -N;   // normals face the eye
    vec3 r = 2.0 * dot(N, V) * N - V;
    float smoothness = u_use_map == 1 ? texture(u_smooth_map, v_uv).r : v_smooth;
    f_color = vec4(u_kr * msem_radiance(u_msem, r, smoothness), 1.0);
    f_aux = vec4(smoothness, v_eyez, dot(N, V), 1.0);
}

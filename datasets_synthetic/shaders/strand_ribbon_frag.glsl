#version 430
// Camera pass of the strands (datasets_synthetic/strand_gl.py) into the mesh rasteriser's frame target:
// z-depth (m) and the normal turned towards the eye (raster_common.glsl), and in the colour
// attachment either (HAIR_KK) the rasteriser's Kajiya-Kay strand shading (raster_shaded_frag.glsl),
// or (chiang, deferred) the sample's segment and its position t along it, marked by
// STRAND_SENTINEL in blue: strand_deferred_comp.glsl later replaces it by exposure x the two
// points' radiance mixed at t (what the rasteriser does with per-vertex emission).
layout(early_fragment_tests) in;
#if HAIR_KK
#include "shading_envmap.glsl"
#include "shading_brdf.glsl"
uniform sampler2D u_irradiance;
uniform vec3 u_light_dir_kk[MAX_LIGHTS];
uniform vec3 u_light_col[MAX_LIGHTS];
uniform int u_nlights;
uniform float u_hair_shininess;
in vec4 g_vis;   // the dominant lights' visibility, per ring vertex, interpolated
#endif

in vec3 g_world;
in vec3 g_normal;
in vec3 g_tangent;
in vec3 g_colour;
in float g_occl;
in float g_spec;
in float g_t;
in float g_eyez;
flat in ivec2 g_points;
flat in int g_segment;

uniform vec3 u_eye;
uniform float u_exposure;

layout(location = 0) out vec4 f_color;
layout(location = 1) out float f_depth;
layout(location = 2) out vec4 f_normal;

void main() {
    vec3 V = normalize(u_eye - g_world);
    float l = length(g_normal);
    vec3 N = l > 0.0 ? g_normal / l : V;
    N = dot(N, V) < 0.0 ? -N : N;
    f_depth = g_eyez;
    f_normal = vec4(N, 1.0);
#if HAIR_KK
    vec3 T = normalize(g_tangent);
    vec3 irradiance = env_irradiance(u_irradiance, N) * g_occl;
    vec3 specular = vec3(0.0);
    for (int i = 0; i < u_nlights; ++i) {
        vec3 L = u_light_dir_kk[i];
        vec3 H = normalize(L + V);
        float tl = dot(T, L), th = dot(T, H);
        float cos_d = sqrt(max(0.0, 1.0 - tl * tl));
        float lobe = blinn_phong_normalized(sqrt(max(0.0, 1.0 - th * th)), u_hair_shininess);
        float v = g_vis[i];
        irradiance += u_light_col[i] * (v * cos_d);
        specular += u_light_col[i] * (v * lobe);
    }
    f_color = vec4(u_exposure * (g_colour / 3.14159265358979323846 * irradiance + g_spec * specular), 1.0);
#else
    f_color = vec4(float(g_segment), g_t, STRAND_SENTINEL, 1.0);
#endif
}

#version 430
// Shaded mesh rasteriser (render/mesh/raster/gl.py, Lighting): ambient irradiance of the environment
// (minus its dominant lights) x per-vertex occlusion -- the exact irradiance table
// (env_irradiance, shading_envmap.glsl) when AMBIENT_TABLE is 1, else SH9 (sh9.glsl) -- plus MAX_LIGHTS directional lights whose
// shadow-map visibility is baked per vertex (render/mesh/raster/gl.py shadow_map_visibility); Lambert diffuse and the energy-preserving Blinn-Phong lobe (docs/methods.md §4 Eq. 4)
// from shading_brdf.glsl.  Strands (non-zero tangent) use Kajiya-Kay: diffuse sin(T, L) and the
// lobe evaluated on sin(T, H).
#include "raster_common.glsl"
#if AMBIENT_TABLE
#include "shading_envmap.glsl"
uniform sampler2D u_irradiance;         // render.shading.irradiance.irradiance_texture
#else
#include "sh9.glsl"
#endif
#include "shading_brdf.glsl"

uniform vec3 u_light_dir[MAX_LIGHTS];   // unit, towards the light
uniform vec3 u_light_col[MAX_LIGHTS];   // irradiance on a surface facing the light
uniform int u_nlights;
uniform float u_exposure;
uniform float u_shininess;
uniform float u_hair_shininess;
in vec4 v_vis;                          // light visibility from the shadow maps, per vertex
in vec3 v_emit;                         // radiance shaded outside (MeshRasterizer.set_emission), 0 by default

const float PI = 3.14159265358979323846;

void main() {
    vec3 V = normalize(u_eye - v_world);
    vec3 N = raster_normal(V);
    bool hair = dot(v_tangent, v_tangent) > HAIR_TANGENT_SQ;  // injected from render.mesh.raster.gl
    vec3 T = hair ? normalize(v_tangent) : vec3(0.0);
#if AMBIENT_TABLE
    vec3 irradiance = env_irradiance(u_irradiance, N) * v_occl;
#else
    vec3 irradiance = sh9_irradiance(N) * v_occl;
#endif
    vec3 specular = vec3(0.0);
    for (int i = 0; i < u_nlights; ++i) {
        vec3 L = u_light_dir[i];
        vec3 H = normalize(L + V);
        float cos_d, lobe;
        if (hair) {
            float tl = dot(T, L), th = dot(T, H);
            cos_d = sqrt(max(0.0, 1.0 - tl * tl));
            lobe = blinn_phong_normalized(sqrt(max(0.0, 1.0 - th * th)), u_hair_shininess);
        } else {
            cos_d = max(dot(N, L), 0.0);
            lobe = cos_d > 0.0 ? blinn_phong_normalized(max(dot(N, H), 0.0), u_shininess) : 0.0;
        }
        float vis = v_vis[i];
        irradiance += u_light_col[i] * (vis * cos_d);
        specular += u_light_col[i] * (vis * lobe);
    }
    vec3 radiance = v_color / PI * irradiance + v_spec * specular + v_emit;
    raster_write(u_exposure * radiance, N);
}

#version 430
// Composite of a captured object (premultiplied RGB + alpha) over the environment seen by the camera, with
// the object's shadow ratio on the ground plane (docs/methods.md §3, seed 004 Eq. 16-17), times the exposure:
// out = premult + (1 - alpha) background, in linear light (a soft matte: no dark or bright fringe).
// Twin of render.composite.reference.composite_reference. Each fragment shades the image pixel (u, v) (OpenCV
// centres) that framebuffer_row.glsl's image_pixel gives (read back with gl_rows_to_image).
// Object pixels may get the light-reflection map added (docs/methods.md §4, seed 002 §3.3; twin:
// render.shading.glare_maps.light_reflection_map): sum_j k_s E_j (n + 2) / (8 pi) cos^n(N.H_j), N.L_j > 0,
// with the view direction V = -normalize(ray) (independent of the depth).
#include "framebuffer_row.glsl"
#include "shading_envmap.glsl"
#include "shading_brdf.glsl"
layout(std430, binding = 6) readonly buffer LrmSources { vec4 lrm_src[]; };  // per source: (L, 0), (E rgb, 0)
uniform int u_lrm_count;       // light sources; 0 = no light-reflection map
uniform sampler2D u_normal;    // unit world normals (RGB32F), row 0 = image row 0
uniform sampler2D u_spec;      // specular-parameter map (k_s, n) (RG32F)
uniform sampler2D u_env;       // equirect, LINEAR, repeat_x
uniform sampler2D u_rgb;       // object colour premultiplied + alpha (RGBA32F), row 0 = image row 0
uniform sampler2D u_ratio;     // shadow-ratio grid (LINEAR, clamp); see composite_shadow_frag.glsl
uniform mat3 u_ray;            // world direction of pixel (u, v, 1): R^T K^-1
uniform vec3 u_eye;            // camera centre (world)
uniform int u_height;
uniform int u_ground;          // 1: multiply the shadow ratio where the ray meets the ground
uniform float u_plane_z;
uniform vec2 u_grid_origin;
uniform vec2 u_grid_size;      // world extent of the grid
uniform float u_exposure;
out vec4 o_col;

void main() {
    ivec2 px = image_pixel(gl_FragCoord.xy, u_height);
    vec4 obj = texelFetch(u_rgb, px, 0);
    vec3 col = vec3(0.0);
    if (obj.a > 0.0) {
        col = obj.rgb;
        if (u_lrm_count > 0) {
            vec3 n = texelFetch(u_normal, px, 0).xyz;
            vec2 sp = texelFetch(u_spec, px, 0).xy;
            if (sp.x > 0.0 && dot(n, n) > 0.0) {
                vec3 v = -normalize(u_ray * vec3(float(px.x), float(px.y), 1.0));
                for (int j = 0; j < u_lrm_count; ++j) {
                    vec3 l = lrm_src[2 * j].xyz;
                    vec3 h = l + v;
                    float hl = length(h);
                    h = hl > 1e-12 ? h / hl : l;
                    if (dot(n, l) > 0.0)
                        col += obj.a * sp.x * blinn_phong_normalized(dot(n, h), sp.y) * lrm_src[2 * j + 1].rgb;
                }
            }
        }
    }
    if (obj.a < 1.0) {
        vec3 d = u_ray * vec3(float(px.x), float(px.y), 1.0);
        vec3 bg = env_radiance(u_env, d);
        if (u_ground == 1 && d.z < 0.0 && u_eye.z > u_plane_z) {
            float t = (u_plane_z - u_eye.z) / d.z;
            vec2 g = (u_eye.xy + t * d.xy - u_grid_origin) / u_grid_size;
            if (all(greaterThanEqual(g, vec2(0.0))) && all(lessThanEqual(g, vec2(1.0))))
                bg *= texture(u_ratio, g).rgb;
        }
        col += (1.0 - obj.a) * bg;
    }
    o_col = vec4(u_exposure * col, 1.0);
}

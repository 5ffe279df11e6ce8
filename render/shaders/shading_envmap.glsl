// The one direction <-> equirect mapping (twin of render/shading/envmap.py; world +z up):
// u = fract(0.5 - atan(y, x) / (2 pi)), v = theta / pi = acos(z) / pi (v = 0 is +z, the top row).
// Textures holding equirect maps: LINEAR filter, repeat_x = true, repeat_y = false.
#ifndef FURROW_SHADING_ENVMAP_GLSL
#define FURROW_SHADING_ENVMAP_GLSL
const float FURROW_PI = 3.14159265358979323846;

vec2 env_dir_to_uv(vec3 d) {
    float u = fract(0.5 - atan(d.y, d.x) / (2.0 * FURROW_PI));
    float v = atan(length(d.xy), d.z) / FURROW_PI;  // accurate near the poles, unlike acos
    return vec2(u, v);
}

vec3 env_uv_to_dir(vec2 uv) {
    float phi = FURROW_PI * (1.0 - 2.0 * uv.x);
    float theta = FURROW_PI * uv.y;
    return vec3(sin(theta) * cos(phi), sin(theta) * sin(phi), cos(theta));
}

// Radiance of an equirect environment texture in direction d (bilinear).
vec3 env_radiance(sampler2D env, vec3 d) {
    return texture(env, env_dir_to_uv(d)).rgb;
}

// Diffuse irradiance from an irradiance table (render.shading.irradiance.irradiance_table,
// uploaded with irradiance_texture()) at unit normal n.
vec3 env_irradiance(sampler2D table, vec3 n) {
    return texture(table, env_dir_to_uv(n)).rgb;
}
#endif

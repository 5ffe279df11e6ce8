#version 430
// Gain volume of the relighting (twin: render.relight_reference.gain_volume_reference). An atlas of
// L slices side by side: fragment (i + L k, j) is voxel (i, j, k) (a data grid: no image-row flip),
// centre origin + (ijk + 0.5) w. Orientation: central differences of the smoothed SDF (texelFetch,
// clamped to the edge); visibility at the nearest surface point of the raw SDF, lifted, in a band
// around the surface.
// Injected: MAX_SG, RELIGHT_MIN_GRADIENT, RELIGHT_LIFT_VOXELS, RELIGHT_BAND_VOXELS.
#include "relight_common.glsl"
uniform sampler3D u_sdf_raw;
uniform sampler3D u_sdf_smooth;
uniform vec3 u_origin;
uniform float u_voxel;
uniform int u_res;
out vec4 o_gain;

float smooth_at(ivec3 v) { return texelFetch(u_sdf_smooth, clamp(v, ivec3(0), ivec3(u_res - 1)), 0).r; }

void main() {
    ivec2 f = ivec2(gl_FragCoord.xy);
    ivec3 v = ivec3(f.x % u_res, f.y, f.x / u_res);
    vec3 x = u_origin + (vec3(v) + 0.5) * u_voxel;
    vec3 g;
    for (int a = 0; a < 3; ++a) {
        ivec3 e = ivec3(0); e[a] = 1;
        g[a] = (smooth_at(v + e) - smooth_at(v - e)) / (2.0 * u_voxel);
    }
    float gl = length(g);
    vec3 n = gl > 0.0 ? g / gl : vec3(0.0);
    float d = texelFetch(u_sdf_raw, v, 0).r;
    vec3 xs = x - (d - RELIGHT_LIFT_VOXELS * u_voxel) * n;
    o_gain = vec4(relight_gain(xs, g, abs(d) <= RELIGHT_BAND_VOXELS * u_voxel), 1.0);
}

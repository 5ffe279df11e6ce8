#version 430
// Visible-share volume of the relighting (twin: render.relight.reference.share_volume_reference).
// An atlas of L slices side by side: fragment (i + L k, j) is voxel (i, j, k) (a data grid: no
// image-row flip), centre origin + (ijk + 0.5) w. Orientation: central differences of the smoothed
// SDF (texelFetch, clamped to the edge); visibility at the nearest surface point of the raw SDF,
// lifted, in a band around the surface (1 elsewhere).
// Injected: as relight_common.glsl, and RELIGHT_LIFT_VOXELS, RELIGHT_BAND_VOXELS.
#include "relight_common.glsl"
uniform sampler3D u_sdf_raw;
uniform sampler3D u_sdf_smooth;
uniform vec3 u_origin;
uniform float u_voxel;
uniform int u_res;
layout(location = 0) out vec4 o_share_a;
layout(location = 1) out vec4 o_share_b;

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
    float d = texelFetch(u_sdf_raw, v, 0).r;
    vec3 sa = vec3(1.0), sb = vec3(1.0);
    if (gl > 0.0 && abs(d) <= RELIGHT_BAND_VOXELS * u_voxel) {
        vec3 n = g / gl;
        vec3 xs = x - (d - RELIGHT_LIFT_VOXELS * u_voxel) * n;
        sa = relight_share(xs, n, 0);
        sb = relight_share(xs, n, 1);
    }
    o_share_a = vec4(sa, 1.0);
    o_share_b = vec4(sb, 1.0);
}

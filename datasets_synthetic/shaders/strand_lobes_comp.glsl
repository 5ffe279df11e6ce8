#version 430
// Radiance of every strand point towards the eye: the width-averaged R / TT / TRT lobes of Chiang
// et al. 2016 under L directional lights (+ the residual lobe and the diffuse multiple-scattering
// stand-in).  GLSL twin of render.shading.hair.fibre_radiance and
// datasets_synthetic.hair_shading.strand_radiance (float32; tests/datasets_synthetic/test_strand_gl.py).
// Constants injected from Python (datasets_synthetic.strand_gl.lobe_defines): LOCAL_SIZE, N_LIGHTS,
// N_NODES, NODE_H_LIST / NODE_W_LIST (Gauss-Legendre nodes and weights, sum w = 1), ETA, ALPHA_RAD,
// SIGMA_DEN (Chiang eq. 9's denominator); the per-light constants are in the Light records
// (strand_gl.light_records).
layout(local_size_x = LOCAL_SIZE) in;

#include "strand_points.glsl"
// per light: direction, power, 1 / v_p and the log normaliser of M_p (p = 0..3), azi = (1 / s, norm / s)
struct Light { vec4 dir; vec4 power; vec4 inv_v; vec4 log_c; vec4 azi; };
layout(std430, binding = 1) readonly buffer Lights { Light lights[]; };
layout(std430, binding = 2) readonly buffer Visibility { float vis[]; };  // (P, N_LIGHTS) row-major
layout(std430, binding = 3) writeonly buffer Radiance { vec4 radiance[]; };
layout(std430, binding = 6) readonly buffer List { uint list[]; };  // visible points (strand_deferred_comp.glsl)

uniform vec3 u_eye;
uniform int u_count;      // points to shade
uniform int u_use_list;   // 1: shade the points list[0 .. u_count - 1]; 0: the points 0 .. u_count - 1

const float PI = 3.14159265358979323846;
const float NODE_H[N_NODES] = NODE_H_LIST;
const float NODE_W[N_NODES] = NODE_W_LIST;
#include "strand_lobes.glsl"

void main() {
    int j = int(gl_GlobalInvocationID.x);
    if (j >= u_count) return;
    int i = u_use_list == 1 ? int(list[j]) : j;
    Point pt = pts[i];
    vec3 T = pt.tangent.xyz;
    vec3 wo = normalize(u_eye - pt.centre.xyz);
    vec3 sigma_a = sigma_a_from_colour(pt.colour.rgb);
    vec3 ms = max(pt.colour.rgb - back_albedo(sigma_a), 0.0) / PI;
    radiance[i] = vec4(strand_lobes(T, wo, sigma_a, ms, i * N_LIGHTS), 1.0);
}

#version 430
// Pass 2 (instanced path): one camera-facing square per slice record, 4-vertex strip.
#include "microfacet_common.glsl"
#include "microfacet_slice.glsl"
#include "microfacet_varyings.glsl"
layout(std430, binding = 2) readonly buffer Slices { Slice slices[]; };

void main() {
    Slice s = slices[gl_InstanceID];
    vec3 v, a, b;
    slice_frame(s.pos_s.xyz, v, a, b);
    vec2 hab = slice_half_extents(s.pos_s.xyz, v, a, b, s.pos_s.w);
    int cand[K_CAND] = int[K_CAND](s.c03.x, s.c03.y, s.c03.z, s.c03.w, s.c45.x, s.c45.y);
    set_corner(slice_corner(v, a, b, hab, s.pos_s.w, gl_VertexID), cand, s.weights.xyz);
}

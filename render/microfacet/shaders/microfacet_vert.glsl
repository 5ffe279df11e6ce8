#version 430
// Pass 2 (instanced path): one camera-facing rectangle per slice tile record, 4-vertex strip.
#include "microfacet_common.glsl"
#include "microfacet_slice.glsl"
#include "microfacet_varyings.glsl"
layout(std430, binding = 2) readonly buffer Slices { Slice slices[]; };
flat out int v_id;   // the record index (read by the visibility pre-pass)

void main() {
    Slice s = slices[gl_InstanceID];
    v_id = gl_InstanceID;
    vec3 v, a, b;
    slice_frame(s.pos_s.xyz, v, a, b);
    int cand[K_CAND] = int[K_CAND](s.c03.x, s.c03.y, s.c03.z, s.c03.w, s.c45.x, s.c45.y);
    set_corner(slice_corner(v, a, b, s.rect, s.pos_s.w, gl_VertexID), cand, s.weights.xyz);
}

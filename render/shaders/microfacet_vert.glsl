#version 430
// Pass 2 (instanced path): one camera-facing square per slice record, 4-vertex strip.
#include "microfacet_common.glsl"
#include "microfacet_slice.glsl"
layout(std430, binding = 2) readonly buffer Slices { Slice slices[]; };
uniform mat4 view_proj;
out vec3 v_world;
flat out ivec4 v_c03;
flat out ivec2 v_c45;
flat out vec3 v_w;
out vec3 v_proj[K_CAND];   // homogeneous projection into each candidate camera
flat out vec3 v_eye_proj[K_CAND];   // the eye's projection into each candidate (refine_colour)

void main() {
    Slice s = slices[gl_InstanceID];
    vec2 corner = vec2((gl_VertexID & 1) == 0 ? -1.0 : 1.0, (gl_VertexID & 2) == 0 ? -1.0 : 1.0);
    vec3 v, a, b;
    slice_frame(s.pos_s.xyz, v, a, b);
    vec2 hab = slice_half_extents(s.pos_s.xyz, v, a, b, s.pos_s.w);
    vec3 p = eye_pos + v * s.pos_s.w + corner.x * hab.x * a + corner.y * hab.y * b;
    v_world = p;
    v_c03 = s.c03;
    v_c45 = s.c45.xy;
    v_w = s.weights.xyz;
    int cand[K_CAND] = int[K_CAND](s.c03.x, s.c03.y, s.c03.z, s.c03.w, s.c45.x, s.c45.y);
    for (int k = 0; k < K_CAND; ++k) {
        v_proj[k] = cand[k] >= 0 ? cam_project_h(cand[k], p) : vec3(0.0);
        v_eye_proj[k] = cand[k] >= 0 ? cam_project_h(cand[k], eye_pos) : vec3(0.0);
    }
    gl_Position = view_proj * vec4(p, 1.0);
}

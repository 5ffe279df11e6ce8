#version 430
// Geometry-shader path: per voxel, camera selection and up to MAX_SLICES squares (§1.2-1.3).
layout(points) in;
layout(triangle_strip, max_vertices = MAX_VERTS) out;
#include "microfacet_common.glsl"
in vec3 g_center[];
uniform mat4 view_proj;
out vec3 v_world;
flat out ivec4 v_c03;
flat out ivec2 v_c45;
flat out vec3 v_w;
out vec3 v_proj[K_CAND];   // homogeneous projection into each candidate camera
flat out vec3 v_eye_proj[K_CAND];   // the eye's projection into each candidate (refine_colour)

void main() {
    vec3 c = g_center[0];
    int lo, hi;
    slice_range(c, lo, hi);
    if (hi < lo) return;
    int cand[K_CAND];
    float w[K_BLEND];
    select_cameras(c, FOOTPRINT_SCALE * 0.5 * SLICE_SIDE * voxel_size, cand, w);
    vec3 v, a, b;
    slice_frame(c, v, a, b);
    for (int n = lo; n <= hi; ++n) {
        vec3 q = eye_pos + v * (float(n) * spacing);
        vec2 hab = slice_half_extents(c, v, a, b, float(n) * spacing);
        for (int k = 0; k < 4; ++k) {
            vec2 corner = vec2((k & 1) == 0 ? -1.0 : 1.0, (k & 2) == 0 ? -1.0 : 1.0);
            vec3 p = q + corner.x * hab.x * a + corner.y * hab.y * b;
            v_world = p;
            v_c03 = ivec4(cand[0], cand[1], cand[2], cand[3]);
            v_c45 = ivec2(cand[4], cand[5]);
            v_w = vec3(w[0], w[1], w[2]);
            for (int j = 0; j < K_CAND; ++j) {
                v_proj[j] = cand[j] >= 0 ? cam_project_h(cand[j], p) : vec3(0.0);
                v_eye_proj[j] = cand[j] >= 0 ? cam_project_h(cand[j], eye_pos) : vec3(0.0);
            }
            gl_Position = view_proj * vec4(p, 1.0);
            EmitVertex();
        }
        EndPrimitive();
    }
}

#version 430
// Geometry-shader path: per voxel, camera selection and up to MAX_SLICES squares (§1.2-1.3).
layout(points) in;
layout(triangle_strip, max_vertices = MAX_VERTS) out;
#include "microfacet_common.glsl"
#include "microfacet_varyings.glsl"
in vec3 g_center[];

void main() {
    vec3 c = g_center[0];
    int lo, hi;
    int cand[K_CAND];
    float w[K_BLEND];
    if (!voxel_slices(c, lo, hi, cand, w)) return;
    vec3 v, a, b;
    slice_frame(c, v, a, b);
    for (int n = lo; n <= hi; ++n) {
        float s = float(n) * spacing;
        vec2 hab = slice_half_extents(c, v, a, b, s);
        for (int k = 0; k < 4; ++k) {
            set_corner(slice_corner(v, a, b, vec4(-hab.x, hab.x, -hab.y, hab.y), s, k), cand, vec3(w[0], w[1], w[2]));
            EmitVertex();
        }
        EndPrimitive();
    }
}

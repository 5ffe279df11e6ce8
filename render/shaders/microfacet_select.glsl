#version 430
// Pass 1 (instanced path): per surface voxel, camera selection and slice records (§1.2-1.3).
layout(local_size_x = 64) in;
#include "microfacet_common.glsl"
#include "microfacet_slice.glsl"
layout(std430, binding = 1) readonly buffer Voxels { vec4 centers[]; };
layout(std430, binding = 2) writeonly buffer Slices { Slice slices[]; };
layout(std430, binding = 3) buffer Indirect { uint vcount; uint icount; uint first_vertex; uint base_instance; };
uniform int n_voxels;
uniform uint max_records;

void main() {
    int id = int(gl_GlobalInvocationID.x);
    if (id >= n_voxels) return;
    vec3 c = centers[id].xyz;
    int lo, hi;
    int cand[K_CAND];
    float w[K_BLEND];
    if (!voxel_slices(c, lo, hi, cand, w)) return;
    uint cnt = uint(hi - lo + 1);
    uint base = atomicAdd(icount, cnt);
    for (uint k = 0u; k < cnt; ++k) {
        if (base + k >= max_records) break;
        Slice s;
        s.pos_s = vec4(c, float(lo + int(k)) * spacing);
        s.weights = vec4(w[0], w[1], w[2], 0.0);
        s.c03 = ivec4(cand[0], cand[1], cand[2], cand[3]);
        s.c45 = ivec4(cand[4], cand[5], id, lo + int(k));
        slices[base + k] = s;
    }
}

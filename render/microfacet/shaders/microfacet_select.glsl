#version 430
// Pass 1 (instanced path): per surface voxel, camera selection and slice records (§1.2-1.3);
// each slice split into G x G tiles of about tile_px drawn pixels, the tiles where no
// fragment can be drawn dropped (CULL 1; microfacet_cull.glsl; twin: microfacet_cull.select_tiles).
// CULL 0: one record per slice (the paper's slices).
layout(local_size_x = 64) in;
#include "microfacet_common.glsl"
#include "microfacet_slice.glsl"
#include "microfacet_cull.glsl"
layout(std430, binding = 1) readonly buffer Voxels { vec4 centers[]; };
layout(std430, binding = 2) writeonly buffer Slices { Slice slices[]; };
layout(std430, binding = 3) buffer Indirect { uint vcount; uint icount; uint first_vertex; uint base_instance; uint n_slices; };
uniform int n_voxels;
uniform uint max_records;
uniform float tile_px;     // target tile side in drawn pixels
uniform float eye_focal;   // drawn pixels per unit of depth

// Homogeneous projection (u z, v z, z) of a direction (no translation) into camera i.
vec3 cam_project_dir(int i, vec3 d) {
    vec4 q = vec4(d, 0.0);
    return vec3(dot(cams[i].proj[0], q), dot(cams[i].proj[1], q), dot(cams[i].proj[2], q));
}

void write_record(uint at, vec3 c, int id, int n, float s, vec4 rect, int cand[K_CAND], float w[K_BLEND]) {
    if (at >= max_records) return;
    Slice r;
    r.pos_s = vec4(c, s);
    r.weights = vec4(w[0], w[1], w[2], 0.0);
    r.c03 = ivec4(cand[0], cand[1], cand[2], cand[3]);
    r.c45 = ivec4(cand[4], cand[5], id, n);
    r.rect = rect;
    slices[at] = r;
}

void main() {
    int id = int(gl_GlobalInvocationID.x);
    if (id >= n_voxels) return;
    vec3 c = centers[id].xyz;
    int lo, hi;
    int cand[K_CAND];
    float w[K_BLEND];
    if (!voxel_slices(c, lo, hi, cand, w)) return;
    vec3 v, a, b;
    slice_frame(c, v, a, b);
    atomicAdd(n_slices, uint(hi - lo + 1));
#if CULL == 0
    // the paper's slices, one record each (contiguous per voxel, front to back)
    uint base = atomicAdd(icount, uint(hi - lo + 1));
    for (int n = lo; n <= hi; ++n) {
        float s = float(n) * spacing;
        vec2 hab = slice_half_extents(c, v, a, b, s);
        write_record(base + uint(n - lo), c, id, n, s, vec4(-hab.x, hab.x, -hab.y, hab.y), cand, w);
    }
#else
    vec3 pa[N_PROJ], pb[N_PROJ];   // the slice axes projected into the candidates shade() reads
    for (int j = 0; j < N_PROJ; ++j) {
        pa[j] = cand[j] >= 0 ? cam_project_dir(cand[j], a) : vec3(0.0);
        pb[j] = cand[j] >= 0 ? cam_project_dir(cand[j], b) : vec3(0.0);
    }
    float tol = 0.5 * spacing * (1.0 + TOL_MARGIN_REL) + TOL_MARGIN_ABS;
    for (int n = lo; n <= hi; ++n) {
        float s = float(n) * spacing;
        vec2 hab = slice_half_extents(c, v, a, b, s);
        int g = clamp(int(ceil(2.0 * max(hab.x, hab.y) * eye_focal / max(s, 1e-12) / tile_px)), 1, MAX_TILES);
        vec3 p0[N_PROJ];
        for (int j = 0; j < N_PROJ; ++j) p0[j] = cand[j] >= 0 ? eye_h[cand[j]].xyz + s * cam_project_dir(cand[j], v) : vec3(0.0);
        for (int ty = 0; ty < g; ++ty)
            for (int tx = 0; tx < g; ++tx) {
                vec4 rect = vec4(hab.x * (-1.0 + 2.0 * float(tx) / float(g)), hab.x * (-1.0 + 2.0 * float(tx + 1) / float(g)),
                                 hab.y * (-1.0 + 2.0 * float(ty) / float(g)), hab.y * (-1.0 + 2.0 * float(ty + 1) / float(g)));
                vec3 hs[N_PROJ][4];
                for (int j = 0; j < N_PROJ; ++j)
                    for (int k = 0; k < 4; ++k)
                        hs[j][k] = p0[j] + ((k & 1) == 0 ? rect.x : rect.y) * pa[j] + ((k & 2) == 0 ? rect.z : rect.w) * pb[j];
                if (tile_drawable(cand, w, hs, tol)) write_record(atomicAdd(icount, 1u), c, id, n, s, rect, cand, w);
            }
    }
#endif
}

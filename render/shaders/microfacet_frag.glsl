#version 430
// Per fragment: Eq. 2 in the candidate cameras, ULR blend, per-fragment fallback (§1.3-1.5).
#include "microfacet_common.glsl"
#include "microfacet_rgbz.glsl"
in vec3 v_world;
flat in ivec4 v_c03;
flat in ivec2 v_c45;
flat in vec3 v_w;
in vec3 v_proj[K_CAND];
out vec4 frag;

void main() {
    int cand[K_CAND];
    cand[0] = v_c03.x; cand[1] = v_c03.y; cand[2] = v_c03.z; cand[3] = v_c03.w;
    cand[4] = v_c45.x; cand[5] = v_c45.y;
    float w[K_BLEND];
    w[0] = v_w.x; w[1] = v_w.y; w[2] = v_w.z;
    vec3 col;
    vec3 proj[K_CAND];
    for (int k = 0; k < K_CAND; ++k) proj[k] = v_proj[k];
    if (!shade(proj, cand, w, 0.5 * spacing, col)) discard;
    frag = vec4(col, 1.0);
}

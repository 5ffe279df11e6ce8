#version 430
// Per fragment: Eq. 2 in the candidate cameras, ULR blend, per-fragment fallback (§1.3-1.5).
#include "microfacet_common.glsl"
#include "microfacet_rgbz.glsl"
in vec3 v_world;
flat in ivec4 v_c03;
flat in ivec2 v_c45;
flat in vec3 v_w;
in vec3 v_proj[K_CAND];
flat in vec3 v_eye_proj[K_CAND];
out vec4 frag;

void main() {
    vec3 col;
    if (!shade(v_proj[0], v_proj[1], v_proj[2], v_proj[3], v_proj[4], v_proj[5], v_eye_proj, v_c03, v_c45, v_w, 0.5 * spacing, col))
        discard;
    frag = vec4(col, 1.0);
}

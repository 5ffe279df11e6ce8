#version 430
// Per fragment: Eq. 2 in the candidate cameras, ULR blend, per-fragment fallback (§1.3-1.5).
#include "microfacet_common.glsl"
#include "microfacet_rgbz.glsl"
#include "microfacet_frag_in.glsl"
out vec4 frag;

void main() {
    vec3 col;
    if (!shade_fragment(col))
        discard;
    frag = vec4(col, 1.0);
}

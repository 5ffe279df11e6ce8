#version 430
// Visibility pre-pass (instanced path): the decision of microfacet_frag.glsl -- shade() with
// Eq. 2, the vote and the fallback -- compiled without the parallax refinement (it changes a
// drawn fragment's colour, never whether it is drawn) on the depth maps alone (DEPTH_ONLY).
// The nearest drawn fragment leaves its depth and its slice record index; the colour pass
// (microfacet_colour_frag.glsl) then shades each drawn sample once.
#include "microfacet_common.glsl"
#include "microfacet_rgbz.glsl"
#include "microfacet_frag_in.glsl"
flat in int v_id;
out float record;

void main() {
    COL col;
    int src;
    if (!shade_fragment(col, src))
        discard;
    record = float(v_id);
}

#version 430
// Per fragment: the same camera selection and ULR weights as the microfacet renderer
// (microfacet_common.glsl), a visibility test |d - D| < vis_tol in every candidate, blend of
// the visible blend cameras, else the first visible candidate, else the vertex colour.
#include "microfacet_common.glsl"
#include "microfacet_rgbz.glsl"
in vec3 v_world;
in vec3 v_color;
uniform float vis_tol;
out vec4 frag;

void main() {
    int cand[K_CAND];
    float w[K_BLEND];
    select_cameras(v_world, 0.0, cand, w);
    COL acc = COL(0.0);
    float wsum = 0.0;
    COL col = COL_OPAQUE(v_color);  // the vertex colour is opaque
    bool found = false;
    for (int k = 0; k < K_BLEND; ++k) {
        if (cand[k] < 0) break;
        COL c;
        if (rgbz_lookup(cand[k], v_world, vis_tol, c) == PASS) { acc += w[k] * c; wsum += w[k]; }
    }
    if (wsum > WEIGHT_EPS) { col = acc / wsum; found = true; }
    for (int k = 0; k < K_CAND && !found; ++k) {
        if (cand[k] < 0) break;
        COL c;
        if (rgbz_lookup(cand[k], v_world, vis_tol, c) == PASS) { col = c; found = true; }
    }
    frag = COL_RGBA(col);
}

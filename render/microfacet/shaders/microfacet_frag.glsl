#version 430
// Per fragment: Eq. 2 in the candidate cameras, ULR blend, per-fragment fallback (§1.3-1.5).
#include "microfacet_common.glsl"
#include "microfacet_rgbz.glsl"
#include "microfacet_frag_in.glsl"
out vec4 frag;

// DEBUG_VIEW (render.methods.RenderOptions.debug; twin: microfacet_geometry.debug_codes) writes a
// code in the red channel instead of the colour: 1 = the dominant camera index + 1 of each drawn
// fragment; 2 = 1 for a drawn fragment, 2 for one that Eq. 2 / the vote rejects, the rejected
// ones pushed behind everything drawn (DEBUG_BACK_DEPTH) so they show only where nothing passed.
void main() {
    COL col;
    int src;
    bool drawn = shade_fragment(col, src);
#if DEBUG_VIEW == 2
    frag = vec4(drawn ? 1.0 : 2.0, 0.0, 0.0, 1.0);
    gl_FragDepth = drawn ? gl_FragCoord.z : DEBUG_BACK_DEPTH;
#else
    if (!drawn)
        discard;
#if DEBUG_VIEW == 1
    frag = vec4(float(src + 1), 0.0, 0.0, 1.0);
#else
    frag = COL_RGBA(col);
#endif
#endif
}

// Exact culling of slice tiles (twin: render/microfacet/cull.py): a tile is kept when a
// fragment of it can be drawn by shade()'s rules, judged from the min / max pyramid of the
// candidates' depth maps.  Needs microfacet_common.glsl.  Defines: PIX_MARGIN, EMPTY_MIN,
// MAX_PYR_LEVELS, VOTE_MARGIN (and shade()'s FREE_FACTOR, ALPHA_VOTE, WEIGHT_EPS, FALLBACK_RULE).
layout(std430, binding = 4) readonly buffer DepthBounds { uint bounds[]; };  // packHalf2x16(min, max)
uniform int pyr_levels;                      // levels of the pyramid (the last one is 1 x 1)
uniform int pyr_offset[MAX_PYR_LEVELS];      // first word of each level (cameras, rows, columns)
uniform ivec2 depth_size;                    // W, H of every depth map

// Min / max valid depth of camera cam over the pixel box [lo, hi] (inclusive): at most
// BOUND_BLOCKS x BOUND_BLOCKS (3) blocks of the finest level where it spans no more (twin: block_bounds).
vec2 block_bounds(int cam, ivec2 lo, ivec2 hi) {
    int span = max(hi.x - lo.x, hi.y - lo.y);
    int k = span > 1 ? min(findMSB(span), pyr_levels - 1) : 0;
    ivec2 a = lo >> k, b = hi >> k;
    ivec2 dim = (depth_size + (1 << k) - 1) >> k;
    int base = pyr_offset[k] + cam * dim.x * dim.y;
    vec2 r = vec2(EMPTY_MIN, 0.0);
    for (int dy = 0; dy < BOUND_BLOCKS; ++dy)
        for (int dx = 0; dx < BOUND_BLOCKS; ++dx) {
            ivec2 q = min(a + ivec2(dx, dy), b);
            vec2 mm = unpackHalf2x16(bounds[base + q.y * dim.x + q.x]);
            r = vec2(min(r.x, mm.x), max(r.y, mm.y));
        }
    return r;
}

// What camera cam can say on the tile whose corners have the homogeneous projections h[0..3]
// in it (cam_project_h), Eq. 2 tolerance tol (margins included): x = it may pass Eq. 2 somewhere
// on it; y = it certainly sees through all of it (FREE: inside its image, and no depth or a
// depth at least FREE_FACTOR tol behind every point).  (twin: tiles_may_pass)
bvec2 tile_test(int cam, vec3 h[4], float tol) {
    float zmin = 1e30, zmax = -1e30;
    vec2 umin = vec2(1e30), umax = vec2(-1e30);
    for (int k = 0; k < 4; ++k) {
        if (h[k].z <= 0.0) return bvec2(true, false);
        vec2 uv = h[k].xy / h[k].z;
        umin = min(umin, uv);
        umax = max(umax, uv);
        zmin = min(zmin, h[k].z);
        zmax = max(zmax, h[k].z);
    }
    vec2 big = vec2(depth_size) + 1.0;   // clamped before the int conversion (huge near z = 0)
    ivec2 lo0 = ivec2(floor(clamp(umin, -2.0, big.x + big.y) + 0.5 - PIX_MARGIN));
    ivec2 hi0 = ivec2(floor(clamp(umax, -2.0, big.x + big.y) + 0.5 + PIX_MARGIN));
    ivec2 lo = max(lo0, ivec2(0)), hi = min(hi0, depth_size - 1);
    if (hi.x < lo.x || hi.y < lo.y) return bvec2(false);
    bool inside = lo == lo0 && hi == hi0;
    vec2 db = block_bounds(cam, lo, hi);
    return bvec2(db.y > zmin - tol && db.x < zmax + tol, inside && db.x >= zmax + FREE_FACTOR * tol);
}

// Can a fragment of the tile be drawn?  cand, w: the voxel's candidates and blend weights;
// hs[j]: the tile corners' projections in candidate j.  "vote" (FALLBACK_RULE 0): the blend
// cameras certain to see through the tile (weight F) outvote those that may pass it (weight P)
// when P (1 - ALPHA_VOTE) < ALPHA_VOTE F (the fallback then never runs: F > 0 is seen weight);
// else, and under "any", some blend or fallback camera must be able to pass.
bool tile_drawable(int cand[K_CAND], float w[K_BLEND], vec3 hs[N_PROJ][4], float tol) {
    float P = 0.0, F = 0.0;
    bool any_pass = false;
    for (int j = 0; j < N_PROJ; ++j) {
        if (cand[j] < 0) continue;
        bvec2 t = tile_test(cand[j], hs[j], tol);
        any_pass = any_pass || t.x;
        if (j < K_BLEND) {
            P += t.x ? w[j] : 0.0;
            F += t.y ? w[j] : 0.0;
        }
    }
#if FALLBACK_RULE == 0
    if (F > WEIGHT_EPS && P * (1.0 - ALPHA_VOTE) < ALPHA_VOTE * F - VOTE_MARGIN) return false;
#endif
    return any_pass;
}

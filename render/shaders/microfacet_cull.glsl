// Exact culling of slice tiles (twin: render/microfacet_cull.py): a tile is kept when one of
// the cameras that can draw a fragment may pass Eq. 2 on it, by the min / max pyramid of its
// depth map.  Needs microfacet_common.glsl.  Defines: PIX_MARGIN, EMPTY_MIN, MAX_PYR_LEVELS.
layout(std430, binding = 4) readonly buffer DepthBounds { uint bounds[]; };  // packHalf2x16(min, max)
uniform int pyr_levels;                      // levels of the pyramid (the last one is 1 x 1)
uniform int pyr_offset[MAX_PYR_LEVELS];      // first word of each level (cameras, rows, columns)
uniform ivec2 depth_size;                    // W, H of every depth map

// Min / max valid depth of camera cam over the pixel box [lo, hi] (inclusive): at most 2 x 2
// blocks of the level where the box spans less than two blocks (twin: block_bounds).
vec2 block_bounds(int cam, ivec2 lo, ivec2 hi) {
    int span = max(hi.x - lo.x, hi.y - lo.y);
    int k = span > 0 ? min(findMSB(span) + 1, pyr_levels - 1) : 0;
    ivec2 a = lo >> k, b = hi >> k;
    ivec2 dim = (depth_size + (1 << k) - 1) >> k;
    int base = pyr_offset[k] + cam * dim.x * dim.y;
    vec2 r = vec2(EMPTY_MIN, 0.0);
    for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx) {
            ivec2 q = min(a + ivec2(dx, dy), b);
            vec2 mm = unpackHalf2x16(bounds[base + q.y * dim.x + q.x]);
            r = vec2(min(r.x, mm.x), max(r.y, mm.y));
        }
    return r;
}

// May camera cam pass Eq. 2 (tolerance tol, margins included) on the tile whose corners have
// the homogeneous projections h[0..3] in it (cam_project_h)?  (twin: tiles_may_pass)
bool tile_may_pass(int cam, vec3 h[4], float tol) {
    float zmin = 1e30, zmax = -1e30;
    vec2 umin = vec2(1e30), umax = vec2(-1e30);
    for (int k = 0; k < 4; ++k) {
        if (h[k].z <= 0.0) return true;
        vec2 uv = h[k].xy / h[k].z;
        umin = min(umin, uv);
        umax = max(umax, uv);
        zmin = min(zmin, h[k].z);
        zmax = max(zmax, h[k].z);
    }
    vec2 big = vec2(depth_size) + 1.0;   // clamped before the int conversion (huge near z = 0)
    ivec2 lo = max(ivec2(floor(clamp(umin, -2.0, big.x + big.y) + 0.5 - PIX_MARGIN)), ivec2(0));
    ivec2 hi = min(ivec2(floor(clamp(umax, -2.0, big.x + big.y) + 0.5 + PIX_MARGIN)), depth_size - 1);
    if (hi.x < lo.x || hi.y < lo.y) return false;
    vec2 db = block_bounds(cam, lo, hi);
    return db.y > zmin - tol && db.x < zmax + tol;
}

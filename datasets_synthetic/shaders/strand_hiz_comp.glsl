#version 430
// The farthest window depth of each TILE x TILE tile of a depth buffer holding the surfaces only
// (strand_ribbon_geom.glsl skips the strand strips behind them).  One invocation per tile.
layout(local_size_x = 8, local_size_y = 8) in;
layout(std430, binding = 11) writeonly buffer Tiles { float tile_max[]; };
uniform sampler2D u_depth;
uniform ivec2 u_tiles;

void main() {
    ivec2 t = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(t, u_tiles))) return;
    ivec2 size = textureSize(u_depth, 0);
    ivec2 p0 = t * TILE;
    ivec2 p1 = min(p0 + TILE, size);
    float m = 0.0;
    for (int y = p0.y; y < p1.y; ++y)
        for (int x = p0.x; x < p1.x; ++x) m = max(m, texelFetch(u_depth, ivec2(x, y), 0).r);
    tile_max[t.y * u_tiles.x + t.x] = m;
}

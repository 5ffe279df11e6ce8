#version 430
// A segment between two rings -> the tube's facets on the side facing the viewer (or the light):
// a strip over the front chain's ring vertices (strand_ribbon.glsl front_chain), each vertex at the
// tube vertex's exact position with its normal, so the strip covers what the tube covers, with the
// tube's depth and interpolated normals, in ceil(sides / 2) + 1 or fewer quads instead of sides.
// With u_hiz = 1 a strip wholly behind the surfaces already drawn is not emitted: its nearest
// window depth is beyond the farthest surface depth of every TILE x TILE tile its screen box
// touches (strand_hiz_comp.glsl; what the depth test would reject, without the cost of setting
// up its triangles).
layout(lines) in;
layout(triangle_strip, max_vertices = MAX_STRIP_VERTICES) out;
#include "strand_ribbon.glsl"

in VS {
    vec3 centre;
    vec3 tangent;
    vec3 frame;
    vec3 colour;
    float r;
    float occl;
    float spec;
    flat ivec2 silhouette;
    flat int sides;
    flat int index;
} gs_in[];

#if HAIR_KK
// the dominant lights' visibility at every ring vertex, from the ring's first row (strand_gl._visibility)
layout(std430, binding = 9) readonly buffer RingVisibility { vec4 ring_vis[]; };
layout(std430, binding = 10) readonly buffer RingStart { uint ring_start[]; };
out vec4 g_vis;
#endif
layout(std430, binding = 11) readonly buffer Tiles { float tile_max[]; };  // farthest surface depth per tile

uniform mat4 u_view;   // world -> GL eye (identity for a shadow map)
uniform mat4 u_proj;   // GL eye -> clip (the light's view-projection for a shadow map)
uniform int u_hiz;     // 1: skip strips behind the surfaces' tiles
uniform ivec2 u_tiles; // tile grid (columns, rows)
uniform vec2 u_viewport;

out vec3 g_world;
out vec3 g_normal;
out vec3 g_tangent;
out vec3 g_colour;     // per-point albedo, occlusion, specular (kajiya-kay)
out float g_occl;
out float g_spec;
out float g_t;         // 0 at the first point, 1 at the second
out float g_eyez;      // z-depth (m)
flat out ivec2 g_points;
flat out int g_segment;   // the segment (line primitive) index

vec3 corner_world(int e, int k) {
    return gs_in[e].centre + gs_in[e].r * ring_direction(gs_in[e].tangent, gs_in[e].frame, k, gs_in[0].sides);
}

// True when every corner of the strip is in front of the camera and farther than the farthest
// surface sample of each tile under the strip's screen box.
bool behind_surfaces(ivec2 chain) {
    int n = gs_in[0].sides;
    vec2 lo = vec2(1e30), hi = vec2(-1e30);
    float zmin = 1e30;
    for (int j = 0; j < chain.y; ++j) {
        for (int e = 0; e < 2; ++e) {
            vec4 c = u_proj * (u_view * vec4(corner_world(e, (chain.x + j) % n), 1.0));
            if (c.w <= 0.0) return false;
            vec3 ndc = c.xyz / c.w;
            vec2 win = (ndc.xy * 0.5 + 0.5) * u_viewport;
            lo = min(lo, win);
            hi = max(hi, win);
            zmin = min(zmin, ndc.z * 0.5 + 0.5);
        }
    }
    ivec2 t0 = clamp(ivec2(floor(lo / float(TILE))), ivec2(0), u_tiles - 1);
    ivec2 t1 = clamp(ivec2(floor(hi / float(TILE))), ivec2(0), u_tiles - 1);
    if ((t1.x - t0.x + 1) * (t1.y - t0.y + 1) > MAX_TILES_TESTED) return false;
    float far_surface = 0.0;
    for (int ty = t0.y; ty <= t1.y; ++ty)
        for (int tx = t0.x; tx <= t1.x; ++tx) far_surface = max(far_surface, tile_max[ty * u_tiles.x + tx]);
    return zmin > far_surface + HIZ_EPS;
}

void corner(int e, int k) {
    int n = gs_in[0].sides;
    vec3 d = ring_direction(gs_in[e].tangent, gs_in[e].frame, k, n);
    g_world = gs_in[e].centre + gs_in[e].r * d;
    g_normal = d;
    g_tangent = gs_in[e].tangent;
    g_colour = gs_in[e].colour;
    g_occl = gs_in[e].occl;
    g_spec = gs_in[e].spec;
    g_t = float(e);
    g_points = ivec2(gs_in[0].index, gs_in[1].index);
    g_segment = gl_PrimitiveIDIn;
#if HAIR_KK
    g_vis = ring_vis[ring_start[gs_in[e].index] + uint(k)];
#endif
    vec4 eye = u_view * vec4(g_world, 1.0);
    g_eyez = -eye.z;
    gl_Position = u_proj * eye;
    EmitVertex();
}

void main() {
    int n = gs_in[0].sides;
    ivec2 chain = front_chain(gs_in[0].silhouette, gs_in[1].silhouette, n);
    if (u_hiz == 1 && behind_surfaces(chain)) return;
    for (int j = 0; j < chain.y; ++j) {
        int k = (chain.x + j) % n;
        corner(1, k);   // this order splits each facet along (ring 0, k) - (ring 1, k + 1), as tube_sweep does
        corner(0, k);
    }
    EndPrimitive();
}

#version 430
// A segment between two rings -> the tube's facets on the side facing the viewer (or the light):
// a strip over the front chain's ring vertices (strand_ribbon.glsl front_chain), each vertex at the
// tube vertex's exact position with its normal, so the strip covers what the tube covers, with the
// tube's depth and interpolated normals, in ceil(sides / 2) + 1 or fewer quads instead of sides.
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

uniform mat4 u_view;   // world -> GL eye (identity for a shadow map)
uniform mat4 u_proj;   // GL eye -> clip (the light's view-projection for a shadow map)

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
    for (int j = 0; j < chain.y; ++j) {
        int k = (chain.x + j) % n;
        corner(1, k);   // this order splits each facet along (ring 0, k) - (ring 1, k + 1), as tube_sweep does
        corner(0, k);
    }
    EndPrimitive();
}

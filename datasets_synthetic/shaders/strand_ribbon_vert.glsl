#version 430
// Strand pass of the GL synthetic renderer (datasets_synthetic/strand_gl.py): one vertex per strand
// point (gl_VertexID = the point, from the segment index buffer) with its ring's silhouette
// vertices seen from the camera (u_ortho = 0) or along a shadow map's light direction (u_ortho = 1).
#include "strand_points.glsl"
#include "strand_ribbon.glsl"

uniform vec3 u_eye;         // camera centre, world (u_ortho = 0)
uniform vec3 u_light_dir;   // unit, towards the light (u_ortho = 1)
uniform int u_ortho;

out VS {
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
} vs;

void main() {
    int i = gl_VertexID;
    Point p = pts[i];
    vec3 c = p.centre.xyz;
    vec3 w_dir = u_ortho == 1 ? u_light_dir : normalize(u_eye - c);
    vs.sides = int(p.tangent.w + 0.5);
    vs.silhouette = silhouette_vertices(p.tangent.xyz, p.frame.xyz, vs.sides, w_dir);
    vs.centre = c;
    vs.tangent = p.tangent.xyz;
    vs.frame = p.frame.xyz;
    vs.colour = p.colour.rgb;
    vs.r = p.centre.w;
    vs.occl = p.colour.w;
    vs.spec = p.frame.w;
    vs.index = i;
    gl_Position = vec4(c, 1.0);
}

#version 430
// Ground shadow ratio (docs/methods.md §3; seed 004 Eq. 16-17) on a grid of the ground plane z = u_plane_z:
// ratio = sum_k mu'_k f_h(min(SSDF_spheres, SSDF_ground), lambda'_k) / sum_k mu'_k f_h(SSDF_ground, lambda'_k)
// with (axis', lambda', mu') = lighting SG k times the clamped-cosine SG at the up normal.
// Twin of render.composite.ground_shadow.shadow_ratio. Grid texel (i, j) = framebuffer pixel (i, j) (a data grid:
// no image-row flip), world point = origin + (ij + 0.5) * cell.
#include "shading_sg.glsl"
#include "shading_ssdf.glsl"
#ifndef MAX_SG
#define MAX_SG 128
#endif
uniform vec2 u_grid_origin;   // world xy of the grid's min corner
uniform vec2 u_grid_cell;     // world size of one texel
uniform float u_plane_z;
uniform int u_sg_count;
uniform vec3 u_sg_axis[MAX_SG];
uniform float u_sg_lambda[MAX_SG];
uniform vec3 u_sg_mu[MAX_SG];
out vec4 o_ratio;

void main() {
    vec3 x = vec3(u_grid_origin + (floor(gl_FragCoord.xy) + 0.5) * u_grid_cell, u_plane_z);
    vec3 n = vec3(0.0, 0.0, 1.0);
    SG cosl; cosl.axis = n; cosl.lambda = SG_COS_LAMBDA; cosl.mu = vec3(SG_COS_MU);
    vec3 occ = vec3(0.0), unocc = vec3(0.0);
    for (int k = 0; k < u_sg_count; ++k) {
        SG l; l.axis = u_sg_axis[k]; l.lambda = u_sg_lambda[k]; l.mu = u_sg_mu[k];
        SG p = sg_product(l, cosl);
        float tg = ssdf_ground(p.axis);
        float ts = min(ssdf_from_spheres(x, n, p.axis), tg);
        occ += p.mu * sg_fh(ts, p.lambda);
        unocc += p.mu * sg_fh(tg, p.lambda);
    }
    vec3 r = vec3(1.0);
    for (int c = 0; c < 3; ++c) if (unocc[c] > 0.0) r[c] = occ[c] / unocc[c];
    o_ratio = vec4(r, 1.0);
}

#version 430
// Colour pass (instanced path, after microfacet_prepass_frag.glsl): once per drawn sample, the
// fragment of the slice record the pre-pass left there -- the intersection of the sample's ray
// with that slice's plane (the ray caster's point, render/microfacet/reference.py) -- coloured
// by shade() with the parallax refinement.
#include "microfacet_common.glsl"
#include "microfacet_rgbz.glsl"
#include "microfacet_slice.glsl"
layout(std430, binding = 2) readonly buffer Slices { Slice slices[]; };
uniform sampler2D records;    // record index per sample (pre-pass)
uniform mat4 view_proj;       // of the drawn (supersampled) eye
uniform vec2 target_size;     // drawn width, height
out vec4 frag;

void main() {
    Slice r = slices[int(texelFetch(records, ivec2(gl_FragCoord.xy), 0).r)];
    // the ray through the sample: the two clip planes x = ndc.x w and y = ndc.y w meet on it
    vec2 ndc = 2.0 * gl_FragCoord.xy / target_size - 1.0;
    mat4 m = transpose(view_proj);
    vec3 d = cross((m[0] - ndc.x * m[3]).xyz, (m[1] - ndc.y * m[3]).xyz);
    if (dot(d, m[3].xyz) < 0.0) d = -d;   // m[3]: the eye's depth row
    vec3 v = normalize(r.pos_s.xyz - eye_pos);   // the slice normal (slice_frame)
    vec3 p = eye_pos + (r.pos_s.w / dot(d, v)) * d;
    int cand[K_CAND] = int[K_CAND](r.c03.x, r.c03.y, r.c03.z, r.c03.w, r.c45.x, r.c45.y);
    vec3 pr[K_CAND], e[K_CAND];
    for (int j = 0; j < K_CAND; ++j) {   // (the candidates past N_PROJ are never read)
        pr[j] = cand[j] >= 0 ? cam_project_h(cand[j], p) : vec3(0.0);
        e[j] = cand[j] >= 0 ? eye_h[cand[j]].xyz : vec3(0.0);
    }
    COL col;
    int src;
    shade(pr[0], pr[1], pr[2], pr[3], pr[4], pr[5], e, r.c03, r.c45.xy, r.weights.xyz, 0.5 * spacing, col, src);
    frag = COL_RGBA(col);
}

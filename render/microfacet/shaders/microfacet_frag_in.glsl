// Inputs of the slice fragment shaders (microfacet_frag.glsl, microfacet_prepass_frag.glsl) and
// shade() on them (microfacet_rgbz.glsl; the candidates past N_PROJ are never read).
in vec3 v_proj[N_PROJ];
flat in ivec4 v_c03;
flat in ivec2 v_c45;
flat in vec3 v_w;
flat in vec3 v_eye_proj[N_PROJ];

bool shade_fragment(out COL col, out int src) {
    vec3 p[K_CAND], e[K_CAND];
    for (int j = 0; j < K_CAND; ++j) {
        p[j] = j < N_PROJ ? v_proj[min(j, N_PROJ - 1)] : vec3(0.0);
        e[j] = j < N_PROJ ? v_eye_proj[min(j, N_PROJ - 1)] : vec3(0.0);
    }
    return shade(p[0], p[1], p[2], p[3], p[4], p[5], e, v_c03, v_c45, v_w, 0.5 * spacing, col, src);
}

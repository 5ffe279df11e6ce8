// The slice corners of the two slice-generation paths (microfacet_vert.glsl: instancing,
// microfacet_geom.glsl: geometry shader), read by microfacet_frag.glsl.
uniform mat4 view_proj;
out vec3 v_world;
flat out ivec4 v_c03;
flat out ivec2 v_c45;
flat out vec3 v_w;
// N_PROJ = K_BLEND + N_FALLBACK: the candidates shade() can read (the others are never projected)
out vec3 v_proj[N_PROJ];   // homogeneous projection into each candidate camera
flat out vec3 v_eye_proj[N_PROJ];   // the eye's projection into each candidate (refine_colour)

// Corner k (0..3, triangle-strip order) of the rectangle rect = (x0, x1, y0, y1) (metres along
// a, b) of the slice at distance s in the slice frame (v, a, b) of its voxel (slice_frame; the
// whole slice is (-ha, ha, -hb, hb), slice_half_extents).
vec3 slice_corner(vec3 v, vec3 a, vec3 b, vec4 rect, float s, int k) {
    return eye_pos + v * s + ((k & 1) == 0 ? rect.x : rect.y) * a + ((k & 2) == 0 ? rect.z : rect.w) * b;
}

// Set the outputs of the slice corner p with the candidates cand and blend weights w.
void set_corner(vec3 p, int cand[K_CAND], vec3 w) {
    v_world = p;
    v_c03 = ivec4(cand[0], cand[1], cand[2], cand[3]);
    v_c45 = ivec2(cand[4], cand[5]);
    v_w = w;
#ifndef FILL_ONLY
    for (int j = 0; j < N_PROJ; ++j) {
        v_proj[j] = cand[j] >= 0 ? cam_project_h(cand[j], p) : vec3(0.0);
        v_eye_proj[j] = cand[j] >= 0 ? eye_h[cand[j]].xyz : vec3(0.0);
    }
#endif
    gl_Position = view_proj * vec4(p, 1.0);
}

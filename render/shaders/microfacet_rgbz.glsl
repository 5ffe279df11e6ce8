// RGBz lookup and Eq. 2 (METHODS §1.4).  Twin: microfacet_geometry.sample_rgbz / eq2_pass.
uniform sampler2DArray rgbz;   // layer i: rgb linear + z-depth (m, 0 = none) of camera i

// Colour of world point p in camera i, or false when Eq. 2 rejects it (|d - D| >= tol).
bool rgbz_lookup(int i, vec3 p, float tol, out vec3 col) {
    vec3 uvz = cam_project(i, p);
    col = vec3(0.0);
    if (uvz.z <= 0.0) return false;
    ivec2 ij = ivec2(floor(uvz.xy + 0.5));
    if (ij.x < 0 || ij.y < 0 || ij.x >= int(cams[i].size.x) || ij.y >= int(cams[i].size.y)) return false;
    vec4 t = texelFetch(rgbz, ivec3(ij, i), 0);
    if (!(t.a > 0.0) || abs(t.a - uvz.z) >= tol) return false;
    col = t.rgb;
    return true;
}

// Blend the passing blend cameras by weight; else the first passing candidate (fallback).
bool shade(vec3 p, int cand[K_CAND], float wts[K_BLEND], float tol, out vec3 colour) {
    vec3 acc = vec3(0.0);
    float wsum = 0.0;
    bool have_first = false;
    vec3 first = vec3(0.0);
    for (int k = 0; k < K_CAND; ++k) {
        int ci = cand[k];
        if (ci < 0) break;
        if (k >= K_BLEND && (wsum > WEIGHT_EPS || have_first)) break;
        vec3 c;
        if (rgbz_lookup(ci, p, tol, c)) {
            if (k < K_BLEND) { acc += wts[k] * c; wsum += wts[k]; }
            if (!have_first) { first = c; have_first = true; }
        }
    }
    colour = wsum > WEIGHT_EPS ? acc / wsum : first;
    return wsum > WEIGHT_EPS || have_first;
}

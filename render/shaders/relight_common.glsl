// Relighting transfer and gain (issue 15; METHODS §3). Twin of render/shading/relight.py
// (transfer, visible_share, gain_from_transfers). Per lighting (A = the capture's, B = the new):
// a transfer table (RGB32F equirect in the map's frame, LINEAR, repeat_x; lookup at u_to_env * n),
// K SG lobes in world coordinates, its reference transfer. Spheres for the SSDF: the SSBO of
// shading_ssdf.glsl (u_ssdf_count = 0: no visibility).
// Injected: MAX_SG (lobes per lighting), RELIGHT_MIN_GRADIENT (render.shading.relight.MIN_GRADIENT).
#include "shading_envmap.glsl"
#include "shading_sg.glsl"
#include "shading_ssdf.glsl"
uniform sampler2D u_table_a;
uniform sampler2D u_table_b;
uniform mat3 u_to_env;
uniform int u_sg_count_a;
uniform int u_sg_count_b;
uniform vec3 u_sg_axis_a[MAX_SG];
uniform float u_sg_lambda_a[MAX_SG];
uniform vec3 u_sg_mu_a[MAX_SG];
uniform vec3 u_sg_axis_b[MAX_SG];
uniform float u_sg_lambda_b[MAX_SG];
uniform vec3 u_sg_mu_b[MAX_SG];
uniform vec3 u_ref_a;
uniform vec3 u_ref_b;
uniform vec3 u_global_gain;
uniform float u_regularise;
uniform float u_max_gain;

// share of one lobe's light left visible at x (SSDF model), relative to nothing in the way
float relight_lobe_share(vec3 x, vec3 n, SG p) {
    float t = ssdf_from_spheres(x, n, p.axis);
    return sg_fh(t, p.lambda) / sg_fh(SSDF_MAX, p.lambda);
}

// visible share S(x) of lighting A (which = 0) or B (which = 1)
vec3 relight_share(vec3 x, vec3 n, int which) {
    if (u_ssdf_count == 0) return vec3(1.0);
    SG cosl; cosl.axis = n; cosl.lambda = SG_COS_LAMBDA; cosl.mu = vec3(SG_COS_MU);
    vec3 num = vec3(0.0), den = vec3(0.0);
    int count = which == 0 ? u_sg_count_a : u_sg_count_b;
    for (int k = 0; k < count; ++k) {
        SG l;
        l.axis = which == 0 ? u_sg_axis_a[k] : u_sg_axis_b[k];
        l.lambda = which == 0 ? u_sg_lambda_a[k] : u_sg_lambda_b[k];
        l.mu = which == 0 ? u_sg_mu_a[k] : u_sg_mu_b[k];
        SG p = sg_product(l, cosl);
        vec3 w = sg_integral(p);
        num += w * relight_lobe_share(x, n, p);
        den += w;
    }
    vec3 s;
    for (int c = 0; c < 3; ++c) s[c] = den[c] > 0.0 ? num[c] / den[c] : 1.0;
    return s;
}

// gain from A to B at x (visibility point xs; no visibility unless `visible`) with SDF gradient g
// (any length)
vec3 relight_gain(vec3 xs, vec3 g, bool visible) {
    float gl = length(g);
    if (!(gl > RELIGHT_MIN_GRADIENT)) return u_global_gain;
    vec3 n = g / gl;
    vec3 e = u_to_env * n;
    vec3 ta = texture(u_table_a, env_dir_to_uv(e)).rgb;
    vec3 tb = texture(u_table_b, env_dir_to_uv(e)).rgb;
    if (visible) {
        ta *= relight_share(xs, n, 0);
        tb *= relight_share(xs, n, 1);
    }
    vec3 den = ta + u_regularise * u_ref_a;
    vec3 num = tb + u_regularise * u_ref_b;
    vec3 q;
    for (int c = 0; c < 3; ++c) q[c] = den[c] > 0.0 ? num[c] / den[c] : u_global_gain[c];
    return clamp(q, vec3(0.0), u_max_gain * u_global_gain);
}

// Relighting transfer and gain (issue 15; docs/methods.md §3). Twin of render/shading/transfer.py
// (visible_share, unoccluded_transfer, forward_transfer, relight_gain). Per lighting (A = the
// capture's, B = the new): a transfer table (RGB32F equirect in the map's frame, LINEAR, repeat_x;
// lookup at u_to_env * n), K SG lobes in world coordinates, its reference transfer. Spheres for the
// SSDF: the SSBO of shading_ssdf.glsl (u_ssdf_count = 0: no visibility).
// Injected: MAX_SG (lobes per lighting), RELIGHT_MIN_GRADIENT (MIN_GRADIENT), RELIGHT_KERNEL
// (0 lambert, 1 fur, 2 half-lambert, 3 wrap: KERNELS; 4 a mix, its weights RELIGHT_KERNEL_W, a vec4),
// RELIGHT_FORWARD_G (FORWARD_G).
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
uniform float u_forward;
uniform float u_regularise;
uniform float u_max_gain;

SG relight_lobe(int which, int k) {
    SG l;
    l.axis = which == 0 ? u_sg_axis_a[k] : u_sg_axis_b[k];
    l.lambda = which == 0 ? u_sg_lambda_a[k] : u_sg_lambda_b[k];
    l.mu = which == 0 ? u_sg_mu_a[k] : u_sg_mu_b[k];
    return l;
}

int relight_lobe_count(int which) { return which == 0 ? u_sg_count_a : u_sg_count_b; }

float relight_kernel(float c) {
#if RELIGHT_KERNEL == 0
    return max(c, 0.0);
#elif RELIGHT_KERNEL == 1
    return sqrt(max(1.0 - min(c * c, 1.0), 0.0));
#elif RELIGHT_KERNEL == 2
    float h = 0.5 * (clamp(c, -1.0, 1.0) + 1.0);
    return h * h;
#elif RELIGHT_KERNEL == 3
    return max(c + 0.5, 0.0) / 1.5;
#else
    // mix: weights of lambert, wrap, half-lambert, uniform (transfer.MIX_BASIS)
    float h = 0.5 * (clamp(c, -1.0, 1.0) + 1.0);
    return dot(RELIGHT_KERNEL_W, vec4(max(c, 0.0), max(c + 0.5, 0.0) / 1.5, h * h, 1.0));
#endif
}

// visible share S(x) of lighting `which` (0 = A, 1 = B) at x with unit orientation n
vec3 relight_share(vec3 x, vec3 n, int which) {
    if (u_ssdf_count == 0) return vec3(1.0);
    SG cosl; cosl.axis = n; cosl.lambda = SG_COS_LAMBDA; cosl.mu = vec3(SG_COS_MU);
    vec3 num = vec3(0.0), den = vec3(0.0);
    for (int k = 0; k < relight_lobe_count(which); ++k) {
        SG p = sg_product(relight_lobe(which, k), cosl);
        vec3 w = sg_integral(p);
        num += w * (sg_fh(ssdf_from_spheres(x, n, p.axis), p.lambda) / sg_fh(SSDF_MAX, p.lambda));
        den += w;
    }
    vec3 s;
    for (int c = 0; c < 3; ++c) s[c] = den[c] > 0.0 ? num[c] / den[c] : 1.0;
    return s;
}

// forward-scattered transfer F(n, v): the lobes as lights, kernel x Henyey-Greenstein (mean 1)
vec3 relight_forward(int which, vec3 n, vec3 v) {
    const float g = RELIGHT_FORWARD_G;
    vec3 f = vec3(0.0);
    for (int k = 0; k < relight_lobe_count(which); ++k) {
        SG l = relight_lobe(which, k);
        float c = -dot(v, l.axis);
        float hg = (1.0 - g * g) / pow(1.0 + g * g - 2.0 * g * c, 1.5);
        f += sg_integral(l) * relight_kernel(dot(n, l.axis)) * hg;
    }
    return f;
}

// gain from A to B for SDF gradient g (any length), unit view v (to the camera), visible shares
vec3 relight_gain(vec3 g, vec3 v, vec3 share_a, vec3 share_b) {
    float gl = length(g);
    if (!(gl > RELIGHT_MIN_GRADIENT)) return u_global_gain;
    vec3 n = g / gl;
    vec3 e = u_to_env * n;
    vec3 ta = texture(u_table_a, env_dir_to_uv(e)).rgb;
    vec3 tb = texture(u_table_b, env_dir_to_uv(e)).rgb;
    if (u_forward != 0.0) {
        ta += u_forward * relight_forward(0, n, v);
        tb += u_forward * relight_forward(1, n, v);
    }
    vec3 den = ta * share_a + u_regularise * (1.0 + u_forward) * u_ref_a;
    vec3 num = tb * share_b + u_regularise * (1.0 + u_forward) * u_ref_b;
    vec3 q;
    for (int c = 0; c < 3; ++c) q[c] = den[c] > 0.0 ? num[c] / den[c] : u_global_gain[c];
    return clamp(q, vec3(0.0), u_max_gain * u_global_gain);
}

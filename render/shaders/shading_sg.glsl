// Spherical Gaussians (docs/methods.md §3). Twin of render/shading/sg.py (same formulas, float32).
// G(i) = mu * exp(lambda * (i.p - 1)); 1 - i.p is computed as |i - p|^2 / 2.
#ifndef FURROW_SHADING_SG_GLSL
#define FURROW_SHADING_SG_GLSL
// Injected from render.shading.sg (render/gl.py TWIN_CONSTANTS): SG_COS_LAMBDA, SG_COS_MU (the
// clamped cosine as one SG: COS_LOBE_LAMBDA / _MU) and SG_PRODUCT_AXIS_EPS (PRODUCT_AXIS_EPS).
const float SG_PI = 3.14159265358979323846;

struct SG { vec3 axis; float lambda; vec3 mu; };

float sg_one_minus_dot(vec3 a, vec3 b) { vec3 d = a - b; return 0.5 * dot(d, d); }

vec3 sg_eval(SG g, vec3 dir) { return g.mu * exp(-g.lambda * sg_one_minus_dot(dir, g.axis)); }

// -expm1(-x) / x, stable for small x
float sg_one_minus_exp_over_x(float x) {
    // series below 0.1 (truncation < x^5/720 ~ 1.4e-8): 1 - exp(-x) cancels in float32
    return (x < 0.1) ? 1.0 - x * (0.5 - x * (1.0 / 6.0 - x * (1.0 / 24.0 - x / 120.0)))
                     : (1.0 - exp(-x)) / x;
}

SG sg_product(SG a, SG b) {
    vec3 v = a.lambda * a.axis + b.lambda * b.axis;
    float lam = length(v);
    float s = a.lambda + b.lambda;
    SG r;
    bool small = lam <= SG_PRODUCT_AXIS_EPS * s;
    r.axis = small ? a.axis : v / lam;
    r.lambda = small ? 0.0 : lam;
    float denom = r.lambda + s;
    float expo = denom > 0.0 ? -2.0 * a.lambda * b.lambda * sg_one_minus_dot(a.axis, b.axis) / denom : 0.0;
    r.mu = a.mu * b.mu * exp(expo);
    return r;
}

vec3 sg_integral(SG g) { return 4.0 * SG_PI * sg_one_minus_exp_over_x(2.0 * g.lambda) * g.mu; }

float sg_hemi_integral(float lambda) { return 2.0 * SG_PI * sg_one_minus_exp_over_x(lambda); }

vec3 sg_inner_product(SG a, SG b) { return sg_integral(sg_product(a, b)); }

// diffuse irradiance of one lighting SG at unit normal n (cosine as one SG)
vec3 sg_irradiance(SG light, vec3 n) {
    SG c; c.axis = n; c.lambda = SG_COS_LAMBDA; c.mu = vec3(SG_COS_MU);
    return sg_inner_product(light, c);
}

#ifdef SG_FH_TABLE
// f_h(theta_d, lambda) from the fitted table (render.shading.sg.fh_table uploaded by
// fh_texture(): R32F, width = warped theta_d nodes, height = log10 lambda nodes, LINEAR, clamp).
uniform sampler2D u_fh_table;
uniform vec4 u_fh_params;  // (log10 lambda min, log10 lambda max, warp Y, unused)
float sg_fh(float theta_d, float lambda) {
    ivec2 sz = textureSize(u_fh_table, 0);
    float td = clamp(theta_d, -0.5 * SG_PI, 0.5 * SG_PI);
    float w = clamp(sin(td) * max(1.0, sqrt(lambda) / u_fh_params.z), -1.0, 1.0);
    float ll = clamp(log(max(lambda, 1e-30)) / log(10.0), u_fh_params.x, u_fh_params.y);
    float x = (w + 1.0) * 0.5 * float(sz.x - 1);
    float y = (ll - u_fh_params.x) / (u_fh_params.y - u_fh_params.x) * float(sz.y - 1);
    float ratio = texture(u_fh_table, (vec2(x, y) + 0.5) / vec2(sz)).r;
    return ratio * sg_hemi_integral(lambda);
}
#endif
#endif

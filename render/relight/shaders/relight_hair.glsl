// Strand transfer of the relighting (issue 23; twins: render/shading/hair_transfer.py hair_gain and
// render/relight/strands.py principal_direction). Included after relight_common.glsl (its SG lobes,
// u_global_gain, u_regularise, u_max_gain); u_hair_ref_a/b: hair_transfer.hair_reference of A and B.
// Injected: HAIR_FORWARD, HAIR_BETA_R, HAIR_BETA_D, HAIR_FLOOR, STRAND_POWER_STEPS, RELIGHT_FORWARD_G.
uniform vec3 u_hair_ref_a;
uniform vec3 u_hair_ref_b;

// principal direction and eigenvalue of the symmetric tensor (xx xy xz yy | yz zz), power iteration from
// the column of the largest diagonal
vec3 strand_principal(vec4 t0, vec4 t1, out float lam) {
    mat3 m = mat3(t0.x, t0.y, t0.z, t0.y, t0.w, t1.x, t0.z, t1.x, t1.y);
    int k = t0.x >= t0.w ? (t0.x >= t1.y ? 0 : 2) : (t0.w >= t1.y ? 1 : 2);
    vec3 v = m[k];
    for (int i = 0; i < STRAND_POWER_STEPS; ++i) {
        v = v / max(length(v), 1e-30);
        v = m * v;
    }
    lam = length(v);
    return v / max(lam, 1e-30);
}

// rho D(T, n, v) + sigma R(T, n, v) of lighting `which` (0 = A, 1 = B); n unit or 0
vec3 hair_transfer(int which, vec3 t, vec3 n, vec3 v, vec3 rho, float sigma) {
    const float g = RELIGHT_FORWARD_G;
    vec3 d = vec3(0.0), r = vec3(0.0);
    float tv = dot(t, v);
    for (int k = 0; k < relight_lobe_count(which); ++k) {
        SG l = relight_lobe(which, k);
        vec3 power = sg_integral(l) * (max(dot(n, l.axis) + 0.5, 0.0) / 1.5);
        float c = dot(t, l.axis);
        float cs = -dot(v, l.axis);
        float hg = (1.0 - g * g) / pow(1.0 + g * g - 2.0 * g * cs, 1.5);
        float xd = (c + tv) / HAIR_BETA_D;
        d += power * ((exp(-0.5 * xd * xd) + HAIR_FLOOR) * (1.0 + HAIR_FORWARD * hg));
        float x = (c + tv) / HAIR_BETA_R;
        r += power * exp(-0.5 * x * x);
    }
    return rho * d + sigma * r;
}

// gain from A to B of a strand with unit tangent t, shell normal n, unit view v, fitted colour rho, sigma
vec3 hair_gain(vec3 t, vec3 n, vec3 v, vec3 rho, float sigma) {
    vec3 den = hair_transfer(0, t, n, v, rho, sigma) + u_regularise * rho * u_hair_ref_a;
    vec3 num = hair_transfer(1, t, n, v, rho, sigma) + u_regularise * rho * u_hair_ref_b;
    vec3 q;
    for (int c = 0; c < 3; ++c) q[c] = den[c] > 0.0 ? num[c] / den[c] : u_global_gain[c];
    return clamp(q, vec3(0.0), u_max_gain * u_global_gain);
}

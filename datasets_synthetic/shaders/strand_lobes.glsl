// Chiang et al. 2016 hair lobes, width-averaged, under N_LIGHTS directional lights (GLSL twin of
// render.shading.hair: attenuation, log_i0e / _m_fast, the trimmed logistic of _radiance_block).
// Needs: NODE_H / NODE_W, the Light SSBO `lights`, the visibility SSBO `vis`, ETA, ALPHA_RAD, SIGMA_DEN.

float fresnel_dielectric(float c, float eta) {
    c = clamp(c, 0.0, 1.0);
    float s_t = sqrt(max(1.0 - c * c, 0.0)) / eta;
    float c_t = sqrt(max(1.0 - s_t * s_t, 0.0));
    float r_par = (eta * c - c_t) / (eta * c + c_t);
    float r_perp = (c - eta * c_t) / (c + eta * c_t);
    return 0.5 * (r_par * r_par + r_perp * r_perp);
}

vec3 sigma_a_from_colour(vec3 colour) {
    vec3 l = log(clamp(colour, 1e-4, 1.0 - 1e-4)) / SIGMA_DEN;
    return l * l;
}

// A_0..A_3 at (cos_o, h) for absorption sigma_a (render.shading.hair.attenuation).
void attenuation(float cos_o, float h, vec3 sigma_a, out vec3 a0, out vec3 a1, out vec3 a2, out vec3 a3) {
    float sin_o2 = max(1.0 - cos_o * cos_o, 0.0);
    float sin_t2 = sin_o2 / (ETA * ETA);
    float cos_t = sqrt(max(1.0 - sin_t2, 0.0));
    float etap = sqrt(max(ETA * ETA - sin_o2, 0.0)) / max(cos_o, 1e-12);
    float hq = h / etap;
    float cos_gt = sqrt(max(1.0 - hq * hq, 0.0));
    vec3 tr = exp(-sigma_a * (2.0 * cos_gt / max(cos_t, 1e-12)));
    float f = fresnel_dielectric(cos_o * sqrt(max(1.0 - h * h, 0.0)), ETA);
    a0 = vec3(f);
    a1 = (1.0 - f) * (1.0 - f) * tr;
    a2 = a1 * tr * f;
    a3 = a2 * f * tr / (1.0 - tr * f);
}

// Width-averaged energy of R + TRT + residual at normal incidence (render.shading.hair.back_albedo).
vec3 back_albedo(vec3 sigma_a) {
    vec3 acc = vec3(0.0);
    for (int k = 0; k < N_NODES; ++k) {
        vec3 a0, a1, a2, a3;
        attenuation(1.0, NODE_H[k], sigma_a, a0, a1, a2, a3);
        acc += (a0 + a2 + a3) * NODE_W[k];
    }
    return acc;
}

// log(I0(x) exp(-x)), Abramowitz & Stegun 9.8.1 / 9.8.2 (render.shading.hair.log_i0e).
float log_i0e(float x) {
    if (x < 3.75) {
        float t = x / 3.75;
        float t2 = t * t;
        float p = 1.0 + t2 * (3.5156229 + t2 * (3.0899424 + t2 * (1.2067492 + t2 * (0.2659732
                  + t2 * (0.0360768 + t2 * 0.0045813)))));
        return log(p) - x;
    }
    float u = 3.75 / x;
    float p = 0.39894228 + u * (0.01328592 + u * (0.00225319 + u * (-0.00157565 + u * (0.00916281 + u * (
              -0.02057706 + u * (0.02635537 + u * (-0.01647633 + u * 0.00392377)))))));
    return log(p) - 0.5 * log(x);
}

// d'Eon's M_p with 1 / v and log-normaliser c given (render.shading.hair._m_fast).
float longitudinal(float cos_i, float cos_o, float sin_i, float sin_o, float inv_v, float log_c) {
    float a = cos_i * cos_o * inv_v;
    float b = sin_i * sin_o * inv_v;
    return exp(log_i0e(a) + a - b + log_c);
}

// Trimmed logistic (unnormalised by s): e / (1 + e)^2 with e = exp(-|d| / s), d wrapped to [-pi, pi].
float logistic(float phi, float defl, float inv_s) {
    float d = phi - defl;                    // in [-pi, 2 pi)
    d = min(abs(d), 2.0 * PI - d);
    float e = exp(-d * inv_s);
    return e / ((1.0 + e) * (1.0 + e));
}

// sum_l power_l vis_l [S_far(wo, d_l) + ms * sin(T, d_l)]  (datasets_synthetic.hair_shading.strand_radiance).
vec3 strand_lobes(vec3 T, vec3 wo, vec3 sigma_a, vec3 ms, int vis_row) {
    float so = clamp(dot(wo, T), -1.0, 1.0);
    float co = sqrt(max(1.0 - so * so, 0.0));
    vec3 po = wo - so * T;
    float po_len = length(po);
    float etap = sqrt(max(ETA * ETA - so * so, 0.0)) / max(co, 1e-12);
    // per node: deflections of R, TT, TRT and the attenuations (weights folded in)
    float defl[3 * N_NODES];
    vec3 att[4 * N_NODES];
    for (int k = 0; k < N_NODES; ++k) {
        float h = NODE_H[k];
        float g_o = asin(h);
        float g_t = asin(clamp(h / etap, -1.0, 1.0));
        for (int p = 0; p < 3; ++p) {
            float x = 2.0 * float(p) * g_t - 2.0 * g_o + float(p) * PI + PI;
            defl[3 * k + p] = x - 2.0 * PI * floor(x / (2.0 * PI)) - PI;
        }
        vec3 a0, a1, a2, a3;
        attenuation(co, h, sigma_a, a0, a1, a2, a3);
        att[4 * k] = a0 * NODE_W[k];
        att[4 * k + 1] = a1 * NODE_W[k];
        att[4 * k + 2] = a2 * NODE_W[k];
        att[4 * k + 3] = a3 * NODE_W[k];
    }
    vec3 a3sum = vec3(0.0);
    for (int k = 0; k < N_NODES; ++k) a3sum += att[4 * k + 3];
    // tilted theta_o of R, TT, TRT (render.shading.hair._tilted)
    vec3 tilt_s, tilt_c;
    for (int p = 0; p < 3; ++p) {
        float a = (p == 0 ? -2.0 : (p == 1 ? 1.0 : 4.0)) * ALPHA_RAD;
        tilt_s[p] = so * cos(a) + co * sin(a);
        tilt_c[p] = abs(co * cos(a) - so * sin(a));
    }
    vec3 single = vec3(0.0), diffuse = vec3(0.0);
    for (int l = 0; l < N_LIGHTS; ++l) {
        Light lt = lights[l];
        float v = vis[vis_row + l];
        if (v <= 0.0) continue;
        vec3 d = lt.dir.xyz;
        float si = clamp(dot(d, T), -1.0, 1.0);
        float ci = sqrt(max(1.0 - si * si, 0.0));
        vec3 pi_ = d - si * T;
        float c = dot(po, pi_) / max(po_len * length(pi_), 1e-12);
        float phi = acos(clamp(c, -1.0, 1.0));
        float inv_s = lt.azi.x;
        vec3 lobes = vec3(0.0);
        for (int p = 0; p < 3; ++p) {
            float m = longitudinal(ci, tilt_c[p], si, tilt_s[p], lt.inv_v[p], lt.log_c[p]);
            vec3 n = vec3(0.0);
            for (int k = 0; k < N_NODES; ++k) n += logistic(phi, defl[3 * k + p], inv_s) * att[4 * k + p];
            lobes += m * n;
        }
        lobes *= lt.azi.y;
        float m3 = longitudinal(ci, co, si, so, lt.inv_v[3], lt.log_c[3]);
        lobes += m3 / (2.0 * PI) * a3sum;
        single += lobes * lt.power.rgb * v;
        diffuse += lt.power.rgb * (v * ci);
    }
    return single + ms * diffuse;
}

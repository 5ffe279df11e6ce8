// Energy-preserving Blinn-Phong (docs/methods.md §4 Eq. 4). Twin of render/shading/brdf.py.
#ifndef FURROW_SHADING_BRDF_GLSL
#define FURROW_SHADING_BRDF_GLSL
// (n + 2) / (8 pi) * cos^n(alpha) for cos_alpha > 0, else 0 (underflows to 0, never NaN).
float blinn_phong_normalized(float cos_alpha, float n) {
    if (cos_alpha <= 0.0) return 0.0;
    return (n + 2.0) / (8.0 * 3.14159265358979323846) * exp(n * log(cos_alpha));
}

// 1 - (sqrt(2)/2)^(n + 2): energy of the normalised lobe (Eq. 5 times the Eq. 4 factor).
float blinn_phong_energy(float n) {
    return 1.0 - exp((n + 2.0) * log(0.7071067811865476));
}
#endif

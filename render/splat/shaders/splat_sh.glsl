// Colour of a Gaussian from its spherical harmonics, as the reference rasteriser evaluates it:
// max(0, 0.5 + sum_k basis_k(dir) sh_k), dir the unit vector from the eye to the Gaussian.
// Twin: volume/splat_sh.py (basis, colour); constants injected by render/splat/gl.py.
// The coefficients follow the Gaussian's first 3 vec4 in the Gaussians buffer, packed as floats
// k * 3 + channel. Defines: SH_K, SH_C0, SH_C1, SH_C2_0..4, SH_C3_0..6.

float sh_float(uint at, uint i) { return data[at + i / 4u][int(i % 4u)]; }
vec3 sh_coeff(uint at, uint k) { return vec3(sh_float(at, 3u * k), sh_float(at, 3u * k + 1u), sh_float(at, 3u * k + 2u)); }

vec3 sh_colour(uint at, vec3 dir) {
    vec3 c = SH_C0 * sh_coeff(at, 0u);
#if SH_K > 1
    float x = dir.x, y = dir.y, z = dir.z;
    c += -SH_C1 * y * sh_coeff(at, 1u) + SH_C1 * z * sh_coeff(at, 2u) - SH_C1 * x * sh_coeff(at, 3u);
#endif
#if SH_K > 4
    float xx = x * x, yy = y * y, zz = z * z, xy = x * y, yz = y * z, xz = x * z;
    c += SH_C2_0 * xy * sh_coeff(at, 4u) + SH_C2_1 * yz * sh_coeff(at, 5u)
       + SH_C2_2 * (2.0 * zz - xx - yy) * sh_coeff(at, 6u) + SH_C2_3 * xz * sh_coeff(at, 7u)
       + SH_C2_4 * (xx - yy) * sh_coeff(at, 8u);
#endif
#if SH_K > 9
    c += SH_C3_0 * y * (3.0 * xx - yy) * sh_coeff(at, 9u) + SH_C3_1 * xy * z * sh_coeff(at, 10u)
       + SH_C3_2 * y * (4.0 * zz - xx - yy) * sh_coeff(at, 11u)
       + SH_C3_3 * z * (2.0 * zz - 3.0 * xx - 3.0 * yy) * sh_coeff(at, 12u)
       + SH_C3_4 * x * (4.0 * zz - xx - yy) * sh_coeff(at, 13u) + SH_C3_5 * z * (xx - yy) * sh_coeff(at, 14u)
       + SH_C3_6 * x * (xx - 3.0 * yy) * sh_coeff(at, 15u);
#endif
    return max(c + 0.5, vec3(0.0));
}

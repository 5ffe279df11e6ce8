// SH9 diffuse irradiance (Ramamoorthi & Hanrahan 2001). Twin of render/shading/sh.py.
// u_sh9[k] = A_l * L_lm (radiance SH coefficients times the cosine-lobe weights), i.e. the
// output of render.shading.sh.sh9_glsl_uniform(); order k = l(l+1)+m:
// (0,0) (1,-1) (1,0) (1,1) (2,-2) (2,-1) (2,0) (2,1) (2,2). n: unit normal, world +z up.
#ifndef FURROW_SH9_GLSL
#define FURROW_SH9_GLSL
uniform vec3 u_sh9[9];

vec3 sh9_irradiance(vec3 n) {
    float x = n.x, y = n.y, z = n.z;
    vec3 e = u_sh9[0] * 0.28209479177387814;
    e += u_sh9[1] * (0.4886025119029199 * y);
    e += u_sh9[2] * (0.4886025119029199 * z);
    e += u_sh9[3] * (0.4886025119029199 * x);
    e += u_sh9[4] * (1.0925484305920792 * x * y);
    e += u_sh9[5] * (1.0925484305920792 * y * z);
    e += u_sh9[6] * (0.31539156525252005 * (3.0 * z * z - 1.0));
    e += u_sh9[7] * (1.0925484305920792 * x * z);
    e += u_sh9[8] * (0.5462742152960396 * (x * x - y * y));
    return max(e, vec3(0.0));
}
#endif

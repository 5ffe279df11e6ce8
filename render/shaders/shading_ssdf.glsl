// SSDF visibility from a set of spheres (docs/methods.md §3, seed 001 Algorithm 1). Twin of
// render/shading/ssdf.py (ssdf_spheres, ssdf_ground). Spheres: an SSBO of vec4 (xyz centre, w
// radius) at binding SSDF_SPHERE_BINDING (default 5), count u_ssdf_count.
#ifndef FURROW_SHADING_SSDF_GLSL
#define FURROW_SHADING_SSDF_GLSL
#ifndef SSDF_SPHERE_BINDING
#define SSDF_SPHERE_BINDING 5
#endif
layout(std430, binding = SSDF_SPHERE_BINDING) readonly buffer SsdfSpheres { vec4 ssdf_sphere[]; };
uniform int u_ssdf_count;
const float SSDF_MAX = 1.5707963267948966;

// x: shading point, n: unit normal (tangent-plane culling), zeta: unit SG axis.
float ssdf_from_spheres(vec3 x, vec3 n, vec3 zeta) {
    float s = SSDF_MAX;
    for (int j = 0; j < u_ssdf_count; ++j) {
        vec3 c = ssdf_sphere[j].xyz;
        float r = ssdf_sphere[j].w;
        vec3 d = c - x;
        float dist = length(d);
        if (dist <= r) continue;                       // inside the sphere
        if (dot(n, d + n * r) < 0.0) continue;         // entirely below the tangent plane
        float v = acos(clamp(dot(d / dist, zeta), -1.0, 1.0)) - asin(clamp(r / dist, 0.0, 1.0));
        s = min(s, v);
    }
    return s;
}

// infinite ground plane below the point: SSDF = elevation of zeta
float ssdf_ground(vec3 zeta) { return asin(clamp(zeta.z / length(zeta), -1.0, 1.0)); }
#endif

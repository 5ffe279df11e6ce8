// Shared fragment inputs / outputs of the mesh rasteriser (render/mesh/raster/gl.py).
in vec3 v_world;
in vec3 v_color;
in vec3 v_normal;
in vec3 v_tangent;
in float v_occl;
in float v_spec;
in float v_eyez;

uniform vec3 u_eye;          // camera centre, world
uniform int u_has_normals;   // 0: flat face normals from screen derivatives

layout(location = 0) out vec4 f_color;   // linear colour, alpha = coverage
layout(location = 1) out float f_depth;  // z-depth in metres
layout(location = 2) out vec4 f_normal;  // world normal facing the camera

// Unit world normal turned towards the eye.
vec3 raster_normal(vec3 V) {
    vec3 geo = cross(dFdx(v_world), dFdy(v_world));
    vec3 N = geo;
    if (u_has_normals == 1 && dot(v_normal, v_normal) > 1e-12) N = v_normal;
    float l = length(N);
    N = l > 0.0 ? N / l : V;
    return dot(N, V) < 0.0 ? -N : N;
}

void raster_write(vec3 colour, vec3 N) {
    f_color = vec4(colour, 1.0);
    f_depth = v_eyez;
    f_normal = vec4(N, 1.0);
}

#version 430
// Mesh rasteriser vertex stage (render/mesh/raster/gl.py). World metres in, eye-space z-depth out.
uniform mat4 u_view;   // camera.gl_view()
uniform mat4 u_proj;   // camera.gl_projection(near, far)

in vec3 in_pos;
in vec3 in_color;
in vec3 in_normal;
in vec3 in_tangent;
in float in_occl;
in float in_spec;
in vec4 in_vis;      // per-vertex visibility of the (up to 4) shadowing lights
in vec3 in_emit;     // per-vertex radiance added by the shaded mode (MeshRasterizer.set_emission)

out vec3 v_world;
out vec3 v_color;
out vec3 v_normal;
out vec3 v_tangent;
out float v_occl;
out float v_spec;
out vec4 v_vis;
out vec3 v_emit;
out float v_eyez;

void main() {
    vec4 e = u_view * vec4(in_pos, 1.0);
    v_eyez = -e.z;  // GL eye looks down -z: z-depth in metres is -e.z
    v_world = in_pos;
    v_color = in_color;
    v_normal = in_normal;
    v_tangent = in_tangent;
    v_occl = in_occl;
    v_spec = in_spec;
    v_vis = in_vis;
    v_emit = in_emit;
    gl_Position = u_proj * e;
}

#version 430
// Glossy mesh renderer vertex stage (render/mesh/glossy/gl.py). World metres in, eye z-depth out.
uniform mat4 u_view;   // camera.gl_view()
uniform mat4 u_proj;   // camera.gl_projection(near, far)

in vec3 in_pos;
in vec3 in_normal;
in float in_smooth;    // MSEM smoothness lambda per vertex (docs/methods.md §2 Eq. 6), [0, 1]
in vec2 in_uv;         // texture coordinates of the per-texel smoothness map

out vec3 v_world;
out vec3 v_normal;
out float v_smooth;
out vec2 v_uv;
out float v_eyez;

void main() {
    vec4 e = u_view * vec4(in_pos, 1.0);
    v_eyez = -e.z;
    v_world = in_pos;
    v_normal = in_normal;
    v_smooth = in_smooth;
    v_uv = in_uv;
    gl_Position = u_proj * e;
}

#version 430
// Fixed-mesh view-dependent texture mapping (the paper's "conventional method", Fig. 11).
in vec3 in_pos;
in vec3 in_color;
uniform mat4 view_proj;
out vec3 v_world;
out vec3 v_color;
void main() {
    v_world = in_pos;
    v_color = in_color;
    gl_Position = view_proj * vec4(in_pos, 1.0);
}

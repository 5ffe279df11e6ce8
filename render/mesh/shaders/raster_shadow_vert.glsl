#version 430
// Shadow-map depth pass of the mesh rasteriser: orthographic light view-projection.
uniform mat4 u_mvp;
in vec3 in_pos;
void main() { gl_Position = u_mvp * vec4(in_pos, 1.0); }

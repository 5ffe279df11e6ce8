#version 430
// Glare streak fans (METHODS §4): positions in pixels (x right, y down), colour per vertex.
in vec2 in_pos;
in vec3 in_col;
uniform vec2 u_size;
out vec3 v_col;
void main() {
    vec2 ndc = in_pos / u_size * 2.0 - 1.0;
    // y down in pixels -> framebuffer row 0 at the top when read back (rows stay top-down)
    gl_Position = vec4(ndc.x, ndc.y, 0.0, 1.0);
    v_col = in_col;
}

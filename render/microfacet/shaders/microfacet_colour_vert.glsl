#version 430
// Colour pass: a full-screen triangle on the far plane; with the depth test ">" (no writes)
// only the samples where the pre-pass drew a fragment are shaded.
void main() {
    vec2 p = vec2((gl_VertexID & 1) != 0 ? 3.0 : -1.0, (gl_VertexID & 2) != 0 ? 3.0 : -1.0);
    gl_Position = vec4(p, 1.0, 1.0);
}

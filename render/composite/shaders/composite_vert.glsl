#version 430
// Full-screen triangle for the compositing passes (render/composite/gl.py). No attributes.
void main() {
    vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}

#version 430
// Bare fill cost reference: the same slice squares, untextured (no lookup, no Eq. 2).
out vec4 frag;
void main() { frag = vec4(1.0); }

#version 430
// Depth only.
void main() {}

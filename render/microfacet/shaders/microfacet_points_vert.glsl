#version 430
// Geometry-shader path: one point per surface voxel, read from the voxel buffer.
layout(std430, binding = 1) readonly buffer Voxels { vec4 centers[]; };
out vec3 g_center;
void main() { g_center = centers[gl_VertexID].xyz; gl_Position = vec4(0.0); }

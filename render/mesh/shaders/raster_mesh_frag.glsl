#version 430
// Flat (unlit) mesh rasteriser: per-vertex colour, z-depth, normals.
#include "raster_common.glsl"

void main() {
    vec3 V = normalize(u_eye - v_world);
    raster_write(v_color, raster_normal(V));
}

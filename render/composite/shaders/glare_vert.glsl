#version 430
// Glare streak pairs (docs/methods.md §4, seed 002 §3.5) as instanced triangle fans of 4 triangles:
// template vertex in_corner = (a, b, weight): centre (0, 0, 1), then the rim (+-1, 0, 0), (0, +-1, 0);
// position = centre + a L axis + b (W / 2) perp (OpenCV pixels, v down), colour = c * weight
// (centre c, rim black, interpolated). Twin: render.shading.glare_maps.rasterize_streaks_reference.
#include "framebuffer_row.glsl"
in vec3 in_corner;
in vec2 in_centre;   // (u, v) OpenCV pixel centre
in vec2 in_axis;     // unit, image axes
in float in_len;     // half-diagonal along the axis
in float in_wid;     // full width across
in vec3 in_col;      // centre value c
uniform vec2 u_size; // image (W, H) in pixels (not the supersampled size)
out vec3 v_col;
void main() {
    vec2 perp = vec2(-in_axis.y, in_axis.x);
    vec2 p = in_centre + in_corner.x * in_len * in_axis + in_corner.y * 0.5 * in_wid * perp;
    gl_Position = vec4(image_to_ndc(p, u_size), 0.0, 1.0);  // same convention as Camera.gl_projection
    v_col = in_col * in_corner.z;
}

#version 430
// Deferred relighting of a frame (twin: render.relight_reference.apply_reference): the world point
// of each pixel's z-depth, the gain volume sampled there (trilinear, clamped to the edge texels),
// times the colour; pixels without depth unchanged. Each fragment shades the image pixel that
// framebuffer_row.glsl's image_pixel gives (read back with gl_rows_to_image).
#include "framebuffer_row.glsl"
uniform sampler2D u_rgb;       // colour, row 0 = image row 0 (texelFetch)
uniform sampler2D u_depth;     // z-depth (R32F), 0 = nothing drawn
uniform sampler3D u_gain;      // gain volume (RGB32F, LINEAR, clamp to edge)
uniform mat3 u_ray;            // world direction of pixel (u, v, 1): R^T K^-1
uniform vec3 u_eye;            // camera centre (world)
uniform vec3 u_origin;         // gain volume min corner (world)
uniform float u_extent;        // gain volume side (metres)
uniform int u_height;
out vec4 o_col;

void main() {
    ivec2 px = image_pixel(gl_FragCoord.xy, u_height);
    vec3 col = texelFetch(u_rgb, px, 0).rgb;
    float z = texelFetch(u_depth, px, 0).r;
    if (z > 0.0) {
        vec3 x = u_eye + z * (u_ray * vec3(float(px.x), float(px.y), 1.0));
        col *= texture(u_gain, (x - u_origin) / u_extent).rgb;
    }
    o_col = vec4(col, 1.0);
}

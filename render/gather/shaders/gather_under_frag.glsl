#version 430
// Pass 2a of the gather method with a matte and a second layer (full-screen triangle behind an early
// depth test that passes only where pass 1b marked a second layer): the farthest splat's point
// gathered like the front's (gather_blend.glsl); out: (its premultiplied colour x s / alpha, s),
// s = clip((alpha - BACK_SOLID) / (1 - BACK_SOLID), 0, 1) how solid the kept views see it; pass 2
// composites it under the front.  No discard: the depth test alone picks the pixels.
// Twin: render/gather/reference.py under_back, solid.  Defines: those of gather_blend.glsl, BACK_SOLID.
#include "framebuffer_row.glsl"
uniform sampler2D far_z;         // pass 1: minus the farthest z (framebuffer rows)
#include "gather_blend.glsl"

void main() {
    float zb = -texelFetch(far_z, ivec2(gl_FragCoord.xy), 0).r;
    COL acc;
    float wsum;
    blend_at(eye_point(image_pixel(gl_FragCoord.xy, height), zb), acc, wsum);
    float a = wsum > 0.0 ? min(acc.a / wsum, 1.0) : 0.0;
    float s = clamp((a - BACK_SOLID) / (1.0 - BACK_SOLID), 0.0, 1.0);
    out_colour = a > 0.0 ? vec4(acc.rgb / wsum * (s / a), s) : vec4(0.0);
}

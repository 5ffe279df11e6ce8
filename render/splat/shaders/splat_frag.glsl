#version 430
// The splat method's fragment shader: the Gaussian's alpha at the pixel centre,
// min(ALPHA_MAX, opacity exp(-q / 2)), skipped below ALPHA_MIN; written premultiplied for
// front-to-back blending (src factor 1 - dst alpha, dst factor 1).
// Twin: render/splat/reference.py (fragments, blend).
#include "framebuffer_row.glsl"
uniform int height;
flat in vec2 v_mean;
flat in vec3 v_conic;
flat in vec4 v_colour;
flat in float v_z;
layout(location = 0) out vec4 out_colour;  // display colour x alpha, alpha
layout(location = 1) out vec4 out_depth;   // z x alpha, 0, 0, alpha

void main() {
    vec2 d = vec2(image_pixel(gl_FragCoord.xy, height)) - v_mean;
    float power = -0.5 * (v_conic.x * d.x * d.x + v_conic.z * d.y * d.y) - v_conic.y * d.x * d.y;
    if (power > 0.0) discard;
    float alpha = min(ALPHA_MAX, v_colour.a * exp(power));
    if (alpha < ALPHA_MIN) discard;
    out_colour = vec4(v_colour.rgb * alpha, alpha);
    out_depth = vec4(v_z * alpha, 0.0, 0.0, alpha);
}

#version 430
// Pass 2 of the gather method (full-screen triangle): the pixel's point at its splatted depth,
// its colour gathered from the K_BLEND nearest kept views (Catmull-Rom bicubic when
// RESAMPLE_CUBIC, else bilinear), weighted by (1 / angle) x soft visibility.
// With HAS_ALPHA (a model with a matte) the colour resampled is premultiplied rgb + alpha (COL =
// vec4), blended with the same weights; without, the straight rgb (COL = vec3) and alpha 1.
// Twin: render/gather/reference.py gather / sample_view / cubic / bilinear.
// The views are their crops (render/crops.py): a pixel outside a view's rect is empty (all 0).
// A pixel no splat covers whose 4 edge neighbours all have a depth at most PINHOLE_SPREAD apart
// takes their mean (PINHOLE_FILL; twin: fill_pinholes).
// With BACK_LAYER (HAS_ALPHA only) pass 2a's second layer (gather_under_frag.glsl) is composited under
// a drawn front (alpha > 0) as far as the front is not solid (from BACK_SOLID up; twin: under_back).
// Defines: K_BLEND, VIS_SIGMA, VIS_FLOOR, Z_EMPTY, RESAMPLE_CUBIC, CUBIC_A, HAS_ALPHA, PINHOLE_FILL,
// PINHOLE_SPREAD, BACK_LAYER, BACK_SOLID.
#include "framebuffer_row.glsl"
uniform sampler2D front_z;       // pass 1 (framebuffer rows), Z_EMPTY where no splat landed
uniform float fill_offset;       // pass 1's z carries a multiple of it by class (render/gather/gl.py _depth_pass)
#if BACK_LAYER
uniform sampler2D under;         // pass 2a: the second layer's colour x solid / alpha, and solid (0 where none)
#endif
#include "gather_blend.glsl"
// Pass 1's z at texel p with its class's offset taken off; Z_EMPTY where no splat landed (twin: gl.py unoffset).
float splat_z(ivec2 p) {
    float z = texelFetch(front_z, p, 0).r;
    return z < Z_EMPTY ? z - fill_offset * floor(z / fill_offset) : z;
}

// Depth of an empty texel p from its 4 edge neighbours (Z_EMPTY where they do not all agree).
float pinhole_z(ivec2 p) {
    ivec2 size = textureSize(front_z, 0);
    if (any(lessThan(p, ivec2(1))) || any(greaterThan(p, size - 2))) return Z_EMPTY;
    float a = splat_z(p + ivec2(0, 1)), b = splat_z(p - ivec2(0, 1));
    float c = splat_z(p - ivec2(1, 0)), d = splat_z(p + ivec2(1, 0));
    float lo = min(min(a, b), min(c, d)), hi = max(max(a, b), max(c, d));
    return (hi < Z_EMPTY && hi - lo <= PINHOLE_SPREAD) ? (((a + b) + c) + d) * 0.25 : Z_EMPTY;
}

void main() {
    float z = splat_z(ivec2(gl_FragCoord.xy));
#if PINHOLE_FILL
    if (!(z < Z_EMPTY)) z = pinhole_z(ivec2(gl_FragCoord.xy));
#endif
    if (!(z < Z_EMPTY)) discard;
    ivec2 pix = image_pixel(gl_FragCoord.xy, height);
    COL acc;
    float wsum;
    blend_at(eye_point(pix, z), acc, wsum);
    if (!(wsum > 0.0)) discard;
#if HAS_ALPHA
    vec4 f = vec4(acc.rgb / wsum, min(acc.a / wsum, 1.0));
#if BACK_LAYER
    // under the front as far as the front is not solid (twin: under_back)
    vec4 u = texelFetch(under, ivec2(gl_FragCoord.xy), 0);
    float k = f.a > 0.0 ? (1.0 - f.a) * (1.0 - clamp((f.a - BACK_SOLID) / (1.0 - BACK_SOLID), 0.0, 1.0)) : 0.0;
    f += k * u;
#endif
    out_colour = f;
#else
    out_colour = vec4(acc / wsum, 1.0);
#endif
}

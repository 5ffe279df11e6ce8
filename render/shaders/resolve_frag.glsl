#version 430
// Supersampling resolve (render/antialias.py; twin: antialias.box_resolve): the mean of each
// FACTOR x FACTOR block of the large colour target (rgb premultiplied over black, alpha =
// coverage) and the nearest depth of the block.
uniform sampler2D big_colour;
uniform sampler2D big_depth;
uniform int factor;
layout(location = 0) out vec4 out_colour;
layout(location = 1) out float out_depth;

void main() {
    ivec2 base = ivec2(gl_FragCoord.xy) * factor;
    vec4 acc = vec4(0.0);
    float dmin = 1.0;
    for (int j = 0; j < factor; ++j)
        for (int i = 0; i < factor; ++i) {
            ivec2 ij = base + ivec2(i, j);
            acc += texelFetch(big_colour, ij, 0);
            dmin = min(dmin, texelFetch(big_depth, ij, 0).r);
        }
    out_colour = acc / float(factor * factor);
    out_depth = dmin;
}

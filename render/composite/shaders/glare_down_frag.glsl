#version 430
// Box average of SUPERSAMPLE x SUPERSAMPLE sub-samples of the streak layer (render/composite/glare_layer.py).
uniform sampler2D u_hi;
out vec4 o_col;
void main() {
    ivec2 base = ivec2(gl_FragCoord.xy) * SUPERSAMPLE;
    vec3 acc = vec3(0.0);
    for (int j = 0; j < SUPERSAMPLE; ++j)
        for (int i = 0; i < SUPERSAMPLE; ++i)
            acc += texelFetch(u_hi, base + ivec2(i, j), 0).rgb;
    o_col = vec4(acc / float(SUPERSAMPLE * SUPERSAMPLE), 1.0);
}

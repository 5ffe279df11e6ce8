#version 430
// Pass 1b of the gather method with a second layer (full-screen triangle): depth MARK_DEPTH where the
// pixel has one -- a front splat, and a farthest splat more than BACK_GAP behind it -- so that pass 2a
// runs only there (its early depth test: llvmpipe then skips the other pixels' shading).
// Twin: render/gather/reference.py back_depth.  Defines: BACK_GAP, Z_EMPTY, MARK_DEPTH.
uniform sampler2D front_z;   // pass 1: nearest z (carrying a multiple of fill_offset by class, gl.py _depth_pass)
uniform sampler2D far_z;     // pass 1: minus the farthest z
uniform float fill_offset;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    float f = texelFetch(front_z, p, 0).r;
    if (!(f < Z_EMPTY)) discard;
    f -= fill_offset * floor(f / fill_offset);
    if (!(-texelFetch(far_z, p, 0).r > f + BACK_GAP)) discard;
    gl_FragDepth = MARK_DEPTH;
}

// One slice tile record written by microfacet_select.glsl and read by microfacet_vert.glsl.
struct Slice {
    vec4 pos_s;     // voxel centre xyz (world), distance s = n * l from the eye
    vec4 weights;   // ULR weights of cand[0..2]
    ivec4 c03;      // candidate cameras 0..3 (-1 = none)
    ivec4 c45;      // candidates 4..5, voxel index, slice number n
    vec4 rect;      // the tile on the slice plane: x0, x1 along a, y0, y1 along b (metres)
};

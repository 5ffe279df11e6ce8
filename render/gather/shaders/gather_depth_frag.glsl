#version 430
// Pass 1: the splat's z-depth into an R32F target blended with MIN (the nearest per pixel); with a
// second layer (render/gather/gl.py) also minus its own z (without the fill's offset) into a second
// R32F target, also MIN: minus the farthest z per pixel.
flat in float v_z;
flat in float v_true_z;
layout(location = 0) out float out_z;
layout(location = 1) out float out_neg_z;

void main() {
    out_z = v_z;
    out_neg_z = -v_true_z;
}

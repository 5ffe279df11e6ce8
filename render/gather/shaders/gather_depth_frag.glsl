#version 430
// Pass 1: the splat's z-depth into an R32F target blended with MIN (the nearest per pixel).
flat in float v_z;
layout(location = 0) out float out_z;

void main() {
    out_z = v_z;
}

// The one GLSL place where OpenCV image pixels meet the OpenGL framebuffer (bottom row first,
// pixel centres at i + 0.5). Twin: capture/camera.py (Camera.gl_projection, gl_row,
// corner_from_cv, gl_rows_to_image); nowhere else in the shaders flips a row or shifts a centre.

// NDC position of the OpenCV image point (u, v) (pixels, centre of pixel (i, j) at (i, j)) in an
// image of `size` = (W, H) pixels: x = 2 (u + 0.5) / W - 1, y = 1 - 2 (v + 0.5) / H.
vec2 image_to_ndc(vec2 uv, vec2 size) {
    vec2 corner = uv + 0.5;
    return vec2(2.0 * corner.x / size.x - 1.0, 1.0 - 2.0 * corner.y / size.y);
}

// Integer image pixel (column, row; row 0 at the top) of the fragment at `frag_coord`
// (gl_FragCoord.xy) in a framebuffer `height` rows tall.
ivec2 image_pixel(vec2 frag_coord, int height) {
    ivec2 fb = ivec2(frag_coord);
    return ivec2(fb.x, height - 1 - fb.y);
}

// The gather method's kept views and their blend at a point (included by gather_frag.glsl and
// gather_under_frag.glsl): uniforms of the eye and the K_BLEND blend cameras, bilinear or Catmull-Rom
// resampling of their crops, (1 / angle) x soft visibility.  Twin: render/gather/reference.py gather /
// sample_view / cubic.  Defines: K_BLEND, VIS_SIGMA, VIS_FLOOR, RESAMPLE_CUBIC, CUBIC_A, HAS_ALPHA.
uniform sampler2DArray rgbz;     // layer i: linear rgb + z-depth (m, 0 = none) of kept view i's crop
#if HAS_ALPHA
uniform sampler2DArray matte;    // layer i: straight alpha of kept view i's crop
#define COL vec4
// premultiplied rgb + alpha (the twin's premultiply, float32)
COL fetch_col(ivec3 c) { float a = texelFetch(matte, c, 0).r; return vec4(texelFetch(rgbz, c, 0).rgb * a, a); }
#else
#define COL vec3
COL fetch_col(ivec3 c) { return texelFetch(rgbz, c, 0).rgb; }
#endif
uniform int height;              // eye image height (pixels)
uniform vec4 eye_intr;           // fx, fy, cx, cy of the eye (OpenCV)
uniform float eye_skew;
uniform mat3 eye_rot;            // world_from_cam rotation of the eye
uniform vec3 eye_center;
uniform mat4 cfw[K_BLEND];       // cam_from_world of the blend cameras
uniform vec4 intr[K_BLEND];      // fx, fy, cx, cy
uniform float skew[K_BLEND];
uniform int layer[K_BLEND];      // their RGBz layers
uniform ivec4 rect[K_BLEND];     // their crops (x0, y0, w, h) in their view_size images
uniform ivec2 view_size;         // W, H of the kept views' images
uniform float weight[K_BLEND];   // 1 / angle; 0 = unused slot
layout(location = 0) out vec4 out_colour;

// Layer texel of image pixel p (within the image) of a view whose crop is r; -1 outside the crop.
ivec2 crop_texel(ivec2 p, ivec4 r) {
    ivec2 q = p - r.xy;
    return (any(lessThan(q, ivec2(0))) || any(greaterThanEqual(q, r.zw))) ? ivec2(-1) : q;
}

// Colour of image pixel (x, y) of layer l (crop r), clamped to the image border; 0 outside the crop.
COL texel(int l, ivec4 r, int x, int y, ivec2 size) {
    ivec2 q = crop_texel(ivec2(clamp(x, 0, size.x - 1), clamp(y, 0, size.y - 1)), r);
    return q.x < 0 ? COL(0.0) : fetch_col(ivec3(q, l));
}

// Keys cubic weights of the taps at -1, 0, 1, 2 from floor(x), t = x - floor(x).
vec4 cubic_weights(float t) {
    float t2 = t * t, t3 = t2 * t;
    return vec4(CUBIC_A * (t3 - 2.0 * t2 + t), (CUBIC_A + 2.0) * t3 - (CUBIC_A + 3.0) * t2 + 1.0,
                -(CUBIC_A + 2.0) * t3 + (2.0 * CUBIC_A + 3.0) * t2 - CUBIC_A * t, CUBIC_A * (t2 - t3));
}

// Colour of layer l (crop r) resampled at uv (OpenCV pixels), taps clamped to the image border.
COL resample(int l, ivec4 r, vec2 uv, ivec2 size) {
    vec2 f0 = floor(uv);
    vec2 f = uv - f0;
    int x0 = int(f0.x), y0 = int(f0.y);
#if RESAMPLE_CUBIC
    vec4 wx = cubic_weights(f.x), wy = cubic_weights(f.y);
    COL acc = COL(0.0);
    for (int j = 0; j < 4; ++j) {
        COL row = wx.x * texel(l, r, x0 - 1, y0 + j - 1, size) + wx.y * texel(l, r, x0, y0 + j - 1, size)
                 + wx.z * texel(l, r, x0 + 1, y0 + j - 1, size) + wx.w * texel(l, r, x0 + 2, y0 + j - 1, size);
        acc += wy[j] * row;
    }
    return max(acc, COL(0.0));
#else
    return mix(mix(texel(l, r, x0, y0, size), texel(l, r, x0 + 1, y0, size), f.x),
               mix(texel(l, r, x0, y0 + 1, size), texel(l, r, x0 + 1, y0 + 1, size), f.x), f.y);
#endif
}

// The kept views' blend at point X (its colour and weight sum into acc, wsum).
void blend_at(vec3 X, out COL acc, out float wsum) {
    ivec2 size = view_size;
    acc = COL(0.0);
    wsum = 0.0;
    for (int j = 0; j < K_BLEND; ++j) {
        if (!(weight[j] > 0.0)) continue;
        vec3 pc = (cfw[j] * vec4(X, 1.0)).xyz;
        if (!(pc.z > 0.0)) continue;
        vec2 uv = vec2(intr[j].x * pc.x / pc.z + skew[j] * pc.y / pc.z + intr[j].z, intr[j].y * pc.y / pc.z + intr[j].w);
        if (uv.x < -0.5 || uv.y < -0.5 || uv.x > float(size.x) - 0.5 || uv.y > float(size.y) - 0.5) continue;
        ivec2 ij = clamp(ivec2(floor(uv + 0.5)), ivec2(0), size - 1);
        ivec2 q = crop_texel(ij, rect[j]);
        float d = q.x < 0 ? 0.0 : texelFetch(rgbz, ivec3(q, layer[j]), 0).a;
        COL col = resample(layer[j], rect[j], uv, size);
        float e = (d - pc.z) / VIS_SIGMA;
        float vis = max(d > 0.0 ? exp(-0.5 * e * e) : 0.0, VIS_FLOOR);
        float w = weight[j] * vis;
        acc += w * col;
        wsum += w;
    }
}

// The eye's point at image pixel pix and z-depth z.
vec3 eye_point(ivec2 pix, float z) {
    float yn = (float(pix.y) - eye_intr.w) / eye_intr.y;
    float xn = (float(pix.x) - eye_intr.z - eye_skew * yn) / eye_intr.x;
    return eye_center + eye_rot * (vec3(xn, yn, 1.0) * z);
}


#version 430
// Deferred relighting of a frame (twin: render.relight.reference.apply_reference): the world point
// of each pixel's z-depth, the smoothed SDF's gradient there (trilinear, central differences of one
// voxel, clamped to the edge texels), the direction to the camera, the visible shares sampled from
// their volumes, the gain of relight_common.glsl -- blended towards the strand gain of
// relight_hair.glsl by the strand score (issue 23) -- times the colour; pixels without depth unchanged.
// Each fragment shades the image pixel framebuffer_row.glsl's image_pixel gives (read back with
// gl_rows_to_image). Injected: as relight_common.glsl and relight_hair.glsl, and RELIGHT_STRANDS (1: the
// strand volumes are bound; 0: the surface transfer only, the strand branch compiled out).
#include "framebuffer_row.glsl"
#include "relight_common.glsl"
#include "relight_hair.glsl"
uniform sampler2D u_rgb;          // colour, row 0 = image row 0 (texelFetch)
uniform sampler2D u_depth;        // z-depth (R32F), 0 = nothing drawn
uniform sampler3D u_sdf_smooth;   // smoothed SDF (R32F, LINEAR, clamp to edge)
uniform sampler3D u_share_a;      // visible share of A (RGB32F, LINEAR, clamp to edge)
uniform sampler3D u_share_b;
uniform mat3 u_ray;               // world direction of pixel (u, v, 1): R^T K^-1
uniform vec3 u_eye;               // camera centre (world)
uniform vec3 u_origin;            // volume min corner (world)
uniform float u_voxel;            // volume voxel (metres)
uniform int u_res;
uniform int u_height;
uniform sampler3D u_strand_t0;    // s T T^T: xx xy xz yy (RGBA32F, LINEAR, clamp to edge)
uniform sampler3D u_strand_t1;    // yz zz
uniform sampler3D u_strand_fit;   // rho rgb, sigma
uniform vec3 u_strand_origin;
uniform float u_strand_voxel;
uniform int u_strand_res;
uniform float u_strand_weight;    // the blend weight is this times the strand score, clamped to 1
out vec4 o_col;

float sdf_at(vec3 x) { return texture(u_sdf_smooth, (x - u_origin) / (u_voxel * float(u_res))).r; }

void main() {
    ivec2 px = image_pixel(gl_FragCoord.xy, u_height);
    vec3 col = texelFetch(u_rgb, px, 0).rgb;
    float z = texelFetch(u_depth, px, 0).r;
    if (z > 0.0) {
        vec3 x = u_eye + z * (u_ray * vec3(float(px.x), float(px.y), 1.0));
        vec3 g;
        for (int a = 0; a < 3; ++a) {
            vec3 e = vec3(0.0); e[a] = u_voxel;
            g[a] = (sdf_at(x + e) - sdf_at(x - e)) / (2.0 * u_voxel);
        }
        vec3 t = (x - u_origin) / (u_voxel * float(u_res));
        vec3 view = normalize(u_eye - x);
        vec3 gain = relight_gain(g, view, texture(u_share_a, t).rgb, texture(u_share_b, t).rgb);
#if RELIGHT_STRANDS
        {
            vec3 ts = (x - u_strand_origin) / (u_strand_voxel * float(u_strand_res));
            float w;
            vec3 tan_ = strand_principal(texture(u_strand_t0, ts), texture(u_strand_t1, ts), w);
            w = clamp(u_strand_weight * w, 0.0, 1.0);
            if (w > 0.0) {
                vec4 f = texture(u_strand_fit, ts);
                float gl = length(g);
                vec3 n = gl > RELIGHT_MIN_GRADIENT ? g / gl : vec3(0.0);
                gain = mix(gain, hair_gain(tan_, n, view, f.rgb, f.a), w);
            }
        }
#endif
        col *= gain;
    }
    o_col = vec4(col, 1.0);
}

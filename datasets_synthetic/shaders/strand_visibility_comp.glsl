#version 430
// Visibility of one directional light at a list of points from its shadow map: GLSL twin of
// render.mesh.raster.shadow_maps.shadow_map_visibility (the point moved u_bias towards the light,
// four bilinear taps half a texel apart, each comparing the point's depth with the map's; points
// outside the map are lit).  Writes vis[i * u_stride + u_column] for i < u_count from
// lookup[u_offset + i].
layout(local_size_x = LOCAL_SIZE) in;
layout(std430, binding = 5) readonly buffer Lookup { vec4 lookup[]; };
layout(std430, binding = 2) buffer Visibility { float vis[]; };

uniform sampler2D u_depth;   // the light's depth map (row 0 = bottom, as read back from GL)
uniform mat4 u_light_vp;
uniform vec3 u_dir;
uniform float u_bias;
uniform int u_count;
uniform int u_offset;
uniform int u_stride;
uniform int u_column;

void main() {
    int i = int(gl_GlobalInvocationID.x);
    if (i >= u_count) return;
    int S = textureSize(u_depth, 0).x;
    vec3 p = lookup[u_offset + i].xyz + u_bias * u_dir;
    vec4 q = u_light_vp * vec4(p, 1.0);
    vec3 ndc = q.xyz / q.w;
    float v = 1.0;
    if (all(lessThanEqual(abs(ndc), vec3(1.0)))) {
        float ref = ndc.z * 0.5 + 0.5;
        vec2 xy = (ndc.xy * 0.5 + 0.5) * float(S) - 0.5;
        v = 0.0;
        for (int ty = 0; ty < 2; ++ty) {
            for (int tx = 0; tx < 2; ++tx) {
                vec2 s = xy + vec2(float(tx) - 0.5, float(ty) - 0.5);
                vec2 f0 = floor(s);
                vec2 f = s - f0;
                ivec2 i0 = ivec2(f0);
                for (int oy = 0; oy < 2; ++oy) {
                    for (int ox = 0; ox < 2; ++ox) {
                        ivec2 t = clamp(i0 + ivec2(ox, oy), ivec2(0), ivec2(S - 1));
                        float wgt = (ox == 1 ? f.x : 1.0 - f.x) * (oy == 1 ? f.y : 1.0 - f.y);
                        v += ref <= texelFetch(u_depth, t, 0).r ? wgt : 0.0;
                    }
                }
            }
        }
        v *= 0.25;
    }
    vis[i * u_stride + u_column] = v;
}

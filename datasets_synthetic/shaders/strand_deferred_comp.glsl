#version 430
// Deferred strand shading of the GL synthetic renderer (datasets_synthetic/strand_gl.py), over the
// supersampled colour attachment of the frame, where the strand pass (strand_ribbon_frag.glsl) left
// (segment, t, STRAND_SENTINEL, 1) on every sample a strand covers:
//   u_stage 0: flag both points of every covered segment (the points the lobe pass must shade);
//   u_stage 1: list the flagged points (u_stage 0's flags, one invocation per point);
//   u_stage 2: replace each strand sample by exposure x mix(radiance[a], radiance[b], t).
layout(local_size_x = 8, local_size_y = 8) in;
layout(rgba32f, binding = 0) uniform image2D u_colour;
layout(std430, binding = 3) readonly buffer Radiance { vec4 radiance[]; };
layout(std430, binding = 4) buffer Flags { uint flags[]; };
layout(std430, binding = 6) buffer List { uint list[]; };
layout(std430, binding = 7) buffer Count { uint list_count; };
layout(std430, binding = 8) readonly buffer Segments { uint segments[]; };  // (M, 2) point indices

uniform int u_stage;
uniform int u_points;
uniform float u_exposure;

void main() {
    if (u_stage == 1) {
        int i = int(gl_GlobalInvocationID.y * gl_NumWorkGroups.x * gl_WorkGroupSize.x + gl_GlobalInvocationID.x);
        if (i < u_points && flags[i] != 0u) list[atomicAdd(list_count, 1u)] = uint(i);
        return;
    }
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(p, imageSize(u_colour)))) return;
    vec4 c = imageLoad(u_colour, p);
    if (c.b != STRAND_SENTINEL) return;
    int seg = int(c.r + 0.5);
    uint a = segments[2 * seg], b = segments[2 * seg + 1];
    if (u_stage == 0) {
        flags[a] = 1u;
        flags[b] = 1u;
        return;
    }
    vec3 rad = mix(radiance[a].rgb, radiance[b].rgb, c.g);
    imageStore(u_colour, p, vec4(u_exposure * rad, c.a));
}

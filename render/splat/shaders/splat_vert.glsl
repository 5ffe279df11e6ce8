#version 430
// The splat method's vertex shader: one instance per Gaussian (front to back, the owner's sort),
// 4 vertices (a triangle strip) spanning the ellipse q = d^T Sigma'^-1 d <= 2 ln(opacity / ALPHA_MIN)
// in OpenCV pixels. Twin: render/splat/reference.py (screen_covariance, project, reach).
// Defines: STRIDE (vec4 per Gaussian), SH_K (coefficients per channel), LOW_PASS, JACOBIAN_CLAMP,
// ALPHA_MIN, NEAR_M, QUAD_MARGIN_PX.
#include "framebuffer_row.glsl"
layout(std430, binding = 0) readonly buffer Gaussians { vec4 data[]; };  // see render/splat/gl.py pack()
layout(std430, binding = 1) readonly buffer Order { uint order[]; };    // Gaussian of each instance
#include "splat_sh.glsl"
uniform mat3 rot;        // cam_from_world rotation (OpenCV axes)
uniform vec3 trans;      // cam_from_world translation
uniform vec4 intr;       // fx, fy, cx, cy
uniform float skew;
uniform vec2 size;       // W, H (pixels)
uniform vec3 eye_center; // the eye's centre (world)
flat out vec2 v_mean;    // centre, OpenCV pixels
flat out vec3 v_conic;   // inverse screen covariance (a, b, c)
flat out vec4 v_colour;  // display colour, opacity
flat out float v_z;      // z-depth of the centre

void main() {
    uint g = order[gl_InstanceID];
    uint base = g * uint(STRIDE);
    vec4 p = data[base];
    vec4 ca = data[base + 1u];
    vec4 cb = data[base + 2u];
    gl_Position = vec4(0.0, 0.0, 2.0, 1.0);  // clipped unless set below
    vec3 t = rot * p.xyz + trans;
    if (!(t.z > NEAR_M) || !(p.w >= ALPHA_MIN)) return;
    mat3 sigma = mat3(ca.x, ca.y, ca.z, ca.y, ca.w, cb.x, ca.z, cb.x, cb.y);  // symmetric
    float fx = intr.x, fy = intr.y;
    float limx = JACOBIAN_CLAMP * 0.5 * size.x / fx, limy = JACOBIAN_CLAMP * 0.5 * size.y / fy;
    float x = clamp(t.x / t.z, -limx, limx) * t.z, y = clamp(t.y / t.z, -limy, limy) * t.z;
    // J as columns (GLSL is column-major): rows (fx/z, s/z, -(fx x + s y)/z^2), (0, fy/z, -fy y/z^2)
    mat3x2 J = mat3x2(fx / t.z, 0.0, skew / t.z, fy / t.z, -(fx * x + skew * y) / (t.z * t.z), -fy * y / (t.z * t.z));
    mat3 sc = rot * sigma * transpose(rot);
    mat2 cov = J * sc * transpose(J);
    cov[0][0] += LOW_PASS;
    cov[1][1] += LOW_PASS;
    float det = cov[0][0] * cov[1][1] - cov[0][1] * cov[0][1];
    v_conic = vec3(cov[1][1], -cov[0][1], cov[0][0]) / det;
    v_mean = vec2(fx * t.x / t.z + skew * t.y / t.z + intr.z, fy * t.y / t.z + intr.w);
    vec3 dir = normalize(p.xyz - eye_center);
    v_colour = vec4(sh_colour(base + 3u, dir), p.w);
    v_z = t.z;
    // the ellipse's axes: eigen decomposition of the 2 x 2 covariance
    float mid = 0.5 * (cov[0][0] + cov[1][1]);
    float rad = sqrt(max(mid * mid - det, 0.0));
    float l1 = mid + rad, l2 = max(mid - rad, 0.0);
    vec2 e1 = abs(cov[0][1]) > 1e-12 ? normalize(vec2(cov[0][1], l1 - cov[0][0]))
                                     : (cov[0][0] >= cov[1][1] ? vec2(1.0, 0.0) : vec2(0.0, 1.0));
    vec2 e2 = vec2(-e1.y, e1.x);
    float k = sqrt(2.0 * log(p.w / ALPHA_MIN));
    vec2 corner = vec2((gl_VertexID & 1) == 0 ? -1.0 : 1.0, (gl_VertexID & 2) == 0 ? -1.0 : 1.0);
    vec2 uv = v_mean + corner.x * (k * sqrt(l1) + QUAD_MARGIN_PX) * e1 + corner.y * (k * sqrt(l2) + QUAD_MARGIN_PX) * e2;
    gl_Position = vec4(image_to_ndc(uv, size), 0.0, 1.0);
}

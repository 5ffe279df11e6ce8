#version 430
// Pass 1 of the gather method: the kept views' RGB-D points as splats (GL points of side
// SPLAT_PX pixels, set by the owner); each carries its OpenCV z-depth in the eye.
// Twin: render/gather/reference.py front_depth, measured_first_depth (the fill drawn second,
// with z_offset beyond every real z, so that MIN keeps a measured z wherever one lands), back_depth
// (v_true_z: the z without the offset).
in vec3 in_pos;
uniform mat4 view_proj;   // world -> clip of the eye
uniform vec4 eye_z_row;   // third row of the eye's cam_from_world: z = dot(row, (p, 1))
uniform float z_offset;   // 0 for the measured points, fill_offset for the geometry's fill
flat out float v_z;
flat out float v_true_z;

void main() {
    gl_Position = view_proj * vec4(in_pos, 1.0);
    v_true_z = dot(eye_z_row, vec4(in_pos, 1.0));
    v_z = v_true_z + z_offset;
}

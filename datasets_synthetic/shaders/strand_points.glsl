// The strand points of the GL synthetic renderer (datasets_synthetic/strand_gl.py, point_records):
// one record per tube ring.  centre.w = ring radius (m), tangent.w = ring sides, colour.w = ambient
// occlusion, frame = unit direction to the ring's first vertex (N), frame.w = specular strength.
struct Point { vec4 centre; vec4 tangent; vec4 colour; vec4 frame; };
layout(std430, binding = 0) readonly buffer Points { Point pts[]; };

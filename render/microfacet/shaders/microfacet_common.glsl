// Shared by the microfacet and VDTM shaders: input cameras, camera selection (docs/methods.md §1.3),
// slice placement (§1.2) and the RGBz clip (Eq. 2, §1.4).  Numpy twin: render/microfacet/geometry.py.
// Defines expected: K_BLEND, K_CAND, MAX_SLICES, PHI_EPS, WEIGHT_EPS, ULR_THRESHOLD_FACTOR.

struct Cam {
    mat4 cfw;      // world -> camera (OpenCV axes)
    vec4 intr;     // fx, fy, cx, cy (OpenCV pixel centres)
    vec4 size;     // W, H, skew, 0
    vec4 center;   // camera centre (world), w unused
    vec4 proj[3];  // rows of K [R | t] (float64 product): homogeneous projection of (p, 1)
};
layout(std430, binding = 0) readonly buffer Cameras { Cam cams[]; };
// Per frame: cam_project_h(i, eye_pos) of every camera (render.microfacet.gl.eye_projections).
layout(std430, binding = 5) readonly buffer EyeProjections { vec4 eye_h[]; };

uniform int n_cams;
uniform vec3 eye_pos;
uniform vec3 eye_right;
uniform vec3 eye_up;
uniform float spacing;      // slice spacing l (m)
uniform float voxel_size;   // w of the current level (m)
uniform float near_plane;   // slices closer than this along their ray are dropped

// Homogeneous projection of a world point into camera i: (u z, v z, z), affine in p, so it
// interpolates exactly across a slice; u, v OpenCV pixels, z = z-depth D.
vec3 cam_project_h(int i, vec3 p) {
    vec4 q = vec4(p, 1.0);
    return vec3(dot(cams[i].proj[0], q), dot(cams[i].proj[1], q), dot(cams[i].proj[2], q));
}

// Projection of a world point into camera i: (u, v) OpenCV pixels and z-depth D.
vec3 cam_project(int i, vec3 p) {
    vec3 h = cam_project_h(i, p);
    return vec3(h.xy / max(h.z, 1e-30), h.z);
}

bool footprint_inside(int i, vec3 p, float r) {
    vec3 uvz = cam_project(i, p);
    if (uvz.z - max(r, 0.0) <= 0.0) return false;
    float ru = cams[i].intr.x * r / uvz.z;
    float rv = cams[i].intr.y * r / uvz.z;
    return uvz.x - ru >= -0.5 && uvz.x + ru <= cams[i].size.x - 0.5 &&
           uvz.y - rv >= -0.5 && uvz.y + rv <= cams[i].size.y - 0.5;
}

// Candidates in increasing phi (-1 past the valid ones) and ULR weights of the first K_BLEND.
void select_cameras(vec3 p, float r, out int cand[K_CAND], out float wts[K_BLEND]) {
    const int NB = K_CAND + 1;
    float bphi[NB];
    int bidx[NB];
    for (int j = 0; j < NB; ++j) { bphi[j] = 1e30; bidx[j] = -1; }
    vec3 v = normalize(p - eye_pos);
    int nvalid = 0;
    for (int i = 0; i < n_cams; ++i) {
        if (!footprint_inside(i, p, r)) continue;
        vec3 u = normalize(p - cams[i].center.xyz);
        float phi = acos(clamp(dot(v, u), -1.0, 1.0));
        // stable insertion into the sorted list by compare-and-swap over constant slots
        // (registers: llvmpipe spills dynamically indexed local arrays)
        float cp = phi;
        int ci = i;
        for (int j = 0; j < NB; ++j) {
            bool before = cp < bphi[j];
            float tp = bphi[j];
            int ti = bidx[j];
            bphi[j] = before ? cp : tp;
            bidx[j] = before ? ci : ti;
            cp = before ? tp : cp;
            ci = before ? ti : ci;
        }
        nvalid = min(nvalid + 1, NB);
    }
    for (int j = 0; j < K_CAND; ++j) cand[j] = bidx[j];
    float last = bphi[max(nvalid - 1, 0)];
    float t = nvalid > K_BLEND ? bphi[K_BLEND] : ULR_THRESHOLD_FACTOR * max(last, PHI_EPS);
    float s = 0.0;
    for (int j = 0; j < K_BLEND; ++j) {
        float pj = max(bphi[j], PHI_EPS);
        float wj = j < nvalid ? max(1.0 - pj / t, 0.0) / pj : 0.0;
        wts[j] = wj; s += wj;
    }
    for (int j = 0; j < K_BLEND; ++j) wts[j] = s > 0.0 ? wts[j] / s : 0.0;
}

// Slice numbers [lo, hi] of the voxel at c (docs/methods.md §1.2); hi < lo: none.
void slice_range(vec3 c, out int lo, out int hi) {
    vec3 d = c - eye_pos;
    float sc = length(d);
    vec3 v = d / max(sc, 1e-12);
    float h = 0.5 * voxel_size * (abs(v.x) + abs(v.y) + abs(v.z));
    lo = int(ceil((sc - h) / spacing - SLAB_COVER));
    hi = int(floor((sc + h) / spacing + SLAB_COVER));
    if (hi < lo) { lo = int(round(sc / spacing)); hi = lo; }
    if (hi - lo + 1 > MAX_SLICES) { lo = int(round(sc / spacing)) - (MAX_SLICES - 1) / 2; hi = lo + MAX_SLICES - 1; }
    if (near_plane > 0.0) lo = max(lo, int(ceil(near_plane / spacing - 1e-7)));
}

// View direction and in-plane axes of the slices of the voxel at c.
void slice_frame(vec3 c, out vec3 v, out vec3 a, out vec3 b) {
    v = normalize(c - eye_pos);
    a = eye_right - dot(eye_right, v) * v;
    if (length(a) < 1e-6) a = eye_up - dot(eye_up, v) * v;
    a = normalize(a);
    b = cross(v, a);
}

// Half sizes of the slice quad at distance s (twin: microfacet_geometry.slice_half_extents).
vec2 slice_half_extents(vec3 c, vec3 v, vec3 a, vec3 b, float s) {
    float half_sq = 0.5 * SLICE_SIDE * voxel_size;
#if TIGHT_RECT
    float lim = RECT_CLAMP * half_sq;
    vec2 hab = vec2(0.0);
    for (int k = 0; k < 8; ++k) {
        vec3 X = c + 0.5 * voxel_size * vec3((k & 4) != 0 ? 1.0 : -1.0, (k & 2) != 0 ? 1.0 : -1.0,
                                             (k & 1) != 0 ? 1.0 : -1.0) - eye_pos;
        float dep = dot(X, v);
        if (dep <= 1e-9) return vec2(lim);
        vec3 Xp = X * (s / dep) - s * v;
        hab = max(hab, abs(vec2(dot(Xp, a), dot(Xp, b))));
    }
    return min(hab, vec2(lim));
#else
    return vec2(half_sq);
#endif
}

// The slices [lo, hi] of the voxel at c (slice_range), its candidate cameras and blend weights
// (select_cameras); false when none of its slices is drawn (cand and w are then not set).
bool voxel_slices(vec3 c, out int lo, out int hi, out int cand[K_CAND], out float w[K_BLEND]) {
    slice_range(c, lo, hi);
    if (hi < lo) return false;
    select_cameras(c, FOOTPRINT_SCALE * 0.5 * SLICE_SIDE * voxel_size, cand, w);
    return true;
}

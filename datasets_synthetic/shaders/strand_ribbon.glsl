// Ring formulas of the GL synthetic renderer's strands; numpy twins in datasets_synthetic/strands.py
// (ring_vertex, silhouette_vertices, front_chain), compared in tests/datasets_synthetic/test_strand_gl.py.

const float RIBBON_PI = 3.14159265358979323846;
const float RIBBON_DEGENERATE = 1e-9;

// Unit direction from a ring's centre to its k-th vertex (geometry.tube_sweep: cos a N + sin a B,
// a = 2 pi k / sides, B = T x N): the vertex's offset / r and its normal.
vec3 ring_direction(vec3 T, vec3 N, int k, int sides) {
    float a = 2.0 * RIBBON_PI * float(k) / float(sides);
    return cos(a) * N + sin(a) * cross(T, N);
}

// The ring's silhouette vertices seen from w_dir (unit, towards the viewer): the vertices with the
// largest and the smallest offset along u = w_dir x T (N when T is along w_dir), ties to the lower index.
ivec2 silhouette_vertices(vec3 T, vec3 N, int sides, vec3 w_dir) {
    vec3 u = cross(w_dir, T);
    float n = length(u);
    u = n > RIBBON_DEGENERATE ? u / n : N;
    int kr = 0, kl = 0;
    float xr = -1e30, xl = 1e30;
    for (int k = 0; k < sides; ++k) {
        float x = dot(ring_direction(T, N, k, sides), u);
        if (x > xr) { xr = x; kr = k; }
        if (x < xl) { xl = x; kl = k; }
    }
    return ivec2(kr, kl);
}

// The front chain of a segment: ring vertices start, start + 1, ... (mod sides), count of them,
// running from the right silhouette vertex over the front to the left one, the union of the two
// rings' chains (so both rings' silhouettes are inside); all the facets (count = sides + 1) when
// that union is a single vertex.  Returns (start, count).
ivec2 front_chain(ivec2 s0, ivec2 s1, int sides) {
    int half_n = sides / 2;
    int dr = (s1.x - s0.x + sides) % sides;
    if (dr > half_n) dr -= sides;
    int dl = (s1.y - s0.y + sides) % sides;
    if (dl > half_n) dl -= sides;
    int start = s0.x + min(dr, 0);
    int stop = s0.y + max(dl, 0);
    // (% of a negative operand is undefined in GLSL: shift by whole turns first; start >= -sides,
    // stop - start >= -2 sides)
    int count = (stop - start + 3 * sides) % sides + 1;
    // the rings disagree about the sides (a segment seen end-on, u turning over): every facet
    if (count < 2) count = sides + 1;
    return ivec2((start + sides) % sides, count);
}

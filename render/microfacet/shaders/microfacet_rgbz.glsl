// RGBz lookup, Eq. 2 and the blend (docs/methods.md §1.3-1.4).
// Twin: microfacet_geometry.sample_rgbz / classify / shade_fragments.
uniform sampler2DArray rgbz;   // layer i: rgb linear (x alpha with HAS_ALPHA) + z-depth (m, 0 = none) of camera i
// HAS_ALPHA (a model with a matte, render/microfacet/rgbz_textures.py): the colour carried is COL = vec4
// (premultiplied rgb, alpha), the alpha read from the matte layer at the same texel; else COL = vec3.
#if HAS_ALPHA && !defined(DEPTH_ONLY)
uniform sampler2DArray matte;  // layer i: alpha of camera i
#define COL vec4
#define COL_AT(t, ij, i) vec4((t).rgb, texelFetch(matte, ivec3(ij, i), 0).r)
#define COL_RGBA(c) (c)
#define COL_OPAQUE(c) vec4(c, 1.0)
#else
#define COL vec3
#define COL_AT(t, ij, i) (t).rgb
#define COL_RGBA(c) vec4(c, 1.0)
#define COL_OPAQUE(c) (c)
#endif
#ifdef DEPTH_ONLY
// Visibility pre-pass (microfacet_prepass_frag.glsl): the depths alone (layer i: z-depth of
// camera i), colours read as black; the decisions are those of the full RGBz lookup.
uniform sampler2DArray zdepth;
#endif

const int NO_VIEW = 0;   // outside the image, behind the camera, or occluded (d <= D - FREE_FACTOR tol)
const int PASS = 1;      // Eq. 2: |d - D| < tol
const int FREE = 2;      // the camera saw through this point (d == 0 or d >= D + FREE_FACTOR * tol)
const int UNSURE = 3;    // tol <= |d - D| < FREE_FACTOR * tol

uniform ivec2 tex_size;        // W, H of every RGBz layer

// Classify a point against layer i given its homogeneous projection pr = (u z, v z, z) in
// that camera (cam_project_h); col = its texel colour.
int rgbz_classify(int i, vec3 pr, float tol, out COL col, out float d) {
    col = COL(0.0);
    d = 0.0;
    if (pr.z <= 0.0) return NO_VIEW;
    vec3 uvz = vec3(pr.xy / pr.z, pr.z);
    ivec2 ij = ivec2(floor(uvz.xy + 0.5));
    if (ij.x < 0 || ij.y < 0 || ij.x >= tex_size.x || ij.y >= tex_size.y) return NO_VIEW;
#ifdef DEPTH_ONLY
    vec4 t = vec4(vec3(0.0), texelFetch(zdepth, ivec3(ij, i), 0).r);
#else
    vec4 t = texelFetch(rgbz, ivec3(ij, i), 0);
#endif
    col = COL_AT(t, ij, i);
    d = t.a;
    if (!(t.a > 0.0)) return FREE;
    float e = t.a - uvz.z;
    if (abs(e) < tol) return PASS;
    if (abs(e) < FREE_FACTOR * tol) return UNSURE;
    return e > 0.0 ? FREE : NO_VIEW;
}

// Classify world point p in camera i (projects it here; used per fragment by the VDTM baseline).
int rgbz_lookup(int i, vec3 p, float tol, out COL col) {
    float d;
    return rgbz_classify(i, cam_project_h(i, p), tol, col, d);
}

// Colour of a slice fragment, or false to discard it.  Unrolled over the K_BLEND = 3 blend
// cameras and K_CAND = 6 candidates (llvmpipe spills dynamically indexed local arrays).
// FALLBACK_RULE 0 ("vote"): the blend cameras that see the point (PASS, FREE, UNSURE) vote with
//   their weights; it is drawn when the passing share >= ALPHA_VOTE, coloured by the passing
//   cameras' weighted mean.  When no blend camera sees it, the first of the remaining
//   candidates (after the blend cameras) that passes or frees it decides (per-fragment fallback).
// FALLBACK_RULE 1 ("any"): blend the passing blend cameras; if none passes, the first passing
//   remaining candidate (the issue's literal fallback; fattens silhouettes).
#if K_BLEND != 3 || K_CAND != 6
#error "shade() is unrolled for K_BLEND = 3, K_CAND = 6"
#endif
// Parallax correction of a passing fragment's colour (DEPTH_REFINE > 0): march along the eye
// ray to where it meets camera i's depth map (fixed-point steps on z), and take the colour there
// when the ray point lies on that surface within REFINE_ACCEPT * tol.  Twin: refine_colours.
// pe = cam_project_h(i, eye_pos) (a flat varying: constant per camera and frame).
COL refine_colour(int i, vec3 pr, vec3 pe, float d, float tol, COL col) {
#if DEPTH_REFINE > 0
    vec3 dir = pr - pe;                  // the eye ray through the fragment, projected: pe + s dir
    if (!(abs(dir.z) > 1e-12)) return col;
    vec3 q = pr;
    vec4 t = vec4(0.0);
    ivec2 ij = ivec2(0);
    for (int it = 0; it < DEPTH_REFINE; ++it) {
        float s = (d - pe.z) / dir.z;
        vec3 q2 = pe + s * dir;
        if (!(q2.z > 0.0) || abs(q2.z - pr.z) > REFINE_RANGE * tol) return col;
        ij = ivec2(floor(q2.xy / q2.z + 0.5));
        if (ij.x < 0 || ij.y < 0 || ij.x >= tex_size.x || ij.y >= tex_size.y) return col;
        t = texelFetch(rgbz, ivec3(ij, i), 0);
        if (!(t.a > 0.0)) return col;
        q = q2;
        d = t.a;
    }
    if (abs(d - q.z) < REFINE_ACCEPT * tol) return COL_AT(t, ij, i);
#endif
    return col;
}

// src / wsrc: the passing blend camera of largest weight so far (the dominant camera, debug view).
int vote(int ci, vec3 pr, vec3 pe, float w, float tol, inout COL acc, inout float wpass, inout float wseen,
         inout int src, inout float wsrc) {
    if (ci < 0) return NO_VIEW;
    COL c;
    float d;
    int st = rgbz_classify(ci, pr, tol, c, d);
    if (st == PASS) c = refine_colour(ci, pr, pe, d, tol, c);
    if (st == PASS && w > wsrc) { src = ci; wsrc = w; }
    if (st == PASS) { acc += w * c; wpass += w; wseen += w; }
    else if (st == FREE) wseen += w;
    else if (st == UNSURE) wseen += UNSURE_WEIGHT * w;
    return st;
}

// Fallback step: the first candidate that decides (PASS or FREE under "vote"; PASS under "any");
// src = that candidate.
void fallback(int ci, vec3 pr, vec3 pe, float tol, inout int decided, inout COL colour, inout int src) {
    if (decided != 0 || ci < 0) return;
    COL c;
    float d;
    int st = rgbz_classify(ci, pr, tol, c, d);
    if (st == PASS) c = refine_colour(ci, pr, pe, d, tol, c);
#if FALLBACK_RULE == 0
    if (st == PASS || st == FREE) { decided = st; colour = c; src = ci; }
#else
    if (st == PASS) { decided = st; colour = c; src = ci; }
#endif
}

// p0..p5: homogeneous projections of the fragment into the candidates (cam_project_h);
// e[k]: the eye's projection into candidate k (refine_colour).  src: the camera whose colour
// dominates a drawn fragment (largest passing blend weight, or the deciding fallback), else -1.
bool shade(vec3 p0, vec3 p1, vec3 p2, vec3 p3, vec3 p4, vec3 p5, vec3 e[K_CAND], ivec4 c03, ivec2 c45, vec3 w,
           float tol, out COL colour, out int src) {
    COL acc = COL(0.0);
    float wpass = 0.0, wseen = 0.0, wsrc = 0.0;
    colour = COL(0.0);
    src = -1;
    int st0 = vote(c03.x, p0, e[0], w.x, tol, acc, wpass, wseen, src, wsrc);
#if FALLBACK_RULE == 0
    // Early out (exact): weights sum to 1, so when the best camera frees the point with
    // weight w0, at most 1 - w0 can pass; drawing needs wpass >= ALPHA_VOTE (w0 + wpass).
    if (st0 == FREE && (1.0 - w.x) * (1.0 - ALPHA_VOTE) < ALPHA_VOTE * w.x) return false;
#endif
    vote(c03.y, p1, e[1], w.y, tol, acc, wpass, wseen, src, wsrc);
    vote(c03.z, p2, e[2], w.z, tol, acc, wpass, wseen, src, wsrc);
#if FALLBACK_RULE == 0
    if (wseen > WEIGHT_EPS) {
        if (wpass < ALPHA_VOTE * wseen || !(wpass > WEIGHT_EPS)) return false;
        colour = acc / wpass;
        return true;
    }
#else
    if (wpass > WEIGHT_EPS) { colour = acc / wpass; return true; }
#endif
    int decided = 0;   // the blend cameras did not decide: try the next N_FALLBACK candidates
    src = -1;
#if N_FALLBACK > 0
    fallback(c03.w, p3, e[3], tol, decided, colour, src);
#endif
#if N_FALLBACK > 1
    fallback(c45.x, p4, e[4], tol, decided, colour, src);
#endif
#if N_FALLBACK > 2
    fallback(c45.y, p5, e[5], tol, decided, colour, src);
#endif
    return decided == PASS;
}

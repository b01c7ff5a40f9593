/* store/ptex/ptextri_filter.c - Ptex's point and triangle filters on triangle-mesh sets (see
 * ptextri.h; the maths is in docs/ptex.md, "Triangle meshes").
 *
 * The triangle filter works in the face's barycentric coordinates (u, v, w = 1 - u - v). The
 * footprint (du/dx, dv/dx), (du/dy, dv/dy) becomes an ellipse A du^2 + B du dv + C dv^2 <= 1
 * (converted to the equilateral domain to clamp its eccentricity to 15 and make it at least
 * half a texel across, then back); its minor axis picks the resolution; the kernel is the
 * ellipse scaled by 3.5, a Gaussian exp(-Q * 3.5^2 / 2) inside it, bounded by u, v, w
 * intervals. Traverse splits the kernel at each edge it overhangs (u < 0: edge 2, v < 0: edge
 * 0, w < 0: edge 1, in that order) and carries the piece into the neighbour's frame (the
 * unfolding that maps the shared edge onto itself), recursively; at a boundary edge the
 * overhang is dropped and the result renormalised, as Ptex does. The taps of a face are its
 * small triangles: the upright ones (texel (x, y), centroid (x + 1/3, y + 1/3)) and the
 * inverted ones (stored mirrored, visited as upright ones of the face flipped across its
 * diagonal), each swept row by row with Q updated by finite differences, in float, in the
 * order Ptex uses, so the taps are the library's (the weights: below).
 *
 * Discard: no piece crosses an edge; the result is divided by the weight kept; coverage =
 * kept / the weight of the whole kernel (over the triangle lattice extended past the face),
 * summed only when the caller passes a coverage array (it is two more sweeps).
 * Clamp: a tap outside the face reads the small triangle under the point of the face nearest
 * its centroid (u, v clamped to >= 0, then pulled back onto u + v = 1 along (1, 1)); coverage 1.
 * Each row is cut into runs (row_clamp): taps inside the face read in place, runs that fold
 * onto one texel or onto a line of texels read without the fold; the band past the diagonal
 * edge is walked (row_band_t: the same texels as folding each tap, fold_tap, which the
 * per-tap build st_ptextri_batch_pertap keeps). At levels of 8 x 8 texels or more the lean
 * and general builds instead run Clamp's whole kernel a row a lane (rows_apply_t with FOLD,
 * below), each tap's texel by fold_tap's operations a lane (fold_idx8).
 *
 * Speed: the sweeps and the point filter's batch loop are instances per texel type and
 * channel count (no per-tap switch); the arithmetic and its order are the same in each, so
 * every instance gives the same bits (tests/unit/test_ptextri_outputs.c). The weights are not
 * libm's expf per tap (Ptex's; st_ptextri_batch_pertap keeps it for the tests, the old
 * bits): the read sweeps (Traverse, Discard's kept taps, Clamp's kernels inside the face)
 * at a level of 8 x 8 texels or more run a piece's rows a lane, eight rows at a time
 * (rows_apply_t: every kept tap weighed by the quad filters' polynomial exp, pk_exp2_4's
 * operations, each row summed in its own lane, the lanes added by one tree; docs/ptex-log.md,
 * "tri29"); at smaller levels they weigh the kept taps of rows of 3 taps or more four at a
 * time with that exp (row_read4, pk_exp2_4: within about 2e-7; docs/ptex-log.md, "trix"),
 * shorter rows one expf a tap. Clamp's kernels that overhang the face, at a level of 8 x 8
 * texels or more, run through the same rows a lane (rows_apply_t with FOLD: the whole
 * kernel's rows, each tap's texel by fold_idx8 - fold_tap's float and int operations a lane,
 * made eight steps ahead of the taps' work - and weighed by pk_exp2_4's operations;
 * docs/ptex-log.md, "Session 33, tri33"). Discard's whole-kernel weight, and Clamp's fold
 * sweeps at smaller levels (seamtex's own, no Ptex reference), step them by recurrence
 * (pt_rec, pt_cur: within about 1e-6 of the per-tap expf; docs/ptex-log.md, "Session 13,
 * tri6"). Those recurrence sweeps run lean rows (lean_fold_row, lean_band, lean_run: the
 * general rows' taps, texels, weights and order with less work a row); the general rows stay
 * for st_ptextri_batch_general, which the tests compare them with bit for bit (docs/ptex-log.md,
 * "Session 15, tri8"). Clamp's lean fold rows find their kept runs eight rows at a time
 * (rows_kept8), and the lean fold and whole-weight sweeps have AVX2 instances, chosen at run
 * time, the same C and bits as the baseline ones (st_ptextri_batch_baseline; docs/ptex-log.md,
 * "tri10"). st_ptextri_batch and _baseline also take shortcuts of their own ("tri23", "tri30"),
 * which the general and per-tap builds do not, so the tests compare them: a query whose
 * footprint and face size are the last query's reuses its kernel shape (tk_shape, tk_cache)
 * and the recurrence's factors (pt_kfc, kf_get), Clamp's inverted fold sweep's first rows and
 * cursor seed (levels below 8 x 8) are made before the upright sweep's rows (fold_pre: the
 * two sweeps' dependent chains overlap; "Session 32, tri32"), and Traverse's and Discard's
 * pieces and
 * Clamp's kernels inside the face (apply_folded) at resolution 0 (a 1 x 1 level: one tap at
 * most) are applied whole (piece_r1) instead of by iterators and the sweeps, as are those at
 * resolution 1 of a face with texels (piece_r2: at most three upright taps and one inverted;
 * docs/ptex-log.md, "trip24"), at resolution 2 (piece_r4: rows of up to 4 taps, weighed as
 * row_read4 and row_step weigh them; docs/ptex-log.md, "tp25") and at resolution 3 or more
 * (piece_rn: piece_bounds, then rows_apply_t as the long way's sweep2_t calls it; "tri29").
 */
#include "ptextri.h"

#include <math.h>
#include <stddef.h>
#include <string.h>

#include "ptex_format.h"
#include "ptexfilter_kernel.h"
#include "ptexres.h"
#include "trilevel.h"

#ifdef __SSE2__
#include <emmintrin.h>
#endif
#if (defined(__x86_64__) || defined(__i386__)) && defined(__GNUC__)
#include <immintrin.h>
#endif

#define PT_MAX_DEPTH  24   /* edge crossings in a row; a closed mesh needs a few */
#define PT_MAX_PIECES 256  /* pieces per query; bounds the work a hostile adjacency can cause */


/* GCC's SLP vectoriser joins the loads of adjacent kernel fields (u and v, two bounds) into
 * one wide load; right after the fields were stored one by one (a piece just reoriented or
 * clamped) such a load cannot take its value from the store buffer and waits for the stores
 * to reach the cache. The functions that read a piece just made keep their loads apart. */
#if defined(__GNUC__) && !defined(__clang__)
#define PT_NO_SLP __attribute__((optimize("no-tree-slp-vectorize")))
#else
#define PT_NO_SLP
#endif

typedef float pt_v4f __attribute__((vector_size(16)));
typedef int32_t pt_v4i __attribute__((vector_size(16)));
typedef double pt_v2d __attribute__((vector_size(16)));

static const float PT_WIDTH = 3.5f;  /* kernel extent in filter widths (Ptex's) */

/* The kernel in normalised barycentric coordinates. */
typedef struct tk {
    int res;               /* log2 of the resolution asked for */
    float u, v;            /* centre; w = 1 - u - v */
    float lo[3], hi[3];    /* bounds of u, v, w */
    float A, B, C;         /* ellipse: A du^2 + B du dv + C dv^2 < 1 */
} tk;

/* One sweep over the upright (or, flipped, the inverted) small triangles, in texel units. */
typedef struct ti {
    int R;                 /* texels per row */
    float u, v;            /* centre, texel units, relative to the tap centroids */
    int lo[3], hi[3];      /* index bounds of u, v, w (adjacent: iterators stores them so) */
    float A, B, C;         /* ellipse over texel units */
    float wscale;          /* 1 / R^2: the area of a tap */
    int valid;
    int odd;               /* the flipped sweep: taps are the inverted triangles */
} ti;

enum { PT_LEAN, PT_PERTAP, PT_GENERAL, PT_LEAN_BASE }; /* the builds st_ptextri_batch* run
                                                       * (tri_batch's wmode: tc.fold and tc.wt
                                                       * follow from it; PT_LEAN_BASE: PT_LEAN
                                                       * without the AVX2 instances) */

struct pt_kf;
struct pt_kfc;

typedef struct tc {
    const st_set *s;
    unsigned nc, dt;
    /* a piece's two sweeps (each when valid), their weights added to weight in turn */
    void (*rd)(struct tc *c, const ti *ev, const ti *od, const uint8_t *data,
               int constant);   /* SW_READ */
    void (*fold)(struct tc *c, const ti *ev, const ti *od, const uint8_t *data,
                 int constant); /* SW_FOLD */
    /* a sweep's whole weight (SW_WEIGHT; kf: the piece's factors, shared by its sweeps) */
    float (*wt)(struct tc *c, const struct ti *it, struct pt_kf *kf);
    pt_v4f acc;            /* channel sums, lanes 0..nc-1 (the rest: 0, or lane 3 scratch
                            * when nc < 4); loaded and stored whole by each sweep */
    float weight;          /* weight applied */
    unsigned pieces;
    int avx2;              /* Traverse's split_apply_avx2 (PT_LEAN on a CPU with AVX2) */
    /* a piece at resolution 0 applied whole, without its sweeps' bounds (piece_r1: Traverse,
     * Discard without coverage); 0: not done (the caller takes the long way) */
    int (*p1)(struct tc *c, const tk *k, const uint8_t *data);
    /* the same for a piece at resolution 1 of a face with texels (piece_r2), at resolution 2
     * (piece_r4: its AVX2 instance when avx2) and at 3 or more (piece_rn: the same) */
    int (*p2)(struct tc *c, const tk *k, const uint8_t *data);
    int (*p4)(struct tc *c, const tk *k, const uint8_t *data);
    int (*pn)(struct tc *c, const tk *k, const uint8_t *data);
    /* the last piece's recurrence factors and their key (kf_get; the lean builds' own, else
     * NULL), kept across the batch's queries */
    struct pt_kfc *kfc;
} tc;

static inline float fmaxf_(float a, float b) { return a > b ? a : b; }
static inline float fminf_(float a, float b) { return a < b ? a : b; }

/* A kernel's bounds (lanes 0..2 of lo, hi: u, v, w; lane 3 unused) clamped into the triangle,
 * the scalar clamp's operations a lane: lo = lo > 0 ? lo : 0 (maxps), then hi = hi < t ? hi :
 * t (minps) with t = 1 - (the other two lower bounds' sum). */
__attribute__((always_inline)) static inline void clamp_bounds4(pt_v4f *lo, pt_v4f *hi)
{
#ifdef __SSE2__
    const pt_v4f one = {1.0f, 1.0f, 1.0f, 1.0f};
    pt_v4f l = (pt_v4f)_mm_max_ps((__m128)*lo, _mm_setzero_ps());
    pt_v4f t = one - (__builtin_shufflevector(l, l, 1, 2, 0, 3) +
                      __builtin_shufflevector(l, l, 2, 0, 1, 3));
    *hi = (pt_v4f)_mm_min_ps((__m128)*hi, (__m128)t);
    *lo = l;
#else
    pt_v4f l = *lo, h = *hi;
    for (int i = 0; i < 3; i++)
        l[i] = fmaxf_(l[i], 0.0f);
    h[0] = fminf_(h[0], 1.0f - (l[1] + l[2]));
    h[1] = fminf_(h[1], 1.0f - (l[2] + l[0]));
    h[2] = fminf_(h[2], 1.0f - (l[0] + l[1]));
    *lo = l;
    *hi = h;
#endif
}

/* The part of a kernel that depends on the footprint only (not on (u, v)): the resolution,
 * the ellipse and the half extents of u, v, w (build_kernel's first steps). */
typedef struct tk_shape {
    int res;
    float A, B, C;
    float uw, vw, ww;
} tk_shape;

__attribute__((always_inline)) static inline void
build_shape(tk_shape *sh, float uw1, float vw1, float uw2, float vw2, float width, float blur,
            unsigned face_log2)
{
    const float sqrt3 = 1.7320508075688772f;
    /* the footprint's ellipse in (u, v) */
    float sAC = 0.25f * width * width, sB = -2.0f * sAC;
    float A = (vw1 * vw1 + vw2 * vw2) * sAC;
    float B = (uw1 * vw1 + uw2 * vw2) * sB;
    float C = (uw1 * uw1 + uw2 * uw2) * sAC;
    /* to the equilateral (cartesian) domain */
    float Ac = 0.75f * A;
    float Bc = (sqrt3 / 2) * (B - A);
    float Cc = 0.25f * A - 0.5f * B + C;
    /* blur that clamps the eccentricity to 15, keeps it a texel wide, or is asked for */
    const float ecc = 15.0f, ratio = (ecc * ecc + 1.0f) / (ecc * ecc - 1.0f);
    float X = sqrtf((Ac - Cc) * (Ac - Cc) + Bc * Bc);
    float b_e = 0.5f * (ratio * X - (Ac + Cc));
    float half_texel = 0.5f / (float)(1u << face_log2);
    float b_t = half_texel * half_texel;
    float b_b = 0.25f * blur * blur;
    float b = fmaxf_(b_b, fmaxf_(b_e, b_t));
    Ac += b;
    Cc += b;
    /* minor radius -> resolution */
    float m = sqrtf(2.0f * (Ac * Cc - 0.25f * Bc * Bc) / (Ac + Cc + X));
    int r = pk_res_from_width(2.0f * m);
    sh->res = r > 0 ? r : 0;
    /* back to the triangle domain, scaled to the kernel's extent */
    A = (float)(4 / 3.0) * Ac;
    B = (2 / sqrt3) * Bc + A;
    C = -0.25f * A + 0.5f * B + Cc;
    float sc = PT_WIDTH * PT_WIDTH;
    A *= sc;
    B *= sc;
    C *= sc;
    sh->uw = fminf_(sqrtf(C), 1.0f);
    sh->vw = fminf_(sqrtf(A), 1.0f);
    sh->ww = fminf_(sqrtf(A - B + C), 1.0f);
    sh->A = A;
    sh->B = B;
    sh->C = C;
}

/* The kernel of shape sh centred at (u, v). */
__attribute__((always_inline)) static inline void kernel_at(tk *k, const tk_shape *sh, float u,
                                                            float v)
{
    float uw = sh->uw, vw = sh->vw, ww = sh->ww;
    float w = 1.0f - u - v;
    k->res = sh->res;
    k->u = u;
    k->v = v;
    k->lo[0] = u - uw; k->lo[1] = v - vw; k->lo[2] = w - ww;
    k->hi[0] = u + uw; k->hi[1] = v + vw; k->hi[2] = w + ww;
    k->A = sh->A;
    k->B = sh->B;
    k->C = sh->C;
}

/* The last shape a batch built and what it was built from (the query's four derivatives'
 * bits and the face's ulog2; the width and blur are the batch's): a query with the same
 * footprint on a face of the same size (fixed-footprint work: a bake, one filter width, an
 * orthographic view of affinely mapped faces; under perspective derivatives vary and a query
 * pays only the key's compare) takes the shape instead of rebuilding it - the same function
 * of the same inputs, so the same bits. */
typedef struct tk_cache {
    int valid;
    unsigned face_log2;
    uint32_t key[4];
    tk_shape sh;
} tk_cache;

__attribute__((always_inline)) static inline void
build_kernel(tk *k, float u, float v, const st_query *q, float width, float blur,
             unsigned face_log2, tk_cache *kc)
{
    if (kc) {
        _Static_assert(offsetof(st_query, dvdx) == offsetof(st_query, dudx) + 4 &&
                           offsetof(st_query, dudy) == offsetof(st_query, dudx) + 8 &&
                           offsetof(st_query, dvdy) == offsetof(st_query, dudx) + 12,
                       "the four derivatives adjacent");
        uint32_t key[4];
        memcpy(key, &q->dudx, 16);
        if (!(kc->valid && kc->face_log2 == face_log2 && memcmp(key, kc->key, 16) == 0)) {
            build_shape(&kc->sh, q->dudx, q->dvdx, q->dudy, q->dvdy, width, blur, face_log2);
            kc->valid = 1;
            kc->face_log2 = face_log2;
            memcpy(kc->key, key, 16);
        }
        kernel_at(k, &kc->sh, u, v);
        return;
    }
    tk_shape sh;
    build_shape(&sh, q->dudx, q->dvdx, q->dudy, q->dvdy, width, blur, face_log2);
    kernel_at(k, &sh, u, v);
}

/* The piece of k past edge e of its face (where coordinate i, 0 on that edge, is below 0: k
 * with hi[i] = 0), carried into the neighbour whose edge ae it is, written to ka
 * (st_tri_across_edge: the unfolding across the shared edge). The map renames (u, v, w)
 * cyclically by s = e - ae (mod 3), so the ellipse only rotates; every coordinate decreases
 * with the one it reads, so lower bounds come from upper ones and back. */
__attribute__((always_inline)) static inline void across_t(const tk *k, unsigned i, unsigned e,
                                                         unsigned ae, tk *ka)
{
    /* st_tri_across_edge's map on the centre, hi (-> lo) and lo (-> hi) at once, a coordinate
     * a lane: new coordinate j reads old (j + s) % 3 and is minus it (j == cz) or 1 minus it,
     * the same operation on the same float as the scalar map */
    static const uint8_t s_of[3][3] = {{0, 2, 1}, {1, 0, 2}, {2, 1, 0}}; /* (e - ae) mod 3 */
    static const uint8_t next_of[3] = {1, 2, 0};                          /* (ae + 1) mod 3 */
    unsigned s = s_of[e][ae], cz = next_of[ae];
    pt_v4f p = {k->u, k->v, 1.0f - k->u - k->v, 0.0f};
    static const pt_v4i lane[3] = {{-1, 0, 0, 0}, {0, -1, 0, 0}, {0, 0, -1, 0}};
    pt_v4f lo = {k->lo[0], k->lo[1], k->lo[2], 0.0f}, hi = {k->hi[0], k->hi[1], k->hi[2], 0.0f};
    pt_v4i hb;
    memcpy(&hb, &hi, 16);
    hb &= ~lane[i]; /* hi[i] = +0 */
    memcpy(&hi, &hb, 16);
    if (s == 1) {
        p = __builtin_shufflevector(p, p, 1, 2, 0, 3);
        lo = __builtin_shufflevector(lo, lo, 1, 2, 0, 3);
        hi = __builtin_shufflevector(hi, hi, 1, 2, 0, 3);
    } else if (s == 2) {
        p = __builtin_shufflevector(p, p, 2, 0, 1, 3);
        lo = __builtin_shufflevector(lo, lo, 2, 0, 1, 3);
        hi = __builtin_shufflevector(hi, hi, 2, 0, 1, 3);
    }
    const pt_v4i m = lane[cz];
    const pt_v4f one = {1.0f, 1.0f, 1.0f, 1.0f};
    pt_v4i pn, ln, hn, po, lon, hon;
    pt_v4f t;
    t = -p; memcpy(&pn, &t, 16);
    t = -lo; memcpy(&ln, &t, 16);
    t = -hi; memcpy(&hn, &t, 16);
    t = one - p; memcpy(&po, &t, 16);
    t = one - lo; memcpy(&lon, &t, 16);
    t = one - hi; memcpy(&hon, &t, 16);
    pt_v4i np = (pn & m) | (po & ~m), nhi = (ln & m) | (lon & ~m), nlo = (hn & m) | (hon & ~m);
    pt_v4f npf, nlof, nhif;
    memcpy(&npf, &np, 16);
    memcpy(&nlof, &nlo, 16);
    memcpy(&nhif, &nhi, 16);
    ka->res = k->res;
    ka->u = npf[0];
    ka->v = npf[1];
    for (int j = 0; j < 3; j++) {
        ka->lo[j] = nlof[j];
        ka->hi[j] = nhif[j];
    }
    float A = k->A, B = k->B, C = k->C;
    if (s == 2) {        /* u' = w, v' = u */
        ka->A = C;
        ka->B = 2.0f * C - B;
        ka->C = A + C - B;
    } else if (s == 1) { /* u' = v, v' = w */
        ka->A = A + C - B;
        ka->B = 2.0f * A - B;
        ka->C = A;
    } else {
        ka->A = A;
        ka->B = B;
        ka->C = C;
    }
}

/* (int)ceilf(x) without the libm call where the conversion is exact (|x| < 2^30, which the
 * bounds of a kernel always are). */
static inline int ceil_int(float x)
{
    if (!(fabsf(x) < 1073741824.0f))
        return (int)ceilf(x);
    int t = (int)x; /* truncates towards 0 */
    return t + ((float)t < x);
}


/* Whether every lane of x is inside |x| < 2^30 (false for a NaN). */
static inline pt_v4i small4(pt_v4f x)
{
    pt_v4i bits;
    memcpy(&bits, &x, 16);
    bits &= 0x7fffffff;
    pt_v4f ax;
    memcpy(&ax, &bits, 16);
    return ax < 1073741824.0f;
}

/* ceil_int of the four lanes of x, which are inside |x| < 2^30: (int)x plus one where that is
 * below x (the same ints as ceil_int, lane by lane). */
static inline pt_v4i ceil_int4(pt_v4f x)
{
    pt_v4i t = __builtin_convertvector(x, pt_v4i); /* truncates towards 0 */
    return t - (__builtin_convertvector(t, pt_v4f) < x); /* a true compare is -1 */
}

/* The lanes of m that are true (-1), as the bits of an int. */
static inline int mask4(pt_v4i m)
{
#ifdef __SSE2__
    return _mm_movemask_ps((__m128)m);
#else
    return (m[0] & 1) | (m[1] & 2) | (m[2] & 4) | (m[3] & 8);
#endif
}

/* The twelve index bounds of kernel k's two sweeps at resolution fR, before their ceilings, as
 * three lanes (lane 3 unused): a = upright lo 0..2, hi 0; b = upright hi 1, 2, inverted lo 0,
 * 1; c = inverted lo 2, hi 0..2, each R x - 1/3 (the inverted sweep seen through its flip);
 * with clamp, the bounds clamped into the triangle first (clamp_bounds4). iterators_t and the
 * whole-piece shortcuts (piece_r2_t, piece_r4_t) take the same operations from here. */
__attribute__((always_inline)) static inline void bound_lanes(const tk *k, float fR, int clamp,
                                                             pt_v4f *a, pt_v4f *b, pt_v4f *c)
{
    const float third = (float)(1 / 3.0);
    pt_v4f lo = {k->lo[0], k->lo[1], k->lo[2], 0.0f}, hi = {k->hi[0], k->hi[1], k->hi[2], 0.0f};
    const pt_v4f one = {1.0f, 1.0f, 1.0f, 1.0f};
    if (clamp)
        clamp_bounds4(&lo, &hi);
    pt_v4f hi1 = one - hi, lo1 = one - lo;
    pt_v4f n2 = -__builtin_shufflevector(hi, lo, 2, 6, 2, 6); /* -hi[2], -lo[2] */
    *a = __builtin_shufflevector(lo, hi, 0, 1, 2, 4) * fR - third;
    *b = __builtin_shufflevector(hi, hi1, 1, 2, 5, 4) * fR - third;
    *c = __builtin_shufflevector(n2, lo1, 0, 5, 4, 1) * fR - third;
}

/* Which sweeps the ceilings ia, ib, ic of bound_lanes' lanes leave valid (hi[j] > lo[j] for
 * j = 0..2, the three compares of each sweep at once): bit 0 the upright sweep, bit 1 the
 * inverted one. */
static inline int sweeps_valid(pt_v4i ia, pt_v4i ib, pt_v4i ic)
{
    pt_v4i ehi = __builtin_shufflevector(ia, ib, 3, 4, 5, 5);
    pt_v4i olo = __builtin_shufflevector(ib, ic, 2, 3, 4, 4);
    pt_v4i ohi = __builtin_shufflevector(ic, ic, 1, 2, 3, 3);
    return ((mask4(ehi > ia) & 7) == 7) | ((mask4(ohi > olo) & 7) == 7) << 1;
}

/* The two sweeps of kernel k at resolution 2^res: upright taps, and inverted ones seen
 * through the flip u' = 1 - v, v' = 1 - u, w' = -w (which makes them upright). With clamp,
 * the kernel kept inside the face: lower bounds raised to 0, upper bounds to what the other
 * two lower bounds leave (k itself is not changed). The twelve index bounds are taken four at
 * a time, each lane with the scalar expression's operations, from the six bounds held in
 * registers (read one by one: a wide load of bounds just stored one by one would wait for the
 * stores instead of taking their values from the store buffer). */
__attribute__((always_inline)) static inline void iterators_t(const tk *k, int res, int clamp,
                                                            ti *ev, ti *od)
{
    int R = 1 << res;
    float fR = (float)R, third = (float)(1 / 3.0);
    float Finv = 1.0f / (fR * fR * (k->A * k->C - 0.25f * k->B * k->B));
    float Ak = k->A * Finv, Bk = k->B * Finv, Ck = k->C * Finv;
    ev->R = od->R = R;
    /* 1 / R^2 = 2^(-2 res) exactly (res <= 15): its bits instead of a division */
    uint32_t wsb = (uint32_t)(127 - 2 * res) << 23;
    float wscale;
    memcpy(&wscale, &wsb, 4);
    ev->wscale = od->wscale = wscale;
    ev->odd = 0;
    od->odd = 1;
    ev->u = k->u * fR - third;
    ev->v = k->v * fR - third;
    /* the bounds a coordinate a lane: ev lo 0..2, hi 0; ev hi 1, 2, od lo 0, 1; od lo 2, hi 0..2 */
    pt_v4f a, b, c;
    bound_lanes(k, fR, clamp, &a, &b, &c);
    pt_v4i ia, ib, ic, ok = small4(a) & small4(b) & small4(c);
    ok &= __builtin_shufflevector(ok, ok, 2, 3, 0, 1);
    if (__builtin_expect((ok & __builtin_shufflevector(ok, ok, 1, 0, 3, 2))[0] != 0, 1)) {
        ia = ceil_int4(a);
        ib = ceil_int4(b);
        ic = ceil_int4(c);
    } else { /* a bound past 2^30 (a huge blur): libm's ceilf where ceil_int takes it */
        for (int i = 0; i < 4; i++) {
            ia[i] = ceil_int(a[i]);
            ib[i] = ceil_int(b[i]);
            ic[i] = ceil_int(c[i]);
        }
    }
    /* lo[3] and hi[3] are adjacent: ev lo 0..2 hi 0 | ev hi 1, 2 | od lo 0, 1 | od lo 2 hi 0..2 */
    _Static_assert(offsetof(ti, hi) == offsetof(ti, lo) + 3 * sizeof(int), "lo, hi adjacent");
    char *el = (char *)ev + offsetof(ti, lo), *ol = (char *)od + offsetof(ti, lo);
    memcpy(el, &ia, 16);
#ifdef __SSE2__ /* the halves of ib straight from the register */
    _mm_storel_epi64((__m128i *)(void *)(el + 16), (__m128i)ib);
    _mm_storeh_pi((__m64 *)(void *)ol, (__m128)ib);
#else
    memcpy(el + 16, &ib, 8);
    memcpy(ol, (const char *)&ib + 8, 8);
#endif
    memcpy(ol + 8, &ic, 16);
    ev->A = Ak;
    ev->B = Bk;
    ev->C = Ck;
    const int valid = sweeps_valid(ia, ib, ic);
    ev->valid = valid & 1;
    od->u = (1.0f - k->v) * fR - third;
    od->v = (1.0f - k->u) * fR - third;
    od->A = Ck;
    od->B = Bk;
    od->C = Ak;
    od->valid = valid >> 1;
}

PT_NO_SLP static void iterators_clamped(const tk *k, int res, ti *ev, ti *od)
{
    iterators_t(k, res, 1, ev, od);
}

PT_NO_SLP static void across(const tk *k, unsigned i, unsigned e, unsigned ae, tk *ka)
{
    across_t(k, i, e, ae, ka);
}

/* Traverse's per-piece work (across, iterators_clamped, split_apply, apply_face_its) built for
 * AVX2 as well, chosen once a batch as the lean sweeps' AVX2 instances are (tc.avx2): the same
 * C, so the same operations on the same values (no FMA: the target adds none and ISO C mode
 * contracts nothing), in VEX encodings (three operands: fewer register copies). */
#if (defined(__x86_64__) || defined(__i386__)) && defined(__GNUC__)
#define PT_TRAV_AVX2 1
__attribute__((target("avx2"))) PT_NO_SLP static void iterators_clamped_avx2(const tk *k, int res,
                                                                            ti *ev, ti *od)
{
    iterators_t(k, res, 1, ev, od);
}

__attribute__((target("avx2"))) PT_NO_SLP static void across_avx2(const tk *k, unsigned i,
                                                                 unsigned e, unsigned ae,
                                                                 tk *ka)
{
    across_t(k, i, e, ae, ka);
}
#endif

/* The unclamped sweeps (Clamp's whole kernel, Discard's whole weight), in the AVX2 instance
 * when Traverse's per-piece work takes it (avx2: tc.avx2). */
PT_NO_SLP static void iterators_whole(const tk *k, int res, ti *ev, ti *od)
{
    iterators_t(k, res, 0, ev, od);
}

#ifdef PT_TRAV_AVX2
__attribute__((target("avx2"))) PT_NO_SLP static void iterators_whole_avx2(const tk *k, int res,
                                                                          ti *ev, ti *od)
{
    iterators_t(k, res, 0, ev, od);
}
#endif

static inline void iterators(int avx2, const tk *k, int res, ti *ev, ti *od)
{
#ifdef PT_TRAV_AVX2
    if (avx2) {
        iterators_whole_avx2(k, res, ev, od);
        return;
    }
#endif
    (void)avx2;
    iterators_whole(k, res, ev, od);
}

/* Channel ch of the texel at px as a float of its stored value (not scaled to [0, 1]). */
__attribute__((always_inline)) static inline float texel_chan(const uint8_t *px, unsigned ch,
                                                              unsigned DT)
{
    switch (DT) {
    case ST_DT_U8:   return (float)px[ch];
    case ST_DT_U16:  return (float)((const uint16_t *)(const void *)px)[ch];
    case ST_DT_HALF: return st_half_to_float(((const uint16_t *)(const void *)px)[ch]);
    default:         return ((const float *)(const void *)px)[ch];
    }
}

/* A tap's vector: channels 0..NC-1 of the texel at px as texel_chan gives them, the other
 * lanes those of one (lane 3 = 1 for the weight's sum when NC < 4). Float texels are loaded
 * whole (8 + 4 bytes for three channels) instead of lane by lane. */
__attribute__((always_inline)) static inline pt_v4f texel_vec(const uint8_t *px, pt_v4f one,
                                                             unsigned DT, unsigned NC)
{
    pt_v4f tv = one;
    if (DT == ST_DT_F32 && NC >= 2) {
        if (NC == 4) {
            memcpy(&tv, px, 16);
            return tv;
        }
        double d; /* the first two channels' bits, loaded as one 8-byte scalar */
        memcpy(&d, px, 8);
        pt_v4f lo = (pt_v4f)(pt_v2d){d, 0.0};
        pt_v4f hi = {NC == 3 ? ((const float *)(const void *)px)[2] : 0.0f, one[3], 0.0f, 0.0f};
        return __builtin_shufflevector(lo, hi, 0, 1, 4, 5);
    }
#pragma GCC unroll 4
    for (unsigned ch = 0; ch < NC; ch++)
        tv[ch] = texel_chan(px, ch, DT);
    return tv;
}

/* Clamp mode: the texel (x, y) of an R x R level that a tap at stored position (x, y) outside
 * the face reads: the texel under the face point nearest its centroid. (A tap inside the face,
 * upright x >= 0, y >= 0, x + y <= R - 1 or inverted x <= R - 1, y <= R - 1, x + y >= R, reads
 * itself: sweep_t takes those without calling this.) */
__attribute__((always_inline)) static inline void fold_tap(int R, int odd, int x, int y,
                                                           int *tx, int *ty)
{
    /* centroid in texel units: upright (x + 1/3, y + 1/3); an inverted one is cell
     * (R-1-y, R-1-x), centroid + 2/3 */
    float cu = odd ? (float)(R - 1 - y) + 2.0f / 3.0f : (float)x + 1.0f / 3.0f;
    float cv = odd ? (float)(R - 1 - x) + 2.0f / 3.0f : (float)y + 1.0f / 3.0f;
    float fR = (float)R;
    cu = cu < 0.0f ? 0.0f : cu;
    cv = cv < 0.0f ? 0.0f : cv;
    if (cu + cv > fR) {
        float t = 0.5f * (cu + cv - fR);
        cu -= t;
        cv -= t;
        if (cu < 0.0f) { cv = fR; cu = 0.0f; }
        if (cv < 0.0f) { cu = fR; cv = 0.0f; }
    }
    /* st_tri_texel(R, cu / fR, cv / fR), whose first step multiplies back by R: R is a power
     * of two and cu, cv >= 0 are far from underflow, so that gives cu and cv exactly; the
     * texel-unit form without the two divisions */
    uint32_t ux, uy;
    st_tri_texel_t((uint32_t)R, cu, cv, &ux, &uy);
    *tx = (int)ux;
    *ty = (int)uy;
}


enum { SW_READ, SW_WEIGHT, SW_FOLD };

/* Clamp's and Discard's whole-kernel sweeps step their weights by recurrence instead of one
 * libm expf per tap (the Gaussian of a quadratic form is a product of exponentials of its
 * finite differences): in a row, a tap weighs w = G (the Gaussian times 1/R^2, in double),
 * then G *= E and E *= kxx (E = exp(gs * the step of Q to the next tap), kxx = exp(gs * 2A)).
 * The taps are the same (Q < 1 with the float Q of the per-tap sweeps); each weight is the
 * Gaussian of the exact Q where the per-tap sweep takes expf of the float finite-difference
 * Q: they differ by about 1e-6 relatively (docs/ptex-log.md, "Session 13, tri6"). rc == NULL:
 * the per-tap expf (Traverse, Discard's kept taps, and st_ptextri_batch_pertap). */
typedef struct pt_rec {
    double G, E, kxx;
} pt_rec;

/* One row's taps in turn: Q and its step DQ (per-tap expf, rc == NULL) or the recurrence's G
 * and E (rc); tap_end hands both back for the row that follows. */
typedef struct pt_tap {
    float Q, DQ;
    double G, E, kxx;
} pt_tap;

__attribute__((always_inline)) static inline pt_tap tap_begin(float Q, float DQ, const pt_rec *rc)
{
    pt_tap t = {Q, DQ, rc ? rc->G : 0.0, rc ? rc->E : 0.0, rc ? rc->kxx : 0.0};
    return t;
}

__attribute__((always_inline)) static inline float tap_w(const pt_tap *t, const pt_rec *rc,
                                                         float gs, float wscale)
{
    return rc ? (float)t->G : expf(gs * t->Q) * wscale;
}

__attribute__((always_inline)) static inline void tap_next(pt_tap *t, const pt_rec *rc, float DDQ)
{
    if (rc) {
        t->G *= t->E;
        t->E *= t->kxx;
    } else {
        t->Q += t->DQ;
        t->DQ += DDQ;
    }
}

__attribute__((always_inline)) static inline void tap_end(const pt_tap *t, pt_rec *rc, float *Qp,
                                                          float *DQp)
{
    if (rc) {
        rc->G = t->G;
        rc->E = t->E;
    }
    *Qp = t->Q;
    *DQp = t->DQ;
}

/* A sweep's row y: its taps' span [x1, x2) (the upright or inverted triangle's bounds on x)
 * and Q, DQ at x1 (the kernel's quadratic form and its step along x). */
__attribute__((always_inline)) static inline void row_span(const ti *it, int R, int y, int *x1,
                                                           int *x2, float *Q, float *DQ)
{
    const float A = it->A, B = it->B, C = it->C;
    int xw = R - y;
    int a = it->lo[0] > xw - it->hi[2] ? it->lo[0] : xw - it->hi[2];
    *x1 = a;
    *x2 = it->hi[0] < xw - it->lo[2] ? it->hi[0] : xw - it->lo[2];
    float U = (float)a - it->u, V = (float)y - it->v;
    *DQ = A * (2.0f * U + 1.0f) + B * V;
    *Q = A * U * U + (B * U + C * V) * V;
}

/* n taps of a row that all read the texel at px (a Clamp run whose taps fold onto one
 * texel): row_step's sums tap by tap (x * w added to each channel's sum in turn, not x
 * times the run's weight), the texel loaded once. */
__attribute__((always_inline)) static inline pt_v4f
row_same(int n, const uint8_t *px, float *Qp, float *DQp, float DDQ, float gs, float wscale,
         pt_v4f one, pt_v4f acc, float *wsum4, pt_rec *rc, unsigned DT, unsigned NC)
{
    pt_tap t = tap_begin(*Qp, *DQp, rc);
    const pt_v4f tv = texel_vec(px, one, DT, NC);
    for (; n > 0; n--) {
        if (rc || t.Q < 1.0f) {
            float w = tap_w(&t, rc, gs, wscale);
            acc += tv * w;
            if (NC == 4)
                *wsum4 += w;
        }
        tap_next(&t, rc, DDQ);
    }
    tap_end(&t, rc, Qp, DQp);
    return acc;
}

/* The taps x in [xa, xb) of row y of a Clamp sweep that fall outside the face, each read
 * from the texel fold_tap gives it; Q, DQ stepped as in row_step. ODD is the sweep's
 * (a constant in each of row_folded's two loops, so fold_tap has no select on it). */
__attribute__((always_inline)) static inline pt_v4f
row_folded_t(int ODD, int R, const uint8_t *data, int y, int xa, int xb, size_t ts,
             float *Qp, float *DQp, float DDQ, float gs, float wscale, pt_v4f one, pt_v4f acc,
             float *wsum4, pt_rec *rc, unsigned DT, unsigned NC)
{
    pt_tap t = tap_begin(*Qp, *DQp, rc);
    for (int x = xa; x < xb; x++) {
        if (rc || t.Q < 1.0f) {
            float w = tap_w(&t, rc, gs, wscale);
            int tx, ty;
            fold_tap(R, ODD, x, y, &tx, &ty);
            acc += texel_vec(data + ((size_t)ty * (size_t)R + (size_t)tx) * ts, one, DT, NC) * w;
            if (NC == 4)
                *wsum4 += w;
        }
        tap_next(&t, rc, DDQ);
    }
    tap_end(&t, rc, Qp, DQp);
    return acc;
}

/* The band past the diagonal edge, walked instead of folded tap by tap. For a tap (x, y) that
 * row_folded would fold (upright: x, y >= 0, x + y >= R; inverted: y <= R - 1, x <= R - 1,
 * x + y <= R - 1, so cu, cv >= 0 and cu + cv > R: the pull-back always runs), with
 * d = x - y + R, the pulled-back centroid is exactly ((R + x - y) / 2, (R - x + y) / 2) in
 * either orientation (the 1/3 or 2/3 offsets cancel), up to float rounding of a few ulps of
 * numbers below 2^18 (|x|, |y| <= 2R + 2 <= 2^16 + 2: kernel bounds are within 1 of a centre
 * in [0, 1]), i.e. errors far below 1/2. So fold_tap gives:
 *   d <= 0: cu - t <= 0 (or just above 0 with cv - t just below R): texel (0, R-1);
 *   d >= 2R: texel (R-1, 0) the same way;
 *   d odd, 0 < d < 2R: the midpoint of an edge segment, texel (k, R-1-k), k = (d - 1) / 2
 *     (the point is on cell (k, R-1-k)'s diagonal: either side of it is that texel);
 *   d even, 0 < d < 2R: the vertex (k, R - k), k = d / 2, where rounding picks among the
 *     three small triangles meeting there: with a = cu - t, b = cv - t as fold_tap computes
 *     them, a < k and b < R - k: texel (k, R-k); a >= k and b >= R - k: (k, R-k) too; a >= k,
 *     b < R - k: (k, R-k-1); a < k, b >= R - k: (k-1, R-k).
 * In texels after M(k) = texel (k, R-1-k) (texel index (R-1-k) R + k), the vertex's texel is
 * R, R, 0 or R - 1 further. band_vertex computes that offset with fold_tap's float operations;
 * tests/unit/test_ptextri.c checks the whole rule against fold_tap (st_ptextri_band_check). */
__attribute__((always_inline)) static inline int band_vertex(int ODD, int R, float fR, int x,
                                                             int y, int k)
{
    float cu = ODD ? (float)(R - 1 - y) + 2.0f / 3.0f : (float)x + 1.0f / 3.0f;
    float cv = ODD ? (float)(R - 1 - x) + 2.0f / 3.0f : (float)y + 1.0f / 3.0f;
    float t = 0.5f * (cu + cv - fR);
    int p = cu - t < (float)k, q = cv - t < (float)(R - k);
    return p == q ? R : p ? R - 1 : 0;
}

/* The taps x in [xa, xb) of row y that row_folded_t would fold, by the rule over band_vertex:
 * the runs d <= 0 and d >= 2R read one texel each (row_same), the band between them steps
 * M(k) by 1 - R texels every second tap and reads the midpoint texels at M(k) and the vertex
 * texels at M(k) + band_vertex. Same taps, same texels, same sums as row_folded_t. */
__attribute__((always_inline)) static inline pt_v4f
row_band_t(int ODD, int R, const uint8_t *data, int y, int xa, int xb, size_t ts,
           float *Qp, float *DQp, float DDQ, float gs, float wscale, pt_v4f one, pt_v4f acc,
           float *wsum4, pt_rec *rc, unsigned DT, unsigned NC)
{
    int lo = y - R + 1, hi = y + R; /* d <= 0 below lo, d >= 2R from hi */
    if (xa < lo) {
        int e = xb < lo ? xb : lo;
        acc = row_same(e - xa, data + (size_t)(R - 1) * (size_t)R * ts, Qp, DQp, DDQ, gs,
                       wscale, one, acc, wsum4, rc, DT, NC);
        xa = e;
    }
    int xe = xb < hi ? xb : hi;
    if (xa < xe) {
        const float fR = (float)R;
        int d = xa - y + R, k = d >> 1;
        const uint8_t *m = data + ((size_t)(R - 1 - k) * (size_t)R + (size_t)k) * ts;
        const ptrdiff_t mstep = (ptrdiff_t)(1 - R) * (ptrdiff_t)ts;
        pt_tap t = tap_begin(*Qp, *DQp, rc);
        for (int x = xa; x < xe; x++, d++) {
            if (rc || t.Q < 1.0f) {
                float w = tap_w(&t, rc, gs, wscale);
                const uint8_t *px = m;
                if (!(d & 1))
                    px += (ptrdiff_t)band_vertex(ODD, R, fR, x, y, d >> 1) * (ptrdiff_t)ts;
                acc += texel_vec(px, one, DT, NC) * w;
                if (NC == 4)
                    *wsum4 += w;
            }
            if (d & 1)
                m += mstep;
            tap_next(&t, rc, DDQ);
        }
        tap_end(&t, rc, Qp, DQp);
        xa = xe;
    }
    if (xa < xb)
        acc = row_same(xb - xa, data + (size_t)(R - 1) * ts, Qp, DQp, DDQ, gs, wscale, one,
                       acc, wsum4, rc, DT, NC);
    return acc;
}

__attribute__((always_inline)) static inline pt_v4f
row_folded(const ti *it, const uint8_t *data, int y, int xa, int xb, size_t ts, float *Qp,
           float *DQp, float DDQ, float gs, float wscale, pt_v4f one, pt_v4f acc,
           float *wsum4, pt_rec *rc, int WALK, unsigned DT, unsigned NC)
{
    if (xa >= xb)
        return acc;
    if (WALK) {
        if (it->odd)
            return row_band_t(1, it->R, data, y, xa, xb, ts, Qp, DQp, DDQ, gs, wscale, one,
                              acc, wsum4, rc, DT, NC);
        return row_band_t(0, it->R, data, y, xa, xb, ts, Qp, DQp, DDQ, gs, wscale, one, acc,
                          wsum4, rc, DT, NC);
    }
    if (it->odd)
        return row_folded_t(1, it->R, data, y, xa, xb, ts, Qp, DQp, DDQ, gs, wscale, one, acc,
                            wsum4, rc, DT, NC);
    return row_folded_t(0, it->R, data, y, xa, xb, ts, Qp, DQp, DDQ, gs, wscale, one, acc,
                        wsum4, rc, DT, NC);
}

/* n taps of a row read from texels px, px + step, .. (the taps of a row inside the level, or a
 * run of Clamp taps that fold onto a line of texels, one after another): each tap with Q < 1
 * adds its texel times its weight to acc (and the weight to *wsum4 when NC == 4); *Q steps by
 * *DQ, *DQ by DDQ (left as after the last tap, for the taps that follow in the row); n <= 0
 * reads nothing. Returns acc. */
__attribute__((always_inline)) static inline pt_v4f
row_step(int n, const uint8_t *px, ptrdiff_t step, float *Qp, float *DQp, float DDQ, float gs,
         float wscale, pt_v4f one, pt_v4f acc, float *wsum4, pt_rec *rc, unsigned DT,
         unsigned NC)
{
    pt_tap t = tap_begin(*Qp, *DQp, rc);
    for (; n > 0; n--, px += step) {
        if (rc || t.Q < 1.0f) {
            float w = tap_w(&t, rc, gs, wscale);
            acc += texel_vec(px, one, DT, NC) * w;
            if (NC == 4)
                *wsum4 += w;
        }
        tap_next(&t, rc, DDQ);
    }
    tap_end(&t, rc, Qp, DQp);
    return acc;
}

/* Four taps of a read sweep's row with Q values qv (a lane of 1: no tap): the kept ones
 * (Q < 1) weigh 2^(Q gl) wscale (gl = gs log2(e)), by pk_exp2_4 for the four at once, and add
 * in lane order, as row_step adds them, the texel at px + lane * step (READ) or one (a
 * constant face: lane 3, or wsum4, sums the weights) times the weight. Returns the kept
 * lanes' mask. */
__attribute__((always_inline)) static inline int
read_blk4(const uint8_t *px, ptrdiff_t step, pt_v4f qv, pt_v4f gl, pt_v4f wscale, pt_v4f one,
          pt_v4f *accp, float *wsum4, int READ, unsigned DT, unsigned NC)
{
    int m = mask4(qv < 1.0f);
    if (!m)
        return m;
    pt_v4f w = pk_exp2_4(qv * gl) * wscale, acc = *accp;
#define PT_LANE(L)                                                                           \
    do {                                                                                     \
        pt_v4f wl = __builtin_shufflevector(w, w, L, L, L, L);                               \
        acc += (READ ? texel_vec(px + (L) * step, one, DT, NC) : one) * wl;                  \
        if (NC == 4)                                                                         \
            *wsum4 += wl[0];                                                                 \
    } while (0)
    if (m == 15) { /* the common case: no test a tap */
        PT_LANE(0);
        PT_LANE(1);
        PT_LANE(2);
        PT_LANE(3);
    } else {
        if (m & 1)
            PT_LANE(0);
        if (m & 2)
            PT_LANE(1);
        if (m & 4)
            PT_LANE(2);
        if (m & 8)
            PT_LANE(3);
    }
#undef PT_LANE
    *accp = acc;
    return m;
}

/* Q at a row's tap, then Q, DQ stepped to the next tap (row_step's operations). */
static inline float q_step(float *Q, float *DQ, float DDQ)
{
    float q = *Q;
    *Q += *DQ;
    *DQ += DDQ;
    return q;
}

/* A read sweep's rows of fewer taps than this keep the per-tap expf (row_step): a vector exp
 * for one or two kept taps costs more than their expf calls (docs/ptex-log.md, "trix"). */
#define PT_W4_MIN 3

/* The read sweeps' rows (Traverse, Discard, Clamp's kernels inside the face): n taps as
 * row_step takes them with rc == NULL - the same float Q, DQ chain, so the same taps (Q < 1),
 * texels and order of the sums - but the weights four kept taps at a time by pk_exp2_4
 * (within about 2e-7 relatively of the per-tap expf, which st_ptextri_batch_pertap keeps:
 * docs/ptex-log.md, "trix"). READ: tap i reads the texel at px + i * step; else none
 * (read_blk4). The taps before the first kept one are stepped over one by one. *Q, *DQ are
 * left as after the last tap, except with LAST (the row's last run): then the row stops at
 * the end of its kept taps when DDQ > 0 (Q falls then rises along the row: DQ only grows, so
 * the kept taps are one run) and *Q, *DQ are not meaningful. */
__attribute__((always_inline)) static inline pt_v4f
row_read4(int n, const uint8_t *px, ptrdiff_t step, float *Qp, float *DQp, float DDQ,
          pt_v4f gl, pt_v4f wscale, pt_v4f one, pt_v4f acc, float *wsum4, int READ, int LAST,
          unsigned DT, unsigned NC)
{
    float Q = *Qp, DQ = *DQp;
    for (; n > 0 && !(Q < 1.0f); n--, px += step)
        q_step(&Q, &DQ, DDQ);
    for (; n >= 4; n -= 4, px += 4 * step) {
        float q0 = q_step(&Q, &DQ, DDQ), q1 = q_step(&Q, &DQ, DDQ);
        float q2 = q_step(&Q, &DQ, DDQ), q3 = q_step(&Q, &DQ, DDQ);
        int m = read_blk4(px, step, (pt_v4f){q0, q1, q2, q3}, gl, wscale, one, &acc, wsum4,
                          READ, DT, NC);
        if (LAST && m != 15 && DDQ > 0.0f) /* the kept run ended in this block */
            return acc;
    }
    if (n > 0) { /* 1 to 3 taps left: the other lanes 1 (no tap) */
        float q0 = q_step(&Q, &DQ, DDQ), q1 = n > 1 ? q_step(&Q, &DQ, DDQ) : 1.0f;
        float q2 = n > 2 ? q_step(&Q, &DQ, DDQ) : 1.0f;
        read_blk4(px, step, (pt_v4f){q0, q1, q2, 1.0f}, gl, wscale, one, &acc, wsum4, READ,
                  DT, NC);
    }
    *Qp = Q;
    *DQp = DQ;
    return acc;
}

int st_ptextri_band_check(int R, int odd, int y, int xa, int xb, const float *texels,
                          int recurrence)
{
    const uint8_t *data = (const uint8_t *)(const void *)texels;
    pt_v4f one = {0.0f, 0.0f, 0.0f, 1.0f}, zero = {0.0f, 0.0f, 0.0f, 0.0f};
    pt_v4f sum[2];
    for (int walk = 0; walk < 2; walk++) {
        /* weights: a recurrence that keeps every tap (all different, none underflowing over
         * a row), or expf of a Q stepped so that the first few taps and those past about
         * 2000 fail Q < 1 */
        pt_rec rc = {1.0, 1.0001, 1.0};
        float Q = 1.05f, DQ = -0.01f, DDQ = 1e-5f, wsum4 = 0.0f;
        sum[walk] = row_folded(&(ti){.R = R, .odd = odd}, data, y, xa, xb, 4, &Q, &DQ, DDQ,
                               -0.5f, 0.5f, one, zero, &wsum4, recurrence ? &rc : NULL, walk,
                               ST_DT_F32, 1);
    }
    return memcmp(&sum[0], &sum[1], sizeof sum[0]) == 0;
}

static inline int clampi(int x, int lo, int hi) { return x < lo ? lo : x > hi ? hi : x; }

/* Row y of a Clamp sweep over a level with texels (not a constant face), taps [x1, x2) with
 * Q, DQ at x1, in tap order, in five runs (cut at c1 <= c2 <= c3 <= c4):
 *   [x1, c1) and [c4, x2): taps that fold_tap maps to one texel, read once;
 *   [c2, c3): taps that read texels in a line, texel (x, y) of the face for those inside it
 *             (upright: y >= 0, 0 <= x <= R-1-y; inverted: y <= R-1, R-y <= x <= R-1);
 *   [c1, c2) and [c3, c4): the others (past the diagonal edge): walked (row_band_t) or, in
 *             the per-tap build, fold_tap tap by tap.
 * With the centroid (cu, cv) = upright (x + 1/3, y + 1/3), inverted (R-1-y + 2/3,
 * R-1-x + 2/3), fold_tap gives (R >= 1, |x|, |y| < 2^20, where (int) of these is exact):
 *   upright x < 0: cu is clamped to 0, the rest depends on y only;
 *   upright y < 0: cv is clamped to 0; 0 <= x <= R-1: cu < R, no pull-back, texel (x, 0);
 *     x >= R: cu > R is pulled back until cv < 0, then (R, 0) whatever x: texel (R-1, 0);
 *   inverted x >= R: cv is clamped to 0, the rest depends on y only;
 *   inverted y >= R: cu is clamped to 0; 0 <= x <= R-1: cv < R, texel (0, R-1-x);
 *     x < 0: cv > R is pulled back until cu < 0, then (0, R) whatever x: texel (0, R-1). */
__attribute__((always_inline)) static inline pt_v4f
row_clamp(const ti *it, const uint8_t *data, int y, int x1, int x2, float Q, float DQ,
          float DDQ, float gs, float wscale, pt_v4f one, pt_v4f acc, float *wsum4,
          pt_rec *rc, int WALK, unsigned DT, unsigned NC)
{
    const size_t ts = st_dtype_size(DT) * NC;
    const int R = it->R, odd = it->odd;
    int c1, c2, c3, c4;
    const uint8_t *line; /* the texel tap x of [c2, c3) reads: line + x * step */
    ptrdiff_t step = (ptrdiff_t)ts;
    if (x2 <= x1)
        return acc;
    if (!odd) {
        c1 = 0;
        if (y < 0) { /* row 0, then its last texel */
            c2 = 0;
            c3 = c4 = R;
            line = data;
        } else { /* inside, then past the diagonal edge (none when y >= R) */
            c2 = 0;
            c3 = R - y > 0 ? R - y : 0;
            c4 = x2;
            line = data + (size_t)y * (size_t)R * ts;
        }
    } else if (y >= R) { /* texels (0, R-1-x): column 0 upwards */
        c1 = c2 = 0;
        c3 = c4 = R;
        step = -(ptrdiff_t)((size_t)R * ts);
        line = data + (size_t)(R - 1) * (size_t)R * ts;
    } else { /* past the diagonal edge, then inside */
        c1 = x1;
        c2 = R - y < R ? R - y : R;
        c3 = c4 = R;
        line = data + (size_t)y * (size_t)R * ts;
    }
    c1 = clampi(c1, x1, x2);
    c2 = clampi(c2, c1, x2);
    c3 = clampi(c3, c2, x2);
    c4 = clampi(c4, c3, x2);
    if (c1 > x1) {
        int tx, ty;
        fold_tap(R, odd, x1, y, &tx, &ty);
        acc = row_same(c1 - x1, data + ((size_t)ty * (size_t)R + (size_t)tx) * ts, &Q, &DQ,
                       DDQ, gs, wscale, one, acc, wsum4, rc, DT, NC);
    }
    acc = row_folded(it, data, y, c1, c2, ts, &Q, &DQ, DDQ, gs, wscale, one, acc, wsum4, rc,
                     WALK, DT, NC);
    if (c3 > c2)
        acc = row_step(c3 - c2, line + (ptrdiff_t)c2 * step, step, &Q, &DQ, DDQ, gs, wscale,
                       one, acc, wsum4, rc, DT, NC);
    acc = row_folded(it, data, y, c3, c4, ts, &Q, &DQ, DDQ, gs, wscale, one, acc, wsum4, rc,
                     WALK, DT, NC);
    if (x2 > c4) {
        int tx, ty;
        fold_tap(R, odd, c4, y, &tx, &ty);
        acc = row_same(x2 - c4, data + ((size_t)ty * (size_t)R + (size_t)tx) * ts, &Q, &DQ,
                       DDQ, gs, wscale, one, acc, wsum4, rc, DT, NC);
    }
    return acc;
}

/* A recurrence sweep's cursor: the Gaussian times 1/R^2 (G) at the first kept tap (x, y) of
 * the last row that had one, and exp(gs * the step of Q) to the next tap along x (Ex) and
 * along y (Ey); k**: exp(gs * the second differences), i**: their inverses. Every row moves it
 * to its own first kept tap: down one row per y step (G *= Ey), then along x. The taps it
 * passes through lie within a lattice step of the kernel's ellipse (Q of a few units at
 * most), so no factor underflows or overflows in double. */
typedef struct pt_cur {
    int seeded, x, y;
    double G, Ex, Ey, kxx, kxy, kyy, ixx, ixy;
} pt_cur;

/* A piece's second differences' factors, in the upright sweep's frame (the inverted sweep has
 * A and C swapped, B the same: kxx and kyy swap); computed by the first sweep that needs them
 * (pt_exp4, double: each is used many times). */
typedef struct pt_kf {
    int set;
    double kxx, kxy, kyy, ixx, ixy, iyy;
} pt_kf;

typedef double pt_v4d __attribute__((vector_size(32)));
typedef int64_t pt_v4l __attribute__((vector_size(32)));

/* exp of the four lanes of x (out = e^x), x clamped to [-700, 700], to about 1e-14 relatively:
 * x = n ln 2 + r, |r| <= ln 2 / 2 (n by the 1.5 * 2^52 rounding trick; ln 2 in two parts, the
 * first exact times n), e^r by its Taylor polynomial of degree 11 (truncation below 7e-15;
 * evaluated by Estrin's scheme),
 * times 2^n made in the exponent bits. Inline, in place of libm's exp and expf for the
 * recurrence's factors. Generic vectors: one 256-bit vector where the caller is built for AVX2
 * (the fold sweeps' AVX2 instances), two SSE2 halves elsewhere; each lane the same operations
 * either way. Pointers, not vector arguments: a 32-byte vector argument of a function built
 * without AVX would change its ABI. */
__attribute__((always_inline)) static inline void pt_exp4(const double *xin, double *out)
{
    const pt_v4d magic = {0x1.8p52, 0x1.8p52, 0x1.8p52, 0x1.8p52};
#ifndef __SSE2__
    const pt_v4d lo = {-700.0, -700.0, -700.0, -700.0}, hi = {700.0, 700.0, 700.0, 700.0};
#endif
    pt_v4d x;
#ifdef __SSE2__
    /* maxpd gives its second operand unless the first is greater (a NaN: lo), minpd likewise:
     * the selects below, by halves (two instructions each in an SSE2 build) */
    pt_v2d xh[2];
    memcpy(xh, xin, 32);
    for (int i = 0; i < 2; i++)
        xh[i] = (pt_v2d)_mm_min_pd(_mm_max_pd((__m128d)xh[i], _mm_set1_pd(-700.0)),
                                   _mm_set1_pd(700.0));
    memcpy(&x, xh, 32);
#else
    memcpy(&x, xin, 32);
    /* x > lo ? x : lo, then x < hi ? x : hi */
    pt_v4l m = x > lo, xb, lb, hb; /* -1 where true (false for a NaN: clamped) */
    memcpy(&xb, &x, 32);
    memcpy(&lb, &lo, 32);
    memcpy(&hb, &hi, 32);
    xb = (xb & m) | (lb & ~m);
    memcpy(&x, &xb, 32);
    m = x < hi;
    xb = (xb & m) | (hb & ~m);
    memcpy(&x, &xb, 32);
#endif
    pt_v4d k = x * 1.4426950408889634 + magic; /* n + 1.5 * 2^52 */
    pt_v4l kb, mb;
    memcpy(&kb, &k, 32);
    memcpy(&mb, &magic, 32);
    pt_v4d n = k - magic;
    pt_v4d r = (x - n * 0x1.62e4p-1) - n * 0x1.7f7d1cf79abcap-20;
    /* Estrin's scheme: pairs, then r^2, r^4, r^8 (a chain of about 10 operations, not
     * Horner's 22; docs/ptex-log.md, "Session 31, tri31") */
    pt_v4d r2 = r * r;
    pt_v4d r4 = r2 * r2;
    pt_v4d r8 = r4 * r4;
    pt_v4d p01 = r + 1.0;
    pt_v4d p23 = r * (1.0 / 6.0) + 0.5;
    pt_v4d p45 = r * (1.0 / 120.0) + 1.0 / 24.0;
    pt_v4d p67 = r * (1.0 / 5040.0) + 1.0 / 720.0;
    pt_v4d p89 = r * (1.0 / 362880.0) + 1.0 / 40320.0;
    pt_v4d pab = r * (1.0 / 39916800.0) + 1.0 / 3628800.0;
    pt_v4d q0 = p23 * r2 + p01;
    pt_v4d q1 = p67 * r2 + p45;
    pt_v4d q2 = pab * r2 + p89;
    pt_v4d p = (q1 * r4 + q0) + q2 * r8;
    pt_v4l sb = (kb - mb + 1023) << 52;
    pt_v4d sc;
    memcpy(&sc, &sb, 32);
    p *= sc;
    memcpy(out, &p, 32);
}

__attribute__((always_inline)) static inline void kf_set(pt_kf *kf, const ti *it)
{
    const double g = -0.5 * (double)PT_WIDTH * (double)PT_WIDTH;
    double e[4];
    pt_exp4((const double[4]){g * 2.0 * (double)it->A, g * 2.0 * (double)it->C,
                              g * (double)it->B, -g * (double)it->B}, e);
    pt_v2d ac = {e[0], e[1]};
    pt_v2d iac = (pt_v2d){1.0, 1.0} / ac;
    kf->set = 1;
    kf->kxx = it->odd ? ac[1] : ac[0];
    kf->kyy = it->odd ? ac[0] : ac[1];
    kf->ixx = it->odd ? iac[1] : iac[0];
    kf->iyy = it->odd ? iac[0] : iac[1];
    kf->kxy = e[2];
    kf->ixy = e[3];
}

/* The factors of the last piece that needed them and their key, the upright sweep's A, B, C
 * (kf_set's inputs in its frame: the inverted sweep's A and C swapped, which kf_set swaps
 * back, lane by lane the same operations), kept over a batch: a query whose kernel has the
 * last one's shape at the same resolution (a fixed footprint) takes them instead of kf_set's
 * four exps - the same function of the same values, so the same bits. */
typedef struct pt_kfc {
    int valid;
    float key[3];
    pt_kf kf;
} pt_kfc;

__attribute__((always_inline)) static inline void kf_get(pt_kf *kf, const ti *it, pt_kfc *kc)
{
    if (!kc) {
        kf_set(kf, it);
        return;
    }
    const float key[3] = {it->odd ? it->C : it->A, it->B, it->odd ? it->A : it->C};
    if (kc->valid && memcmp(key, kc->key, sizeof key) == 0) {
        *kf = kc->kf;
        return;
    }
    kf_set(kf, it);
    memcpy(kc->key, key, sizeof key);
    kc->kf = *kf;
    kc->valid = 1;
}

/* The cursor at tap (x, y) of sweep it, from the sweep's quadratic form in double. */
__attribute__((always_inline)) static inline void cur_seed(pt_cur *cu, const ti *it, int x,
                                                           int y, float wscale)
{
    const double g = -0.5 * (double)PT_WIDTH * (double)PT_WIDTH;
    const double A = it->A, B = it->B, C = it->C;
    const double U = (double)x - (double)it->u, V = (double)y - (double)it->v;
    cu->seeded = 1;
    cu->x = x;
    cu->y = y;
    double e[4];
    pt_exp4((const double[4]){g * (A * U * U + (B * U + C * V) * V),
                              g * (A * (2.0 * U + 1.0) + B * V),
                              g * (B * U + C * (2.0 * V + 1.0)), 0.0}, e);
    cu->G = (double)wscale * e[0];
    cu->Ex = e[1];
    cu->Ey = e[2];
}

/* Moves the cursor to tap (x, y) (y >= its row), seeding it at the sweep's first kept tap. */
__attribute__((always_inline)) static inline void cur_to(pt_cur *cu, const ti *it, int x, int y,
                                                         float wscale)
{
    if (!cu->seeded) {
        cur_seed(cu, it, x, y, wscale);
        return;
    }
    double G = cu->G, Ex = cu->Ex, Ey = cu->Ey;
    for (int j = cu->y; j < y; j++) { /* Q(x, j + 1) - Q(x, j) steps by 2C, Q's x step by B */
        G *= Ey;
        Ex *= cu->kxy;
        Ey *= cu->kyy;
    }
    for (int i = cu->x; i < x; i++) {
        G *= Ex;
        Ex *= cu->kxx;
        Ey *= cu->kxy;
    }
    for (int i = cu->x; i > x; i--) { /* G(i - 1) = G(i) / Ex(i - 1) */
        Ex *= cu->ixx;
        Ey *= cu->ixy;
        G /= Ex;
    }
    cu->x = x;
    cu->y = y;
    cu->G = G;
    cu->Ex = Ex;
    cu->Ey = Ey;
}

/* The lean recurrence sweeps (REC == 2, the build's own; REC == 1 keeps the general ones,
 * which st_ptextri_batch_general runs for the tests). The same rows, taps, texels, weights
 * and sums in the same order as the general fold sweep (row_clamp over row_same, row_step
 * and row_band_t with a pt_rec) and weight sweep, with less per-row work: each row's texels
 * come from at most three regions found with a few compares (lean_fold_row), each run of
 * taps is one loop stepping a texel address, and the weights G, E stay in registers. */

/* One tap of the lean sweeps: acc += texel px * (float)G (and wsum4 += it when NC == 4),
 * then G *= E, E *= kxx, as pt_rec's taps do. */
__attribute__((always_inline)) static inline pt_v4f lean_tap(const uint8_t *px, double *G,
                                                             double *E, double kxx,
                                                             pt_v4f one, pt_v4f acc,
                                                             float *wsum4, unsigned DT,
                                                             unsigned NC)
{
    float w = (float)*G;
    acc += texel_vec(px, one, DT, NC) * w;
    if (NC == 4)
        *wsum4 += w;
    *G *= *E;
    *E *= kxx;
    return acc;
}

/* n taps reading px, px + step, ..: acc += texel * (float)G (and wsum4 += it when NC == 4),
 * then G *= E, E *= kxx, as pt_rec's taps do. */
__attribute__((always_inline)) static inline pt_v4f
lean_run(int n, const uint8_t *px, ptrdiff_t step, double *Gp, double *Ep, double kxx,
         pt_v4f one, pt_v4f acc, float *wsum4, unsigned DT, unsigned NC)
{
    double G = *Gp, E = *Ep;
    for (; n > 0; n--, px += step)
        acc = lean_tap(px, &G, &E, kxx, one, acc, wsum4, DT, NC);
    *Gp = G;
    *Ep = E;
    return acc;
}

/* The taps [xa, xe) of row y of lean_band's middle run (0 < d < 2R for each: the band
 * proper), midpoints and vertices as row_band_t walks them; xa < xe. */
__attribute__((always_inline)) static inline pt_v4f
lean_band_mid(int ODD, int R, const uint8_t *data, int y, int xa, int xe, size_t ts,
              double *Gp, double *Ep, double kxx, pt_v4f one, pt_v4f acc, float *wsum4,
              unsigned DT, unsigned NC)
{
    {
        const float fR = (float)R;
        int d = xa - y + R, x = xa;
        /* M(k) = texel (k, R-1-k), index (R-1) R + k (1 - R): M(0) (a row's invariant) plus
         * k steps */
        const ptrdiff_t mstep = (ptrdiff_t)(1 - R) * (ptrdiff_t)ts;
        const uint8_t *m = data + (ptrdiff_t)(R - 1) * (ptrdiff_t)R * (ptrdiff_t)ts +
                           (ptrdiff_t)(d >> 1) * mstep;
        double G = *Gp, E = *Ep;
        if (d & 1) { /* a midpoint first: M(k), then the next k */
            acc = lean_tap(m, &G, &E, kxx, one, acc, wsum4, DT, NC);
            m += mstep;
            x++;
            d++;
        }
        /* band_vertex's operations with its int-to-float conversions kept as float counters
         * (integers below 2^18: exact): the centroid coordinate that moves with x, k and R - k;
         * the other coordinate is the row's */
        const float cfix = ODD ? (float)(R - 1 - y) + 2.0f / 3.0f : (float)y + 1.0f / 3.0f;
        float xf = ODD ? (float)(R - 1 - x) : (float)x, kf = (float)(d >> 1),
              rkf = (float)(R - (d >> 1));
        const float xstep = ODD ? -2.0f : 2.0f;
        const ptrdiff_t offR = (ptrdiff_t)R * (ptrdiff_t)ts, offR1 = offR - (ptrdiff_t)ts;
        for (; x < xe; x += 2, d += 2, xf += xstep, kf += 1.0f, rkf -= 1.0f) {
            /* d even: the vertex, then the midpoint */
            float cmov = ODD ? xf + 2.0f / 3.0f : xf + 1.0f / 3.0f;
            float cu = ODD ? cfix : cmov, cv = ODD ? cmov : cfix;
            float t = 0.5f * (cu + cv - fR);
            int p = cu - t < kf, q = cv - t < rkf;
            const uint8_t *px = m + (p == q ? offR : p ? offR1 : 0);
            acc = lean_tap(px, &G, &E, kxx, one, acc, wsum4, DT, NC);
            if (x + 1 >= xe)
                break;
            acc = lean_tap(m, &G, &E, kxx, one, acc, wsum4, DT, NC);
            m += mstep;
        }
        *Gp = G;
        *Ep = E;
    }
    return acc;
}

/* row_band_t's taps [xa, xb) of row y (the part of a row past the diagonal edge that the
 * general sweep walks): the same three runs, texels and order. */
__attribute__((always_inline)) static inline pt_v4f
lean_band(int ODD, int R, const uint8_t *data, int y, int xa, int xb, size_t ts, double *Gp,
          double *Ep, double kxx, pt_v4f one, pt_v4f acc, float *wsum4, unsigned DT,
          unsigned NC)
{
    int lo = y - R + 1, hi = y + R; /* d <= 0 below lo, d >= 2R from hi */
    if (xa < lo) {
        int e = xb < lo ? xb : lo;
        acc = lean_run(e - xa, data + (size_t)(R - 1) * (size_t)R * ts, 0, Gp, Ep, kxx, one,
                       acc, wsum4, DT, NC);
        xa = e;
    }
    int xe = xb < hi ? xb : hi;
    if (xa < xe) {
        acc = lean_band_mid(ODD, R, data, y, xa, xe, ts, Gp, Ep, kxx, one, acc, wsum4, DT, NC);
        xa = xe;
    }
    if (xa < xb)
        acc = lean_run(xb - xa, data + (size_t)(R - 1) * ts, 0, Gp, Ep, kxx, one, acc, wsum4,
                       DT, NC);
    return acc;
}

/* A Clamp row's kept taps [xk, xl) as row_clamp reads them (its comment has the rules), in
 * three regions: [xk, a) one texel (fold_tap of its first tap) or, inverted rows y < R, the
 * band; [.., b) a line of texels; the rest one texel (fold_tap of its first tap) or, upright
 * rows y >= 0, the band. */
__attribute__((always_inline)) static inline pt_v4f
lean_fold_row(int ODD, int R, const uint8_t *data, int y, int xk, int xl, double *Gp,
              double *Ep, double kxx, pt_v4f one, pt_v4f acc, float *wsum4, unsigned DT,
              unsigned NC)
{
    const size_t ts = st_dtype_size(DT) * NC;
    int a, b, band;
    const uint8_t *line;
    ptrdiff_t step = (ptrdiff_t)ts;
    if (!ODD) {
        a = 0;
        band = y >= 0; /* the third region */
        b = y < 0 ? R : R - y > 0 ? R - y : 0;
        line = data + (y > 0 ? (size_t)y * (size_t)R * ts : 0);
    } else if (y >= R) { /* column 0 upwards */
        a = 0;
        b = R;
        band = 0;
        step = -(ptrdiff_t)((size_t)R * ts);
        line = data + (size_t)(R - 1) * (size_t)R * ts;
    } else {
        a = R - (y > 0 ? y : 0);
        b = R;
        band = 1; /* the first region */
        line = data + (y > 0 ? (size_t)y * (size_t)R * ts : 0);
    }
    int x = xk, tx, ty;
    if (x < a) {
        int e = xl < a ? xl : a;
        if (ODD && band) {
            acc = lean_band(1, R, data, y, x, e, ts, Gp, Ep, kxx, one, acc, wsum4, DT, NC);
        } else {
            fold_tap(R, ODD, x, y, &tx, &ty);
            acc = lean_run(e - x, data + ((size_t)ty * (size_t)R + (size_t)tx) * ts, 0, Gp, Ep,
                           kxx, one, acc, wsum4, DT, NC);
        }
        x = e;
    }
    if (x < xl && x < b) {
        int e = xl < b ? xl : b;
        acc = lean_run(e - x, line + (ptrdiff_t)x * step, step, Gp, Ep, kxx, one, acc, wsum4,
                       DT, NC);
        x = e;
    }
    if (x < xl) {
        if (!ODD && band) {
            acc = lean_band(0, R, data, y, x, xl, ts, Gp, Ep, kxx, one, acc, wsum4, DT, NC);
        } else {
            fold_tap(R, ODD, x, y, &tx, &ty);
            acc = lean_run(xl - x, data + ((size_t)ty * (size_t)R + (size_t)tx) * ts, 0, Gp, Ep,
                           kxx, one, acc, wsum4, DT, NC);
        }
    }
    return acc;
}

/* A recurrence sweep's row y: its first kept tap xk (the first x of [x1, x2) whose float Q,
 * stepped from row_span's as the per-tap loop steps it, is below 1), Q and DQ there, and x2;
 * 0 when the row keeps none. */
__attribute__((always_inline)) static inline int row_first_kept(const ti *it, int R, int y,
                                                                float DDQ, int *xkp, int *x2p,
                                                                float *Qp, float *DQp)
{
    int x1, x2;
    float Q, DQ;
    row_span(it, R, y, &x1, &x2, &Q, &DQ);
    int xk = x1;
    while (xk < x2 && !(Q < 1.0f)) {
        Q += DQ;
        DQ += DDQ;
        xk++;
    }
    *xkp = xk;
    *x2p = x2;
    *Qp = Q;
    *DQp = DQ;
    return xk < x2;
}

/* The end of the kept run that starts at xk (Q, DQ there): DQ only grows (DDQ > 0), so Q
 * falls then rises, and the kept taps of a row are one run [xk, xl). */
__attribute__((always_inline)) static inline int kept_end(int xk, int x2, float Q, float DQ,
                                                          float DDQ)
{
    int xl = xk + 1;
    for (float q = Q + DQ, dq = DQ + DDQ; xl < x2 && q < 1.0f; xl++) {
        q += dq;
        dq += DDQ;
    }
    return xl;
}


typedef float pt_v8f __attribute__((vector_size(32)));
typedef int32_t pt_v8i __attribute__((vector_size(32)));

/* The largest of *v's eight lanes, by three halvings (by pointer: a 32-byte vector passed by
 * value changes the ABI where AVX is not enabled). */
__attribute__((always_inline)) static inline int32_t pt_v8i_max(const pt_v8i *v)
{
    pt_v8i x = *v, o = __builtin_shufflevector(x, x, 4, 5, 6, 7, 0, 1, 2, 3), m = x > o;
    x = (x & m) | (o & ~m);
    o = __builtin_shufflevector(x, x, 2, 3, 0, 1, 6, 7, 4, 5);
    m = x > o;
    x = (x & m) | (o & ~m);
    o = __builtin_shufflevector(x, x, 1, 0, 3, 2, 5, 4, 7, 6);
    m = x > o;
    x = (x & m) | (o & ~m);
    return x[0];
}

/* The kept runs [xk, xl) of eight rows y0 .. y0 + 7 of a recurrence sweep (rows from y2 on keep
 * nothing), as row_first_kept and kept_end find them, a row a lane: row_span's bounds, Q and
 * DQ (each lane the scalar expressions' operations in their order: the same floats), then the
 * float Q chain stepped over the rows' spans together, as long as the longest span (n counts
 * down by one a step in every lane: a lane is live while its span is above the step count).
 * Returns a mask of the rows that keep a tap (bit r: row y0 + r).
 * The kept taps of a row are one run, so counting is enough: DDQ > 0, so DQ never decreases
 * (rounding is monotone) and Q, once it has risen, never falls (Q + DQ rounds to >= Q when
 * DQ >= 0; a NaN stays a NaN). So no row keeps a tap, then not one, then another: if Q_i < 1
 * <= Q_j (or Q_j NaN) and i < j < k, Q rose somewhere in (i, j] (a NaN does not come back to
 * Q_k < 1), and from there Q_k >= Q_j >= 1. With the run [p, p + c) of a row's steps, the
 * steps at and after its first kept one number N - p (N steps in all) and the kept ones c.
 * Eight rows a group (rows_kept4's four until tri30): a sweep of 5-8 rows (the whole kernel at
 * footprint 4 on a 32-texel face) steps its rows' chains once, in one 256-bit register in
 * the AVX2 instances (docs/ptex-log.md, "tri30"). */
__attribute__((always_inline)) static inline unsigned rows_kept8(const ti *it, int R, int y0,
                                                                 int y2, float DDQ, int *xk,
                                                                 int *xl)
{
    const pt_v8i z = {0, 0, 0, 0, 0, 0, 0, 0};
    const pt_v8i yv = (pt_v8i){0, 1, 2, 3, 4, 5, 6, 7} + y0, xw = R - yv;
    pt_v8i lo0 = z + it->lo[0], t = xw - it->hi[2], m = lo0 > t;
    pt_v8i a = (lo0 & m) | (t & ~m); /* max(lo[0], R - y - hi[2]) */
    pt_v8i hi0 = z + it->hi[0], t2 = xw - it->lo[2];
    m = hi0 < t2;
    pt_v8i x2 = (hi0 & m) | (t2 & ~m);      /* min(hi[0], R - y - lo[2]) */
    pt_v8i n = (x2 - a) & (yv < y2); /* taps left in the row (none past y2) */
    const float A = it->A, B = it->B, C = it->C;
    pt_v8f U = __builtin_convertvector(a, pt_v8f) - it->u;
    pt_v8f V = __builtin_convertvector(yv, pt_v8f) - it->v;
    pt_v8f DQ = A * (2.0f * U + 1.0f) + B * V;
    pt_v8f Q = A * U * U + (B * U + C * V) * V;
    pt_v8i started = z, after = z, kept = z;
    /* the steps: as many as the longest span (none when no span is above 0) */
    int steps = 0;
    for (int i = 0; i < 8; i++)
        steps = n[i] > steps ? n[i] : steps;
    for (int N = 0; N < steps; N++) {
        pt_v8i k = (Q < 1.0f) & (n > N);
        started |= k;
        after -= started; /* a true compare is -1 */
        kept -= k;
        Q += DQ;
        DQ += DDQ;
    }
    pt_v8i first = a + (steps - after);
    pt_v8i last = first + kept;
    memcpy(xk, &first, 32);
    memcpy(xl, &last, 32);
    pt_v8i has = kept > 0;
    unsigned mask = 0;
    for (int i = 0; i < 8; i++)
        mask |= (unsigned)(has[i] & 1) << i;
    return mask;
}

/* A lean fold sweep's start made ahead (fold_pre): its first group of rows' kept runs
 * (rows_kept8 from y0, the sweep's first row) and the cursor seeded at its first kept tap
 * (cur_seed), so that the seed's exp runs while the other sweep's rows are read
 * (docs/ptex-log.md, "Session 32, tri32"). ok: made (the sweep takes the lean fold rows). */
typedef struct pt_pre {
    int ok;
    unsigned rows;
    int xks[8], xls[8];
    pt_cur cu;
} pt_pre;

/* pt_pre of sweep it when sweep_t would take the lean fold rows on it (a level with texels):
 * sweep_t's rows [y1, y2) and its test for the recurrence, the same operations on the same
 * values, then rows_kept8 on the first group and cur_seed at its first kept tap - what
 * lean_fold_rows and cur_to compute there (so the same bits). */
__attribute__((always_inline)) static inline void fold_pre(const ti *it, pt_pre *pre)
{
    const int R = it->R;
    const float DDQ = 2.0f * it->A;
    int y1 = it->lo[1], y2 = it->hi[1];
    if (y1 < R - it->hi[2] - it->hi[0] + 1)
        y1 = R - it->hi[2] - it->hi[0] + 1;
    if (y2 > R - it->lo[2] - it->lo[0])
        y2 = R - it->lo[2] - it->lo[0];
    pre->ok = DDQ > 0.0f && (y2 - y1) * (it->hi[0] - it->lo[0]) >= 16 && y1 < y2;
    if (!pre->ok)
        return;
    pre->rows = rows_kept8(it, R, y1, y2, DDQ, pre->xks, pre->xls);
    if (pre->rows) {
        int r = __builtin_ctz(pre->rows);
        cur_seed(&pre->cu, it, pre->xks[r], y1 + r, it->wscale);
    }
}

/* Whether every tap of sweep it's rows [y1, y2) lies in the band proper past the diagonal
 * edge: a tap that fold_tap pulls back onto u + v = 1 (upright x, y >= 0, x + y >= R;
 * inverted x, y <= R - 1, x + y <= R - 1) with 0 < d = x - y + R < 2R, which lean_fold_row
 * reads through lean_band's middle run alone. A row's taps x in [x1, x2) (row_span) have
 * x >= lo[0], x < hi[0], R - hi[2] <= x + y < R - lo[2]; so hi[2] <= 0 (upright) or
 * lo[2] >= 0 (inverted) puts x + y on the band's side, lo[0] >= y2 - R gives d > 0 and
 * hi[0] <= y1 + R gives d < 2R on every row. */
static inline int fold_band_only(const ti *it, int y1, int y2)
{
    const int R = it->R;
    if (it->lo[0] < y2 - R || it->hi[0] > y1 + R)
        return 0;
    if (it->odd)
        return y2 <= R && it->hi[0] <= R && it->lo[2] >= 0;
    return y1 >= 0 && it->lo[0] >= 0 && it->hi[2] <= 0;
}

/* The rows [y1, y2) of a lean Clamp fold sweep over a level with texels, orientation ODD (the
 * sweep's it->odd, a constant here so that the loop holds one lean_fold_row): each row's kept
 * taps [xk, xl) found with the float Q of the per-tap loop (the same taps), the cursor moved
 * to xk, the row read by lean_fold_row; as sweep_t's general recurrence rows, the same
 * weights, texels and order. pre (or NULL): the first group of rows made ahead (fold_pre). */
__attribute__((always_inline)) static inline pt_v4f
lean_fold_rows(int ODD, int BAND, const ti *it, const uint8_t *data, int y1, int y2,
               pt_cur *cu, float DDQ, float wscale, pt_v4f one, pt_v4f acc, float *wsum4,
               const pt_pre *pre, unsigned DT, unsigned NC)
{
    const int R = it->R;
    for (int y0 = y1; y0 < y2; y0 += 8) {
        int xks[8], xls[8];
        unsigned rows;
        if (pre && y0 == y1) { /* the first group, made ahead */
            rows = pre->rows;
            memcpy(xks, pre->xks, sizeof xks);
            memcpy(xls, pre->xls, sizeof xls);
        } else {
            rows = rows_kept8(it, R, y0, y2, DDQ, xks, xls);
        }
        for (; rows; rows &= rows - 1) {
            int r = __builtin_ctz(rows), y = y0 + r, xk = xks[r], xl = xls[r];
            cur_to(cu, it, xk, y, wscale);
            double G = cu->G, E = cu->Ex;
            if (BAND) /* lean_fold_row's band proper (fold_band_only), without its cuts */
                acc = lean_band_mid(ODD, R, data, y, xk, xl, st_dtype_size(DT) * NC, &G, &E,
                                    cu->kxx, one, acc, wsum4, DT, NC);
            else
                acc = lean_fold_row(ODD, R, data, y, xk, xl, &G, &E, cu->kxx, one, acc, wsum4,
                                    DT, NC);
        }
    }
    return acc;
}


/* acc with lane 3 set to +0 and the other lanes' bits kept: where a sweep's weight sum starts
 * (NC < 4: lane 3 sums the weights; sweep_t, piece_r1, piece_r2). */
__attribute__((always_inline)) static inline pt_v4f lane3_cleared(pt_v4f acc)
{
    const pt_v4i keep = {-1, -1, -1, 0};
    pt_v4i bits;
    memcpy(&bits, &acc, 16);
    bits &= keep;
    memcpy(&acc, &bits, 16);
    return acc;
}
/* Sweeps one iterator: Q by finite differences along each row (Heckbert), a tap where Q < 1
 * weighs exp(-Q * 3.5^2 / 2) / R^2. SW_READ reads texel (x, y) of data (a constant face or a
 * 1x1 level: data is its one texel, applied once with the summed weight, as Ptex does);
 * SW_WEIGHT only sums; SW_FOLD reads the folded texel of each tap. Returns the weight. The
 * texel type DT and channel count NC are constants in each instance (sweep_fns), so a tap's
 * loads and sums are a few instructions and the sums stay in registers; the arithmetic and
 * its order are those of every other instance (each channel's sum gets x * w tap by tap). */
__attribute__((always_inline)) static inline float sweep_t(tc *c, const ti *it,
                                                           const uint8_t *data, int constant,
                                                           int how, int REC, pt_kf *kf,
                                                           const pt_pre *pre, unsigned DT,
                                                           unsigned NC)
{
    const size_t ts = st_dtype_size(DT) * NC;
    const int R = it->R;
    /* the channel sums and (NC < 4) the weight's sum in lane 3 of one vector: a tap adds
     * {x0, .., 1} * w, lane by lane the scalar sums' operations (1 * w is w); the untouched
     * lanes add +0 (a sum is never -0: it starts +0 and x + y rounds to +0 when it is 0) */
    pt_v4f one = {0.0f, 0.0f, 0.0f, NC < 4 ? 1.0f : 0.0f}, acc = c->acc;
    if (NC < 4) /* lane 3 (the last sweep's weight) to +0 */
        acc = lane3_cleared(acc);
    float wsum4 = 0.0f, DDQ = 2.0f * it->A; /* wsum4: the weight's sum when NC == 4 */
    float ws = 0.0f; /* the lean weight sweep's sum (lane 3's, which starts at +0) */
    const float gs = -0.5f * (PT_WIDTH * PT_WIDTH);
    const float wscale = it->wscale;
    const int reads = how == SW_READ && !constant;
    /* a read sweep with REC set: the weights by pk_exp2_4, four taps at a time (row_read4;
     * REC 0: the per-tap expf) */
    const int W4 = how == SW_READ && REC;
    const pt_v4f gl = {gs * 1.44269504f, gs * 1.44269504f, gs * 1.44269504f,
                       gs * 1.44269504f}; /* 2^(Q gl) = exp(gs Q) */
    const pt_v4f wsv = {wscale, wscale, wscale, wscale};
    /* only the rows with a tap: x1 < x2 needs R - y - hi[2] < hi[0] and lo[0] < R - y - lo[2]
     * (the rows left out visit nothing) */
    int y1 = it->lo[1], y2 = it->hi[1];
    if (y1 < R - it->hi[2] - it->hi[0] + 1)
        y1 = R - it->hi[2] - it->hi[0] + 1;
    if (y2 > R - it->lo[2] - it->lo[0])
        y2 = R - it->lo[2] - it->lo[0];
    if (reads && y1 >= 0 && y2 <= R && it->lo[0] >= 0 && it->hi[0] <= R) {
        /* every row inside the level (a piece clamped into its face, which Traverse and
         * Discard always apply): the rows without the per-row checks, the row's address
         * stepped; the same Q, DQ and taps as the loop below */
        const size_t rs = (size_t)R * ts;
        const uint8_t *row = data + (size_t)y1 * rs;
        for (int y = y1; y < y2; y++, row += rs) {
            __asm__ volatile("" ::: "memory"); /* as below: the fields re-read each row */
            int x1, x2;
            float Q, DQ;
            row_span(it, R, y, &x1, &x2, &Q, &DQ);
            if (W4 && x2 - x1 >= PT_W4_MIN)
                acc = row_read4(x2 - x1, row + (size_t)x1 * ts, (ptrdiff_t)ts, &Q, &DQ, DDQ,
                                gl, wsv, one, acc, &wsum4, 1, 1, DT, NC);
            else
                acc = row_step(x2 - x1, row + (size_t)x1 * ts, (ptrdiff_t)ts, &Q, &DQ, DDQ,
                               gs, wscale, one, acc, &wsum4, NULL, DT, NC);
        }
        y2 = y1; /* done: the loop below visits nothing */
    }
    /* a sweep of a few taps (under about 16 in its bounds) keeps the per-tap expf, cheaper
     * than the recurrence's start */
    if (REC && how != SW_READ && DDQ > 0.0f &&
        (y2 - y1) * (it->hi[0] - it->lo[0]) >= 16) {
        if (!kf->set)
            kf_get(kf, it, c->kfc);
        /* the weights by recurrence (pt_rec): each row's kept taps [xk, xl) found with the
         * float Q of the per-tap loop below (the same taps), the cursor moved to xk */
        pt_cur cu = {.seeded = 0, .kxx = it->odd ? kf->kyy : kf->kxx, .kxy = kf->kxy,
                     .kyy = it->odd ? kf->kxx : kf->kyy, .ixx = it->odd ? kf->iyy : kf->ixx,
                     .ixy = kf->ixy}; /* seeded at its first kept tap */
        if (REC == 2 && how == SW_FOLD && !constant) {
            int band = fold_band_only(it, y1, y2);
            if (pre && pre->rows) { /* seeded ahead at the first kept tap: cur_to moves 0 */
                cu.seeded = 1;
                cu.x = pre->cu.x;
                cu.y = pre->cu.y;
                cu.G = pre->cu.G;
                cu.Ex = pre->cu.Ex;
                cu.Ey = pre->cu.Ey;
            }
            if (it->odd && band)
                acc = lean_fold_rows(1, 1, it, data, y1, y2, &cu, DDQ, wscale, one, acc,
                                     &wsum4, pre, DT, NC);
            else if (it->odd)
                acc = lean_fold_rows(1, 0, it, data, y1, y2, &cu, DDQ, wscale, one, acc,
                                     &wsum4, pre, DT, NC);
            else if (band)
                acc = lean_fold_rows(0, 1, it, data, y1, y2, &cu, DDQ, wscale, one, acc,
                                     &wsum4, NULL, DT, NC);
            else
                acc = lean_fold_rows(0, 0, it, data, y1, y2, &cu, DDQ, wscale, one, acc,
                                     &wsum4, NULL, DT, NC);
            y2 = y1; /* done: the loop below visits nothing */
        }
        for (int y = y1; y < y2; y++) {
            int xk, x2;
            float Q, DQ;
            if (!row_first_kept(it, R, y, DDQ, &xk, &x2, &Q, &DQ))
                continue;
            if (REC == 2 && how == SW_WEIGHT) {
                /* the lean weight rows: kept_end and the weight loop in one
                 * (tap x + 1 is kept when x + 1 < x2 and its float Q, q, is below 1) */
                cur_to(&cu, it, xk, y, wscale);
                double G = cu.G, E = cu.Ex;
                float q = Q + DQ, dq = DQ + DDQ;
                for (int x = xk;;) { /* lane 3 += 1 * w: += w */
                    ws += (float)G;
                    G *= E;
                    E *= cu.kxx;
                    if (!(++x < x2 && q < 1.0f))
                        break;
                    q += dq;
                    dq += DDQ;
                }
                continue;
            }
            int xl = kept_end(xk, x2, Q, DQ, DDQ);
            cur_to(&cu, it, xk, y, wscale);
            if (REC == 2) { /* the lean rows of a constant face (others: lean_fold_rows) */
                double G = cu.G, E = cu.Ex;
                acc = lean_run(xl - xk, data, 0, &G, &E, cu.kxx, one, acc, &wsum4, DT, NC);
                continue;
            }
            pt_rec rc = {cu.G, cu.Ex, cu.kxx};
            if (how == SW_WEIGHT)
                acc = row_same(xl - xk, NULL, &Q, &DQ, DDQ, gs, wscale, one, acc, &wsum4, &rc,
                               DT, 0);
            else if (constant) /* every tap reads texel 0 */
                acc = row_same(xl - xk, data, &Q, &DQ, DDQ, gs, wscale, one, acc, &wsum4, &rc,
                               DT, NC);
            else
                acc = row_clamp(it, data, y, xk, xl, Q, DQ, DDQ, gs, wscale, one, acc, &wsum4,
                                &rc, 1, DT, NC);
        }
        y2 = y1; /* done */
        if (REC == 2 && how == SW_WEIGHT)
            return ws;
    }
    for (int y = y1; y < y2; y++) {
        /* the row's set-up reads the sweep's fields from memory (an empty asm that may change
         * memory), so that they are not held in registers across the loop, where every expf
         * call would spill and reload them */
        __asm__ volatile("" ::: "memory");
        int x1, x2;
        float Q, DQ;
        row_span(it, R, y, &x1, &x2, &Q, &DQ);
        if (W4 && x2 - x1 >= PT_W4_MIN) { /* the row's taps before, in and after the level's
                                            * row, as the loop below */
            if (!(reads && y >= 0 && y < R)) { /* none read */
                acc = row_read4(x2 - x1, data, 0, &Q, &DQ, DDQ, gl, wsv, one, acc, &wsum4, 0, 1,
                                DT, NC);
                continue;
            }
            int a = clampi(0, x1, x2), b = clampi(R, a, x2);
            acc = row_read4(a - x1, data, 0, &Q, &DQ, DDQ, gl, wsv, one, acc, &wsum4, 0, 0, DT,
                            NC);
            acc = row_read4(b - a, data + ((size_t)y * (size_t)R + (size_t)a) * ts,
                            (ptrdiff_t)ts, &Q, &DQ, DDQ, gl, wsv, one, acc, &wsum4, 1, 0, DT,
                            NC);
            acc = row_read4(x2 - b, data, 0, &Q, &DQ, DDQ, gl, wsv, one, acc, &wsum4, 0, 1, DT,
                            NC);
            continue;
        }
        if (how == SW_FOLD) {
            if (constant) /* every tap reads texel 0 */
                acc = row_same(x2 - x1, data, &Q, &DQ, DDQ, gs, wscale, one, acc, &wsum4, NULL,
                               DT, NC);
            else
                acc = row_clamp(it, data, y, x1, x2, Q, DQ, DDQ, gs, wscale, one, acc, &wsum4,
                                NULL, REC, DT, NC);
            continue;
        }
        /* a read stays inside the level whatever the float bounds did */
        int rd_ok = reads && y >= 0 && y < R;
        const uint8_t *row = rd_ok ? data + (size_t)y * (size_t)R * ts : NULL;
        if (rd_ok && x1 >= 0 && x2 <= R) {
            /* the whole row inside the level (a piece clamped into its face): no checks */
            acc = row_step(x2 - x1, row + (size_t)x1 * ts, (ptrdiff_t)ts, &Q, &DQ, DDQ, gs,
                           wscale, one, acc, &wsum4, NULL, DT, NC);
            continue;
        }
        for (int x = x1; x < x2; x++) {
            if (Q < 1.0f) {
                float w = expf(gs * Q) * wscale;
                pt_v4f tv = one;
                if (how == SW_READ && rd_ok && (unsigned)x < (unsigned)R)
                    tv = texel_vec(row + (size_t)x * ts, one, DT, NC);
                acc += tv * w;
                if (NC == 4)
                    wsum4 += w;
            }
            Q += DQ;
            DQ += DDQ;
        }
    }
    float wsum = NC < 4 ? acc[3] : wsum4;
    if (how == SW_READ && constant) { /* channel lanes get x * wsum, lane 3 (spent) + 0 */
        pt_v4f zero = {0.0f, 0.0f, 0.0f, 0.0f};
        acc += texel_vec(data, zero, DT, NC) * wsum;
    }
    if (how != SW_WEIGHT)
        c->acc = acc; /* one 16-byte store, which the next sweep's 16-byte load forwards */
    return wsum;
}

/* The read sweeps' rows a lane (rows_apply_t): the rows of a piece's two sweeps (upright rows
 * first, then inverted ones) eight at a time, one row a lane of 8-lane vectors (one 256-bit
 * register in the AVX2 instances, two SSE halves in the others; each lane the same operations
 * either way). A lane starts its row as row_span does (the same float operations: the same Q,
 * DQ) and steps the float chain Q += DQ, DQ += DDQ a tap as row_step does (the same Q a tap,
 * so the same kept taps, Q < 1); every tap of every lane is weighed by pt_exp2_8 (pk_exp2_4's
 * operations lane by lane, as row_read4 weighs rows of 3 taps or more; no libm expf), its
 * texel fetched and added to the lane's own sums, a tap not kept (or past its row) adding +0
 * (its texel not used). So a lane's sums are its row's kept taps in tap order; the piece's
 * are the eight lanes' added by one fixed tree (hsum8), then added to c->acc and c->weight
 * once. No branch a tap or a row: the steps of eight rows run as long as the longest; a step
 * where no lane keeps its tap only adds +0 to the sums and steps the chain (no exp, no
 * texels; the same bits). Float texels of three or four channels are loaded 16 bytes a lane
 * and transposed to the channels' vectors by shuffles (lanes_texels; docs/ptex-log.md,
 * "Session 31, tri31"). Pieces at R >= PT_LANES_MIN_R only (both in sweep2_t and piece_rn),
 * so every build takes the same rows for the same piece (docs/ptex-log.md, "tri29"). */
/* the rows a lane from resolution 3 (R = 8) up: below, a piece's few taps cost less by the
 * row functions (piece_r2, piece_r4; docs/ptex-log.md, "tri29") */
#define PT_LANES_MIN_R 8

/* pk_exp2_4 on eight lanes: the same operations lane by lane, so the same value a lane. */
__attribute__((always_inline)) static inline void pt_exp2_8(const pt_v8f *yin, pt_v8f *out)
{
#define PT_C8(c) {c, c, c, c, c, c, c, c}
    const pt_v8f k0 = PT_C8(-126.0f), half = PT_C8(0.5f), one = PT_C8(1.0f);
    const pt_v8f k3 = PT_C8(0.693147181f), k4 = PT_C8(0.240226507f),
                 k5 = PT_C8(0.0555041087f), k6 = PT_C8(0.00961812911f),
                 k7 = PT_C8(0.00133335581f), k8 = PT_C8(0.000154035304f);
#undef PT_C8
    pt_v8f y = *yin;
    /* maxps(k0, y): k0 where k0 > y, else y (a NaN y: y) */
    pt_v8i lo = k0 > y, yb, mb;
    memcpy(&yb, &y, 32);
    memcpy(&mb, &k0, 32);
    yb = (yb & ~lo) | (mb & lo);
    memcpy(&y, &yb, 32);
    pt_v8i ii = __builtin_convertvector(y - half, pt_v8i); /* y <= 0: nearest */
    pt_v8f f = y - __builtin_convertvector(ii, pt_v8f);
    pt_v8f q = one + f * (k3 + f * (k4 + f * (k5 + f * (k6 + f * (k7 + f * k8)))));
    pt_v8i bits = (ii + 127) << 23;
    pt_v8f sc;
    memcpy(&sc, &bits, 32);
    *out = q * sc;
}

/* GCC takes the lane stores of t below for reads of an uninitialised vector (clang has no
 * such warning, and refuses an unknown one under -Werror) */
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
/* Channels 0..NC-1 of the texels idx of data (texel_chan's values) where kept, +0 elsewhere
 * (a lane not kept reads texel 0, whatever it holds, and is then cleared): a lane at a time
 * (AVX2's gathers were slower on the comparison's files: docs/ptex-log.md, "tri29"); float
 * texels of 3-4 channels as one 16-byte load a lane and a transpose when `wide` (three
 * channels: the caller has checked that the 4 bytes past every texel read are in the level). */
__attribute__((always_inline)) static inline void lanes_texels(const uint8_t *data,
                                                               const pt_v8i *idx,
                                                               const pt_v8i *kept, pt_v8f *out,
                                                               int wide, unsigned DT, unsigned NC)
{
    const size_t ts = st_dtype_size(DT) * NC;
    pt_v8i si = *idx & *kept;
    pt_v8f t[4] = {{0}, {0}, {0}, {0}};
    if (DT == ST_DT_F32 && NC >= 3 && wide) {
        /* each lane's texel as one 16-byte load (three channels: 4 bytes past the texel,
         * inside the level: the caller's `wide`), the 8 x 4 block transposed by shuffles to
         * the channels' vectors: the same values as the loads a lane below */
        pt_v4f x[8];
#pragma GCC unroll 8
        for (int L = 0; L < 8; L++)
            memcpy(&x[L], data + (size_t)(uint32_t)si[L] * ts, 16);
        pt_v8f y0 = __builtin_shufflevector(x[0], x[4], 0, 1, 2, 3, 4, 5, 6, 7);
        pt_v8f y1 = __builtin_shufflevector(x[1], x[5], 0, 1, 2, 3, 4, 5, 6, 7);
        pt_v8f y2 = __builtin_shufflevector(x[2], x[6], 0, 1, 2, 3, 4, 5, 6, 7);
        pt_v8f y3 = __builtin_shufflevector(x[3], x[7], 0, 1, 2, 3, 4, 5, 6, 7);
        pt_v8f a01 = __builtin_shufflevector(y0, y1, 0, 8, 1, 9, 4, 12, 5, 13);
        pt_v8f a23 = __builtin_shufflevector(y2, y3, 0, 8, 1, 9, 4, 12, 5, 13);
        pt_v8f b01 = __builtin_shufflevector(y0, y1, 2, 10, 3, 11, 6, 14, 7, 15);
        pt_v8f b23 = __builtin_shufflevector(y2, y3, 2, 10, 3, 11, 6, 14, 7, 15);
        t[0] = __builtin_shufflevector(a01, a23, 0, 1, 8, 9, 4, 5, 12, 13);
        t[1] = __builtin_shufflevector(a01, a23, 2, 3, 10, 11, 6, 7, 14, 15);
        t[2] = __builtin_shufflevector(b01, b23, 0, 1, 8, 9, 4, 5, 12, 13);
        t[3] = __builtin_shufflevector(b01, b23, 2, 3, 10, 11, 6, 7, 14, 15);
    } else {
#pragma GCC unroll 8
        for (int L = 0; L < 8; L++) {
            const uint8_t *px = data + (size_t)(uint32_t)si[L] * ts;
#pragma GCC unroll 4
            for (unsigned ch = 0; ch < NC; ch++)
                t[ch][L] = texel_chan(px, ch, DT);
        }
    }
#pragma GCC unroll 4
    for (unsigned ch = 0; ch < NC; ch++) {
        pt_v8i tb;
        memcpy(&tb, &t[ch], 32);
        tb &= *kept;
        memcpy(&out[ch], &tb, 32);
    }
}
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif

static inline int32_t fbits(float x)
{
    int32_t b;
    memcpy(&b, &x, 4);
    return b;
}

/* The sum of x's eight lanes, always by one tree: (l0 + l4) + (l2 + l6), + (l1 + l5) +
 * (l3 + l7). */
__attribute__((always_inline)) static inline float hsum8(const pt_v8f *x)
{
    pt_v4f h = __builtin_shufflevector(*x, *x, 0, 1, 2, 3) +
               __builtin_shufflevector(*x, *x, 4, 5, 6, 7);
    pt_v4f q = h + __builtin_shufflevector(h, h, 2, 3, 0, 1);
    return q[0] + q[1];
}

/* A sweep's rows as sweep_t clips them (b: its index bounds lo 0..2, hi 0..2): the first row
 * in *y1, the count returned (0: none). */
static inline int sweep_rows(int R, const int *b, int *y1)
{
    int a = b[1], z = b[4];
    if (a < R - b[5] - b[3] + 1)
        a = R - b[5] - b[3] + 1;
    if (z > R - b[2] - b[0])
        z = R - b[2] - b[0];
    *y1 = a;
    return z > a ? z - a : 0;
}

/* Whether sweep_t takes its fast path on a sweep with bounds b (every row inside the R x R
 * level; the condition sweep_t tests, on the same clipped rows). */
static inline int sweep_inside(int R, const int *b)
{
    int y1, n = sweep_rows(R, b, &y1);
    return y1 >= 0 && y1 + n <= R && b[0] >= 0 && b[3] <= R;
}

/* The read sweeps' rows of one piece at resolution R (texels at data; both sweeps' rows inside
 * the level, sweep_inside): eb, ob the upright and inverted sweeps' index bounds (lo 0..2,
 * hi 0..2), ev_ok, od_ok which are valid; (eu, evv) and (ou, ov) their centres, the upright
 * ellipse Ak, Bk, Ck (the inverted one: Ck, Bk, Ak), wscale 1 / R^2. Adds the kept taps' sums
 * to c->acc's channel lanes and their weight to c->weight (see above). */
/* *d = a where m (-1 or 0 a lane), d elsewhere (by pointer: a 32-byte vector passed or
 * returned by value changes the ABI where AVX is not enabled) */
__attribute__((always_inline)) static inline void sel8f(pt_v8f *d, const pt_v8i *m,
                                                        const pt_v8f *a)
{
    pt_v8i ab, db;
    memcpy(&ab, a, 32);
    memcpy(&db, d, 32);
    db = (ab & *m) | (db & ~*m);
    memcpy(d, &db, 32);
}

/* Clamp's fold (fold_tap, then st_tri_texel_t) a lane: *idx, the texel index ty R + tx that
 * the tap of each lane reads, from the tap's centroid in texel units as fold_tap makes it -
 * (float)X + off, (float)Y + off, with X, Y, off the lane's (upright rows: x, y, 1/3; inverted
 * rows: R-1-y, R-1-x, 2/3) - and then fold_tap's operations in its order on each lane: the
 * clamps to >= 0, the pull-back onto cu + cv = R (t = 0.5 (cu + cv - R), its two corrections
 * in order), st_tri_texel_t's truncation, its clamp to R - 1 (its clamp to 0 is not needed:
 * cu, cv >= 0 here, so their int parts are too), its fractions and its even / odd choice. The
 * same float and int operations on the same values: the same texel as fold_tap, for every
 * tap, inside the face or not (fold_tap gives a tap inside the face its own texel). */
__attribute__((always_inline)) static inline void fold_idx8(const pt_v8i *X, const pt_v8i *Y,
                                                            const pt_v8f *off, int R, int rsh,
                                                            pt_v8i *idx)
{
    const pt_v8f z = {0, 0, 0, 0, 0, 0, 0, 0};
    const float fR = (float)R;
    const pt_v8f fRv = z + fR;
    pt_v8f cu = __builtin_convertvector(*X, pt_v8f) + *off;
    pt_v8f cv = __builtin_convertvector(*Y, pt_v8f) + *off;
    pt_v8i m = cu < 0.0f;
    sel8f(&cu, &m, &z);
    m = cv < 0.0f;
    sel8f(&cv, &m, &z);
    pt_v8i pb = cu + cv > fR;
    pt_v8f t = 0.5f * (cu + cv - fR);
    pt_v8f pu = cu - t, pv = cv - t;
    m = pu < 0.0f;
    sel8f(&pv, &m, &fRv);
    sel8f(&pu, &m, &z);
    m = pv < 0.0f;
    sel8f(&pu, &m, &fRv);
    sel8f(&pv, &m, &z);
    sel8f(&cu, &pb, &pu);
    sel8f(&cv, &pb, &pv);
    const int r1 = R - 1;
    pt_v8i ui = __builtin_convertvector(cu, pt_v8i), vi = __builtin_convertvector(cv, pt_v8i);
    m = ui > r1;
    ui = (ui & ~m) | (r1 & m);
    m = vi > r1;
    vi = (vi & ~m) | (r1 & m);
    pt_v8f uf = cu - __builtin_convertvector(ui, pt_v8f);
    pt_v8f vf = cv - __builtin_convertvector(vi, pt_v8f);
    pt_v8i e = uf + vf <= 1.0f;
    pt_v8i tx = (ui & e) | ((r1 - vi) & ~e), ty = (vi & e) | ((r1 - ui) & ~e);
    *idx = (ty << rsh) + tx;
}

/* fold_idx8's X, Y and off a lane at a row's first tap a (row y; up: -1 in upright rows, 0 in
 * inverted ones), and their step to the next tap (X by 1 in upright rows, Y by -1 in inverted
 * ones): rows_apply_t's and st_ptextri_fold_check's. */
__attribute__((always_inline)) static inline void fold_start8(const pt_v8i *up, const pt_v8i *a,
                                                              const pt_v8i *y, int R, pt_v8i *X,
                                                              pt_v8i *Y, pt_v8f *off)
{
    const pt_v8i r1 = (pt_v8i){0, 0, 0, 0, 0, 0, 0, 0} + (R - 1);
    *X = (*up & *a) | (~*up & (r1 - *y));
    *Y = (*up & *y) | (~*up & (r1 - *a));
    pt_v8i ob = (*up & fbits(1.0f / 3.0f)) | (~*up & fbits(2.0f / 3.0f));
    memcpy(off, &ob, 32);
}

__attribute__((always_inline)) static inline void fold_step8(const pt_v8i *up, pt_v8i *X,
                                                             pt_v8i *Y)
{
    *X -= *up;
    *Y += ~*up;
}

/* FOLD (Clamp's whole kernel, not clamped into the face: rows past the level; the lean and
 * general builds at R >= PT_LANES_MIN_R, from sweep2_t): each tap's texel is fold_idx8's
 * (made eight steps at a time ahead of the taps' exp, loads and sums: each step's fold is a
 * long dependent chain) instead of the row's stepped index. The same taps as the
 * recurrence fold sweeps (the same float Q chain, Q < 1) and the same texels (fold_tap's
 * rule); the weights pk_exp2_4's instead of the recurrence's (about 1e-6 relatively) and the
 * sums a row a lane, so Clamp's values move by float rounding (docs/ptex-log.md, "Session 33,
 * tri33"). */
__attribute__((always_inline)) static inline void
rows_apply_t(tc *c, const uint8_t *data, int R, const int *eb, const int *ob, int ev_ok,
             int od_ok, float eu, float evv, float ou, float ov, float Ak, float Bk, float Ck,
             float wscale, int FOLD, unsigned DT, unsigned NC)
{
    int y1e = 0, y1o = 0;
    const int ne = ev_ok ? sweep_rows(R, eb, &y1e) : 0;
    const int no = od_ok ? sweep_rows(R, ob, &y1o) : 0;
    const int total = ne + no;
    const int rsh = __builtin_ctz((unsigned)R); /* R is a power of two */
    const float gs = -0.5f * (PT_WIDTH * PT_WIDTH), glf = gs * 1.44269504f;
    const pt_v8i lane = {0, 1, 2, 3, 4, 5, 6, 7};
    const pt_v8f z8 = {0, 0, 0, 0, 0, 0, 0, 0};
    pt_v8f acc[4] = {z8, z8, z8, z8}, wacc = z8;
    for (int g = 0; g < total; g += 8) {
        pt_v8i id = lane + g;
        pt_v8i up = id < ne, live = id < total;
        pt_v8i y = (up & (y1e + id)) | (~up & (y1o + id - ne));
#define PT_SELI(E, O) ((up & (E)) | (~up & (O)))
        pt_v8i lo0 = PT_SELI(eb[0], ob[0]), lo2 = PT_SELI(eb[2], ob[2]);
        pt_v8i hi0 = PT_SELI(eb[3], ob[3]), hi2 = PT_SELI(eb[5], ob[5]);
#undef PT_SELI
        /* the sweep's ellipse and centre a lane: selects of the bits, no lane inserts */
        pt_v8f A, C, u, v;
        pt_v8i Ab = (up & fbits(Ak)) | (~up & fbits(Ck)), Cb = (up & fbits(Ck)) | (~up & fbits(Ak));
        pt_v8i ub = (up & fbits(eu)) | (~up & fbits(ou)), vb = (up & fbits(evv)) | (~up & fbits(ov));
        memcpy(&A, &Ab, 32);
        memcpy(&C, &Cb, 32);
        memcpy(&u, &ub, 32);
        memcpy(&v, &vb, 32);
        /* row_span a lane: x1 = max(lo[0], R - y - hi[2]), x2 = min(hi[0], R - y - lo[2]) */
        pt_v8i xw = R - y, t = xw - hi2, m = lo0 > t;
        pt_v8i a = (lo0 & m) | (t & ~m);
        pt_v8i t2 = xw - lo2;
        m = hi0 < t2;
        pt_v8i x2 = (hi0 & m) | (t2 & ~m);
        pt_v8i n = (x2 - a) & live;
        pt_v8f U = __builtin_convertvector(a, pt_v8f) - u;
        pt_v8f V = __builtin_convertvector(y, pt_v8f) - v;
        pt_v8f DQ = A * (2.0f * U + 1.0f) + Bk * V;
        pt_v8f Q = A * U * U + (Bk * U + C * V) * V;
        const pt_v8f DDQ = 2.0f * A;
        const int maxn = pt_v8i_max(&n);   /* the longest row's taps */
        pt_v8i idx, X, Y, fidx[8];
        pt_v8f off;
        int wide;
        if (!FOLD) {
            idx = (y << rsh) + a;
            /* 16-byte texel loads when no lane's row reaches the level's last texel (the 4
             * bytes past a three-channel float texel are then the next texel's) */
            pt_v8i end = ((y << rsh) + x2) & live;
            wide = NC == 4 || pt_v8i_max(&end) < R * R;
        } else {
            fold_start8(&up, &a, &y, R, &X, &Y, &off);
            idx = y;
            wide = NC == 4;
        }
        for (int j = 0; j < maxn; j++, idx += 1) {
            if (FOLD && !(j & 7)) {
                /* the next eight steps' texels made first, apart from the taps' work: each
                 * step's fold is a long dependent chain, the steps' chains independent */
                for (int i = 0; i < 8 && i < maxn - j; i++) {
                    fold_idx8(&X, &Y, &off, R, rsh, &fidx[i]);
                    fold_step8(&up, &X, &Y);
                }
            }
            pt_v8i kept = (j < n) & (Q < 1.0f);
            pt_v4i kh = __builtin_shufflevector(kept, kept, 0, 1, 2, 3) |
                        __builtin_shufflevector(kept, kept, 4, 5, 6, 7);
            if (!mask4(kh)) {
                /* no lane keeps this step's tap: each lane adds +0 (a -0 sum becomes +0),
                 * the weights' sums are unchanged (never -0) */
#pragma GCC unroll 4
                for (unsigned ch = 0; ch < NC; ch++)
                    acc[ch] += z8;
                Q += DQ;
                DQ += DDQ;
                continue;
            }
            if (FOLD) {
                idx = fidx[j & 7];
                /* 16-byte loads unless a kept lane reads the level's last texel */
                if (NC == 3) {
                    pt_v8i last = (idx == R * R - 1) & kept;
                    wide = !mask4(__builtin_shufflevector(last, last, 0, 1, 2, 3) |
                                  __builtin_shufflevector(last, last, 4, 5, 6, 7));
                }
            }
            pt_v8f yq = Q * glf, w;
            pt_exp2_8(&yq, &w);
            w = w * wscale;
            pt_v8i wb;
            memcpy(&wb, &w, 32);
            wb &= kept;
            memcpy(&w, &wb, 32);
            pt_v8f tx[4];
            lanes_texels(data, &idx, &kept, tx, wide, DT, NC);
#pragma GCC unroll 4
            for (unsigned ch = 0; ch < NC; ch++)
                acc[ch] += tx[ch] * w;
            wacc += w;
            Q += DQ;
            DQ += DDQ;
        }
    }
    pt_v4f add = {0.0f, 0.0f, 0.0f, 0.0f};
#pragma GCC unroll 4
    for (unsigned ch = 0; ch < NC; ch++)
        add[ch] = hsum8(&acc[ch]);
    c->acc += add;
    c->weight += hsum8(&wacc);
}

int st_ptextri_fold_check(int R, int y0, int x0, int nx, unsigned upmask)
{
    if (R < 1 || (R & (R - 1)) || R > (1 << 15) || nx < 0)
        return -1;
    const int rsh = __builtin_ctz((unsigned)R);
    pt_v8i up, a, y, X, Y, idx;
    pt_v8f off;
    for (int L = 0; L < 8; L++) {
        up[L] = (upmask >> L & 1u) ? -1 : 0;
        a[L] = x0 - L; /* rows starting at different taps */
        y[L] = y0 + L;
    }
    fold_start8(&up, &a, &y, R, &X, &Y, &off);
    int bad = 0;
    for (int j = 0; j < nx; j++) {
        fold_idx8(&X, &Y, &off, R, rsh, &idx);
        fold_step8(&up, &X, &Y);
        for (int L = 0; L < 8; L++) {
            int tx, ty;
            fold_tap(R, up[L] ? 0 : 1, a[L] + j, y[L], &tx, &ty);
            bad += idx[L] != ty * R + tx;
        }
    }
    return bad;
}

typedef void (*sweep_fn)(tc *c, const ti *ev, const ti *od, const uint8_t *data,
                         int constant);

/* Both sweeps of a piece in one call (the sums carried in registers from one to the other):
 * c->weight += the upright sweep's weight, then += the inverted sweep's, as two calls would. */
__attribute__((always_inline)) static inline void sweep2_t(tc *c, const ti *ev, const ti *od,
                                                           const uint8_t *data, int constant,
                                                           int how, int REC, unsigned DT,
                                                           unsigned NC)
{
    /* a read sweep pair (pk_exp2_4's weights) whose rows lie inside the level: a row a lane */
    if (how == SW_READ && REC && !constant && ev->R >= PT_LANES_MIN_R &&
        (!ev->valid || sweep_inside(ev->R, ev->lo)) &&
        (!od->valid || sweep_inside(od->R, od->lo))) {
        rows_apply_t(c, data, ev->R, ev->lo, od->lo, ev->valid, od->valid, ev->u, ev->v, od->u,
                     od->v, ev->A, ev->B, ev->C, ev->wscale, 0, DT, NC);
        return;
    }
    /* Clamp's whole kernel (a fold sweep pair of a level with texels) at R >= PT_LANES_MIN_R,
     * in the builds whose weights are not the per-tap expf (REC: the lean and the general
     * one): a row a lane as above, each tap's texel by fold_idx8 (fold_tap's rule) */
    if (how == SW_FOLD && REC && !constant && ev->R >= PT_LANES_MIN_R) {
        rows_apply_t(c, data, ev->R, ev->lo, od->lo, ev->valid, od->valid, ev->u, ev->v, od->u,
                     od->v, ev->A, ev->B, ev->C, ev->wscale, 1, DT, NC);
        return;
    }
    float w = c->weight;
    pt_kf kf = {.set = 0}; /* the factors once a piece, for both sweeps */
    if (how == SW_FOLD && REC == 2 && !constant && ev->valid && od->valid) {
        /* the lean fold rows of both sweeps: the inverted sweep's start made first (fold_pre),
         * so that its seed's exp overlaps the upright sweep's rows */
        pt_pre pre;
        fold_pre(od, &pre);
        w += sweep_t(c, ev, data, 0, SW_FOLD, 2, &kf, NULL, DT, NC);
        w += sweep_t(c, od, data, 0, SW_FOLD, 2, &kf, pre.ok ? &pre : NULL, DT, NC);
        c->weight = w;
        return;
    }
    if (ev->valid)
        w += sweep_t(c, ev, data, constant, how, REC, &kf, NULL, DT, NC);
    if (od->valid)
        w += sweep_t(c, od, data, constant, how, REC, &kf, NULL, DT, NC);
    c->weight = w;
}

/* A read sweep F (its constant faces' instance: F##c), weights by pk_exp2_4 (W4) or the
 * per-tap expf. */
#define PT_READ(F, W4, DT, NC) PT_READ_AT(F, W4, DT, NC, )
#define PT_READ_AT(F, W4, DT, NC, ATTR)                                                      \
    ATTR __attribute__((noinline)) static void F##c_##DT##_##NC(tc *c, const ti *ev,          \
                                                                const ti *od,                 \
                                                                const uint8_t *d)             \
    {                                                                                        \
        sweep2_t(c, ev, od, d, 1, SW_READ, W4, DT, NC);                                      \
    }                                                                                        \
    ATTR static void F##_##DT##_##NC(tc *c, const ti *ev, const ti *od, const uint8_t *d,   \
                                     int constant)                                          \
    {                                                                                        \
        if (constant) {                                                                      \
            F##c_##DT##_##NC(c, ev, od, d);                                                  \
            return;                                                                          \
        }                                                                                    \
        sweep2_t(c, ev, od, d, 0, SW_READ, W4, DT, NC);                                      \
    }
/* The read sweeps of a constant face or a 1x1 level (no texel read per tap, the one texel
 * times the summed weight after) are an instance of their own, sweep_rc_*; in the others, and
 * in the fold sweeps' two branches, `constant` is a constant. */
#define PT_SWEEP(DT, NC)                                                                     \
    PT_READ(sweep_r, 1, DT, NC)  /* the weights by pk_exp2_4 (row_read4) */                 \
    PT_READ(sweep_rp, 0, DT, NC) /* the per-tap expf (st_ptextri_batch_pertap) */           \
    PT_FOLD(sweep_f, 1, DT, NC)  /* the general recurrence rows */                          \
    PT_FOLD(sweep_fl, 2, DT, NC) /* the lean ones */                                         \
    PT_FOLD(sweep_fp, 0, DT, NC) /* the per-tap expf */                                     \
    PT_FOLD_AVX2(DT, NC)
/* The lean fold sweeps and the read sweeps built for AVX2 as well (PT_AVX2: x86 with GCC or
 * clang; sweep_fla, sweep_ra), chosen at run time when the CPU has it: the same C, so the same operations on the same values (no FMA:
 * the target adds none, and ISO C mode contracts nothing), in VEX encodings (three operands,
 * fewer register copies) and with pt_exp4 in one 256-bit vector. */
#if (defined(__x86_64__) || defined(__i386__)) && defined(__GNUC__)
#define PT_AVX2 1
#define PT_FOLD_AVX2(DT, NC)                                                                 \
    PT_FOLD_AT(sweep_fla, 2, DT, NC, __attribute__((target("avx2"))))                       \
    PT_READ_AT(sweep_ra, 1, DT, NC, __attribute__((target("avx2"))))
#else
#define PT_FOLD_AVX2(DT, NC)
#endif
/* A fold sweep with weights by REC; a constant face: every tap reads texel 0 (not the read
 * sweeps' sum). */
#define PT_FOLD(F, REC, DT, NC) PT_FOLD_AT(F, REC, DT, NC, )
#define PT_FOLD_AT(F, REC, DT, NC, ATTR)                                                     \
    ATTR static void F##_##DT##_##NC(tc *c, const ti *ev, const ti *od, const uint8_t *d,   \
                                     int constant)                                          \
    {                                                                                        \
        if (constant)                                                                        \
            sweep2_t(c, ev, od, d, 1, SW_FOLD, REC, DT, NC);                              \
        else                                                                                 \
            sweep2_t(c, ev, od, d, 0, SW_FOLD, REC, DT, NC);                              \
    }
#define PT_SWEEP_NC(DT) PT_SWEEP(DT, 1) PT_SWEEP(DT, 2) PT_SWEEP(DT, 3) PT_SWEEP(DT, 4)
PT_SWEEP_NC(0)
PT_SWEEP_NC(1)
PT_SWEEP_NC(2)
PT_SWEEP_NC(3)

/* A piece k clamped into its face at resolution 0 (the face's 1 x 1 level: the texel at
 * data), applied as iterators_clamped and c->rd (sweep2_t with constant set) apply it,
 * without making its two sweeps or walking their rows. The clamped bounds are each at least
 * 0, the upper ones at most 1 (1 minus two lower ones), so with R = 1 each index bound is the
 * ceiling of a value in [-1/3, 2/3] or of a lower bound minus 1/3: the upright sweep is valid
 * (hi > lo for u, v and w) exactly when its bounds are lo {0, 0, 0}, hi {1, 1, 1}, and then
 * has one row (y 0) of one tap (x 0); the inverted sweep, when valid, has lo {0, 0, -1}, hi
 * {1, 1, 0}, so no row (y from R - hi[2] - hi[0] + 1 = 1 to hi[1] = 1), and adds texel * 0 to
 * the sums and 0 to the weight: nothing, for a finite texel. So: the upright sweep's bounds
 * by iterators' operations (lanes lo 0..2, hi 0, then hi 1, 2; ceil_int4 outside
 * |x| < 2^30 gives some int that is neither 0 nor 1, as the ceiling there is neither), the
 * tap's Q as iterators and row_span make it (R = 1: fR * fR * .. is the value itself,
 * 1 / R^2 is 1), its expf when Q < 1, then what sweep_t does after its rows - the same
 * operations on the same values. A texel not finite returns 0 (the caller takes the long
 * way). Lane 3 of c->acc (scratch when NC < 4) is not what the long way leaves there. */
__attribute__((always_inline)) static inline int piece_r1_t(tc *c, const tk *k,
                                                            const uint8_t *data, unsigned DT,
                                                            unsigned NC)
{
    const pt_v4f zero = {0.0f, 0.0f, 0.0f, 0.0f};
    const pt_v4f tv = texel_vec(data, zero, DT, NC);
    if (mask4(tv * 0.0f == zero) != 15) /* inf * 0 and NaN * 0 are NaN */
        return 0;
    const float fR = 1.0f, third = (float)(1 / 3.0);
    pt_v4f lo = {k->lo[0], k->lo[1], k->lo[2], 0.0f}, hi = {k->hi[0], k->hi[1], k->hi[2], 0.0f};
    clamp_bounds4(&lo, &hi);
    pt_v4f a = __builtin_shufflevector(lo, hi, 0, 1, 2, 4);
    pt_v4f b = __builtin_shufflevector(hi, hi, 1, 2, 1, 2);
    a = a * fR - third;
    b = b * fR - third;
    const pt_v4i want_a = {0, 0, 0, 1}, want_b = {1, 1, 1, 1};
    if (mask4(ceil_int4(a) == want_a) != 15 || mask4(ceil_int4(b) == want_b) != 15)
        return 1; /* the upright sweep is not valid: nothing to add */
    float Finv = 1.0f / (fR * fR * (k->A * k->C - 0.25f * k->B * k->B));
    float Ak = k->A * Finv, Bk = k->B * Finv, Ck = k->C * Finv;
    float eu = k->u * fR - third, evv = k->v * fR - third;
    float U = (float)0 - eu, V = (float)0 - evv; /* row_span at x = 0, y = 0 */
    float Q = Ak * U * U + (Bk * U + Ck * V) * V;
    if (Q < 1.0f) {
        const float gs = -0.5f * (PT_WIDTH * PT_WIDTH);
        const pt_v4f one = {0.0f, 0.0f, 0.0f, NC < 4 ? 1.0f : 0.0f};
        pt_v4f acc = c->acc;
        if (NC < 4) /* lane 3 to +0, as sweep_t */
            acc = lane3_cleared(acc);
        float wt = expf(gs * Q) * 1.0f, wsum4 = 0.0f;
        acc += one * wt;
        if (NC == 4)
            wsum4 += wt;
        float wsum = NC < 4 ? acc[3] : wsum4;
        c->acc = acc + tv * wsum;
        c->weight += wsum;
    }
    return 1;
}

#define PT_P1(DT, NC)                                                                        \
    static int piece_r1_##DT##_##NC(tc *c, const tk *k, const uint8_t *d)                    \
    {                                                                                        \
        return piece_r1_t(c, k, d, DT, NC);                                                  \
    }
#define PT_P1_NC(DT) PT_P1(DT, 1) PT_P1(DT, 2) PT_P1(DT, 3) PT_P1(DT, 4)
PT_P1_NC(0)
PT_P1_NC(1)
PT_P1_NC(2)
PT_P1_NC(3)

/* The weights of n taps with Q values q[0..n-1] as row_step weighs a kept tap (a read
 * sweep's rows under PT_W4_MIN taps: one libm expf a tap), into w: the one place piece_r2
 * evaluates weights, to follow row_step's if its weights change (piece_r4 has its own copies
 * of row_step's and row_read4's weights: r4_row and its caller). */
__attribute__((always_inline)) static inline void short_row_weights(const float *q, int n,
                                                                    float wscale, float *w)
{
    const float gs = -0.5f * (PT_WIDTH * PT_WIDTH);
    for (int i = 0; i < n; i++)
        w[i] = expf(gs * q[i]) * wscale;
}

/* A valid sweep of a clamped piece at R = 2 (index bounds l0..2, h0..2; the ellipse A, B, C
 * and centre u, v of its ti): its kept taps appended to q, px from n on, the number after them
 * returned. A clamped piece's lower bounds are at least 0 and its upper ones at most 1, so a
 * valid sweep has l0, l1 >= 0 and h0, h1 <= 2 (each the ceiling of 2 x (a value in [0, 1])
 * - 1/3): its rows are 0 and 1, within the level (sweep_t's fast path), row y's taps x in
 * [max(l0, 2 - y - h2), min(h0, 2 - y - l2)) (row_span); row 0 has at most 2 taps and row 1 at
 * most one (upright: l2 >= 0, so x < 1 - l2 <= 1; inverted: h2 <= 0, so x >= 1 - h2 >= 1, and
 * x < h0 <= 2). Rows sweep_t leaves out have empty spans. Each row as row_span starts it (its
 * first tap's Q from the row's x1) and row_step steps it. */
__attribute__((always_inline)) static inline int r2_sweep(int l0, int l1, int l2, int h0,
                                                          int h1, int h2, float A, float B,
                                                          float C, float u, float v,
                                                          const uint8_t *data, size_t ts,
                                                          float *q, const uint8_t **px, int n)
{
    const int R = 2;
    if (l1 <= 0 && 0 < h1) { /* row 0: up to 2 taps */
        int y = 0, xw = R - y;
        int x1 = l0 > xw - h2 ? l0 : xw - h2;
        int x2 = h0 < xw - l2 ? h0 : xw - l2;
        if (x1 < x2) {
            float U = (float)x1 - u, V = (float)y - v;
            float DQ = A * (2.0f * U + 1.0f) + B * V;
            float Q = A * U * U + (B * U + C * V) * V;
            if (Q < 1.0f) {
                q[n] = Q;
                px[n++] = data + (size_t)x1 * ts;
            }
            if (x1 + 1 < x2) {
                Q += DQ;
                if (Q < 1.0f) {
                    q[n] = Q;
                    px[n++] = data + (size_t)(x1 + 1) * ts;
                }
            }
        }
    }
    if (l1 <= 1 && 1 < h1) { /* row 1: at most tap (0, 1) */
        int y = 1, xw = R - y;
        int x1 = l0 > xw - h2 ? l0 : xw - h2;
        int x2 = h0 < xw - l2 ? h0 : xw - l2;
        if (x1 < x2) {
            float U = (float)x1 - u, V = (float)y - v;
            float Q = A * U * U + (B * U + C * V) * V;
            if (Q < 1.0f) {
                q[n] = Q;
                px[n++] = data + ((size_t)R + (size_t)x1) * ts;
            }
        }
    }
    return n;
}

/* Taps i0..i1-1 (texels px, weights w; at most MAX of them, a constant the loop unrolls by)
 * of one sweep of piece_r2 (or piece_r4) added to acc as sweep_t adds them: lane 3 from +0 (NC < 4; wsum4
 * when NC == 4), then *wt += the sweep's weight. */
__attribute__((always_inline)) static inline pt_v4f
r2_add(pt_v4f acc, const uint8_t *const *px, const float *w, int i0, int i1, int MAX,
       float *wt, unsigned DT, unsigned NC)
{
    const pt_v4f one = {0.0f, 0.0f, 0.0f, NC < 4 ? 1.0f : 0.0f};
    if (NC < 4)
        acc = lane3_cleared(acc);
    float wsum4 = 0.0f;
    for (int i = i0; i < i1 && i < i0 + MAX; i++) {
        acc += texel_vec(px[i], one, DT, NC) * w[i];
        if (NC == 4)
            wsum4 += w[i];
    }
    *wt += NC < 4 ? acc[3] : wsum4;
    return acc;
}

/* A whole piece's (piece_r2_t, piece_r4_t, piece_rn_t) bounds at resolution fR, as iterators_t with clamp
 * makes them: the twelve index bounds in ia, ib, ic (bound_lanes' lanes: ev lo 0..2 hi 0 | ev
 * hi 1, 2 od lo 0, 1 | od lo 2 hi 0..2) and the ellipse's Ak, Bk, Ck. Returns sweeps_valid's
 * bits (0: no valid sweep), or -1 when a bound is past 2^30 (iterators takes libm's ceilf
 * there: the caller takes the long way). */
__attribute__((always_inline)) static inline int piece_bounds(const tk *k, float fR, pt_v4i *ia,
                                                              pt_v4i *ib, pt_v4i *ic, float *Ak,
                                                              float *Bk, float *Ck)
{
    pt_v4f a, b, c;
    bound_lanes(k, fR, 1, &a, &b, &c);
    if (mask4(small4(a) & small4(b) & small4(c)) != 15)
        return -1;
    *ia = ceil_int4(a);
    *ib = ceil_int4(b);
    *ic = ceil_int4(c);
    const int valid = sweeps_valid(*ia, *ib, *ic);
    if (!valid)
        return 0;
    float Finv = 1.0f / (fR * fR * (k->A * k->C - 0.25f * k->B * k->B));
    *Ak = k->A * Finv;
    *Bk = k->B * Finv;
    *Ck = k->C * Finv;
    return valid;
}

/* A piece k clamped into its face at resolution 1 (the face's 2 x 2 level, texels at data, not
 * a constant face), applied as iterators_clamped and c->rd (sweep2_t with constant 0) apply
 * it, without the two ti structs, the sweep call or its per-sweep set-up. The twelve index
 * bounds are iterators' operations on the same values (Finv, Ak, Bk, Ck, the centres, the
 * clamp and ceil_int4 of the same lanes); a valid sweep's rows lie inside the level and have
 * at most 2 taps (r2_sweep), so sweep_t takes its fast path and row_step's per-tap weights.
 * Each row's taps are those of row_span and row_step (the same float Q, DQ chain: the same
 * kept taps, Q < 1); the kept taps of both sweeps (at most 3 upright and 1 inverted) are
 * weighed by one short_row_weights call, then added in the sweeps' order: a sweep's channel
 * lanes on from c->acc, its weight's lane 3 from +0 (NC < 4; wsum4 when NC == 4), then
 * c->weight += the upright sweep's weight, += the inverted one's - the same operations on the
 * same values as the long way. Returns 0 (the caller takes the long way) when a bound is past
 * 2^30 (where iterators takes libm's ceilf). Lane 3 of c->acc when NC < 4 (scratch) is the
 * last valid sweep's weight, as the long way leaves it. */
__attribute__((always_inline)) static inline int piece_r2_t(tc *c, const tk *k,
                                                            const uint8_t *data, unsigned DT,
                                                            unsigned NC)
{
    const int R = 2;
    const size_t ts = st_dtype_size(DT) * NC;
    const float fR = (float)R, third = (float)(1 / 3.0);
    pt_v4i ia, ib, ic;
    float Ak, Bk, Ck;
    const int valid = piece_bounds(k, fR, &ia, &ib, &ic, &Ak, &Bk, &Ck);
    if (valid <= 0)
        return valid + 1; /* -1: the long way (0); 0: no valid sweep, nothing to add (1) */
    const int ev_ok = valid & 1, od_ok = valid >> 1;
    /* the kept taps of both sweeps in order (at most 3 each): Q and texel */
    float q[8], w[8];
    const uint8_t *px[8];
    int n = 0, ne = 0;
    if (ev_ok)
        n = r2_sweep(ia[0], ia[1], ia[2], ia[3], ib[0], ib[1], Ak, Bk, Ck,
                     k->u * fR - third, k->v * fR - third, data, ts, q, px, n);
    ne = n;
    if (od_ok)
        n = r2_sweep(ib[2], ib[3], ic[0], ic[1], ic[2], ic[3], Ck, Bk, Ak,
                     (1.0f - k->v) * fR - third, (1.0f - k->u) * fR - third, data, ts, q, px,
                     n);
    uint32_t wsb = (uint32_t)(127 - 2 * 1) << 23; /* 1 / R^2, as iterators_t */
    float wscale;
    memcpy(&wscale, &wsb, 4);
    short_row_weights(q, n, wscale, w);
    pt_v4f acc = c->acc;
    float wt = c->weight;
    /* each valid sweep as sweep_t ends it: lane 3 from +0 (NC < 4; wsum4 when NC == 4), its
     * taps added, c->weight += its weight (the inverted sweep: at most one tap) */
    if (ev_ok)
        acc = r2_add(acc, px, w, 0, ne, 3, &wt, DT, NC);
    if (od_ok)
        acc = r2_add(acc, px, w, ne, n, 1, &wt, DT, NC);
    c->acc = acc;
    c->weight = wt;
    return 1;
}

#define PT_P2(DT, NC)                                                                        \
    static int piece_r2_##DT##_##NC(tc *c, const tk *k, const uint8_t *d)                    \
    {                                                                                        \
        return piece_r2_t(c, k, d, DT, NC);                                                  \
    }
#define PT_P2_NC(DT) PT_P2(DT, 1) PT_P2(DT, 2) PT_P2(DT, 3) PT_P2(DT, 4)
PT_P2_NC(0)
PT_P2_NC(1)
PT_P2_NC(2)
PT_P2_NC(3)

/* Row y of a valid sweep of piece_r4 (index bounds l0..2, h0..2; the ellipse A, B, C and
 * centre u, v of its ti; at most MAXN taps): its kept taps (Q < 1) appended to q, w, px from
 * *np on, as sweep_t's fast path takes the row - row_span's span, Q and DQ, then the float
 * chain Q += DQ, DQ += DDQ a tap (row_step's and row_read4's q_step: the same Q a tap, so the
 * same kept taps). A row of PT_W4_MIN taps or more is weighed as row_read4 weighs it: one
 * pk_exp2_4 of the row's Q values times gl, times wscale (lane by lane, so a lane's weight
 * does not depend on the lanes beside it, nor on which taps row_read4 stepped over first);
 * a shorter row's kept taps are listed in e (*ne on) for row_step's per-tap expf after. */
__attribute__((always_inline)) static inline void
r4_row(int y, int MAXN, int l0, int l2, int h0, int h2, float A, float B, float C, float u,
       float v, float DDQ, float wscale, const uint8_t *data, size_t ts, float *q, float *w,
       const uint8_t **px, int *np, int *e, int *ne)
{
    const int R = 4;
    int xw = R - y;
    int x1 = l0 > xw - h2 ? l0 : xw - h2;
    int x2 = h0 < xw - l2 ? h0 : xw - l2;
    int nt = x2 - x1;
    if (nt <= 0)
        return;
    float U = (float)x1 - u, V = (float)y - v;
    float DQ = A * (2.0f * U + 1.0f) + B * V;
    float Q = A * U * U + (B * U + C * V) * V;
    const uint8_t *p0 = data + ((size_t)y * (size_t)R + (size_t)x1) * ts;
    int n = *np;
    if (MAXN >= PT_W4_MIN && nt >= PT_W4_MIN) {
        const float gs = -0.5f * (PT_WIDTH * PT_WIDTH);
        const pt_v4f gl = {gs * 1.44269504f, gs * 1.44269504f, gs * 1.44269504f,
                           gs * 1.44269504f};
        float q0 = q_step(&Q, &DQ, DDQ), q1 = q_step(&Q, &DQ, DDQ);
        float q2 = q_step(&Q, &DQ, DDQ), q3 = MAXN > 3 && nt > 3 ? Q : 1.0f;
        pt_v4f qv = {q0, q1, q2, q3};
        pt_v4f wv = pk_exp2_4(qv * gl) * wscale;
        for (int i = 0; i < MAXN && i < 4; i++)
            if (qv[i] < 1.0f) {
                q[n] = qv[i];
                w[n] = wv[i];
                px[n++] = p0 + (size_t)i * ts;
            }
        *np = n;
        return;
    }
    for (int i = 0; i < MAXN && i < PT_W4_MIN - 1 && i < nt; i++) {
        float qi = q_step(&Q, &DQ, DDQ);
        if (qi < 1.0f) {
            e[(*ne)++] = n;
            q[n] = qi;
            px[n++] = p0 + (size_t)i * ts;
        }
    }
    *np = n;
}

/* The rows of one valid sweep of piece_r4 (rows y1..y2 - 1 as sweep_t clips them; a clamped
 * piece's lower bounds are at least 0 and its upper ones at most 1, so l0, l1 >= 0 and h0,
 * h1 <= R - the fast path of sweep_t - and row y has at most R - y taps upright (l2 >= 0), at
 * most y inverted (h2 <= 0)). */
__attribute__((always_inline)) static inline void
r4_sweep(int ODD, int l0, int l1, int l2, int h0, int h1, int h2, float A, float B, float C,
         float u, float v, float wscale, const uint8_t *data, size_t ts, float *q, float *w,
         const uint8_t **px, int *np, int *e, int *ne)
{
    const int R = 4;
    int y1 = l1, y2 = h1;
    if (y1 < R - h2 - h0 + 1)
        y1 = R - h2 - h0 + 1;
    if (y2 > R - l2 - l0)
        y2 = R - l2 - l0;
    const float DDQ = 2.0f * A;
#define PT_R4ROW(Y)                                                                          \
    if (y1 <= (Y) && (Y) < y2)                                                               \
        r4_row(Y, ODD ? (Y) : R - (Y), l0, l2, h0, h2, A, B, C, u, v, DDQ, wscale, data, ts, q, \
               w, px, np, e, ne);
    PT_R4ROW(0)
    PT_R4ROW(1)
    PT_R4ROW(2)
    PT_R4ROW(3)
#undef PT_R4ROW
}

/* A piece k clamped into its face at resolution 2 (the face's 4 x 4 level, texels at data,
 * not a constant face), applied as iterators_clamped and c->rd (sweep2_t with constant 0)
 * apply it: piece_r2's bounds (iterators' operations on the same values, R = 4), then each
 * valid sweep by r4_sweep (sweep_t's fast path: the same row functions), without the two ti
 * structs, the sweep call or its per-sweep loads. Returns 0 (the caller takes the long way)
 * when a bound is past 2^30. Lane 3 of c->acc when NC < 4 (scratch) is the last valid
 * sweep's weight, as the long way leaves it. */
__attribute__((always_inline)) static inline int piece_r4_t(tc *c, const tk *k,
                                                            const uint8_t *data, unsigned DT,
                                                            unsigned NC)
{
    const int R = 4;
    const float fR = (float)R, third = (float)(1 / 3.0);
    pt_v4i ia, ib, ic;
    float Ak, Bk, Ck;
    const int valid = piece_bounds(k, fR, &ia, &ib, &ic, &Ak, &Bk, &Ck);
    if (valid <= 0)
        return valid + 1; /* -1: the long way (0); 0: no valid sweep, nothing to add (1) */
    const int ev_ok = valid & 1, od_ok = valid >> 1;
    uint32_t wsb = (uint32_t)(127 - 2 * 2) << 23; /* 1 / R^2, as iterators_t */
    float wscale;
    memcpy(&wscale, &wsb, 4);
    const size_t ts = st_dtype_size(DT) * NC;
    /* the kept taps of both sweeps in order (at most 10 upright, 6 inverted): Q, weight and
     * texel; e: those of rows under PT_W4_MIN taps (weighed after, by expf) */
    float q[16], w[16];
    const uint8_t *px[16];
    int e[16];
    int n = 0, ne = 0, n1;
    if (ev_ok)
        r4_sweep(0, ia[0], ia[1], ia[2], ia[3], ib[0], ib[1], Ak, Bk, Ck, k->u * fR - third,
                 k->v * fR - third, wscale, data, ts, q, w, px, &n, e, &ne);
    n1 = n;
    if (od_ok)
        r4_sweep(1, ib[2], ib[3], ic[0], ic[1], ic[2], ic[3], Ck, Bk, Ak,
                 (1.0f - k->v) * fR - third, (1.0f - k->u) * fR - third, wscale, data, ts, q,
                 w, px, &n, e, &ne);
    {
        const float gs = -0.5f * (PT_WIDTH * PT_WIDTH);
        for (int j = 0; j < ne; j++) /* row_step's weights */
            w[e[j]] = expf(gs * q[e[j]]) * wscale;
    }
    pt_v4f acc = c->acc;
    float wt = c->weight;
    /* each valid sweep as sweep_t ends it: lane 3 from +0 (NC < 4; wsum4 when NC == 4), its
     * taps added in order, c->weight += its weight */
    if (ev_ok)
        acc = r2_add(acc, px, w, 0, n1, 16, &wt, DT, NC);
    if (od_ok)
        acc = r2_add(acc, px, w, n1, n, 16, &wt, DT, NC);
    c->acc = acc;
    c->weight = wt;
    return 1;
}

/* A piece template T (piece_r4_t, piece_rn_t below) per texel type and channel count, NAME_DT_NC,
 * and (x86 with GCC or clang) its AVX2 instance NAMEa_DT_NC, which Traverse's split_apply_avx2
 * calls when the lean sweeps run theirs (tc.avx2): the same C, so the same operations on the
 * same values (no FMA), in VEX encodings - for piece_r4 about 10% fewer instructions than the
 * SSE build at triangle fp 0.25 (docs/ptex-log.md, "tp25"). */
#ifdef PT_AVX2
#define PT_PIECE_AVX2(NAME, T, DT, NC)                                                       \
    __attribute__((target("avx2"))) static int NAME##a_##DT##_##NC(tc *c, const tk *k,      \
                                                                   const uint8_t *d)         \
    {                                                                                        \
        return T(c, k, d, DT, NC);                                                           \
    }
#else
#define PT_PIECE_AVX2(NAME, T, DT, NC)
#endif
#define PT_PIECE(NAME, T, DT, NC)                                                            \
    static int NAME##_##DT##_##NC(tc *c, const tk *k, const uint8_t *d)                      \
    {                                                                                        \
        return T(c, k, d, DT, NC);                                                           \
    }                                                                                        \
    PT_PIECE_AVX2(NAME, T, DT, NC)
#define PT_PIECE_NC(NAME, T, DT)                                                             \
    PT_PIECE(NAME, T, DT, 1) PT_PIECE(NAME, T, DT, 2) PT_PIECE(NAME, T, DT, 3)               \
    PT_PIECE(NAME, T, DT, 4)
#define PT_PIECES(NAME, T)                                                                   \
    PT_PIECE_NC(NAME, T, 0) PT_PIECE_NC(NAME, T, 1) PT_PIECE_NC(NAME, T, 2)                  \
    PT_PIECE_NC(NAME, T, 3)
PT_PIECES(piece_r4, piece_r4_t)

/* A piece k clamped into its face at resolution res >= 3 (the face's R x R level, texels at
 * data, not a constant face), applied as iterators_clamped and c->rd (sweep2_t with constant 0)
 * apply it, without the two ti structs, the sweep call or its per-sweep set-up: the bounds by
 * piece_bounds (iterators' operations on the same values), then rows_apply_t with the values
 * iterators_t gives the sweeps (centres, ellipse, 1 / R^2) - the same operations on the same
 * values as the long way. A clamped piece's rows lie inside the level (its lower bounds are at
 * least 0, its upper ones at most 1); should one not (sweep_inside), or a bound be past 2^30
 * (where iterators takes libm's ceilf), returns 0: the caller takes the long way. */
__attribute__((always_inline)) static inline int piece_rn_t(tc *c, const tk *k,
                                                            const uint8_t *data, unsigned DT,
                                                            unsigned NC)
{
    const int res = k->res, R = 1 << res;
    const float fR = (float)R, third = (float)(1 / 3.0);
    pt_v4i ia, ib, ic;
    float Ak, Bk, Ck;
    const int valid = piece_bounds(k, fR, &ia, &ib, &ic, &Ak, &Bk, &Ck);
    if (valid <= 0)
        return valid + 1; /* -1: the long way (0); 0: no valid sweep, nothing to add (1) */
    const int ev_ok = valid & 1, od_ok = valid >> 1;
    const int eb[6] = {ia[0], ia[1], ia[2], ia[3], ib[0], ib[1]};
    const int ob[6] = {ib[2], ib[3], ic[0], ic[1], ic[2], ic[3]};
    if ((ev_ok && !sweep_inside(R, eb)) || (od_ok && !sweep_inside(R, ob)))
        return 0;
    uint32_t wsb = (uint32_t)(127 - 2 * res) << 23; /* 1 / R^2, as iterators_t */
    float wscale;
    memcpy(&wscale, &wsb, 4);
    rows_apply_t(c, data, R, eb, ob, ev_ok, od_ok, k->u * fR - third, k->v * fR - third,
                 (1.0f - k->v) * fR - third, (1.0f - k->u) * fR - third, Ak, Bk, Ck, wscale,
                 0, DT, NC);
    return 1;
}

/* piece_rn per texel type and channel count, and its AVX2 instances (PT_PIECES above), which
 * the lean build takes when the lean sweeps take theirs (tc.avx2). */
PT_PIECES(piece_rn, piece_rn_t)

typedef int (*piece_r1_fnp)(tc *c, const tk *k, const uint8_t *d);

static piece_r1_fnp piece_r1_fn(unsigned dt, unsigned nc)
{
#define PT_ROW(DT) {piece_r1_##DT##_1, piece_r1_##DT##_2, piece_r1_##DT##_3, piece_r1_##DT##_4}
    static const piece_r1_fnp p1[4][4] = {PT_ROW(0), PT_ROW(1), PT_ROW(2), PT_ROW(3)};
#undef PT_ROW
    return p1[dt][nc - 1];
}

static piece_r1_fnp piece_r2_fn(unsigned dt, unsigned nc)
{
#define PT_ROW(DT) {piece_r2_##DT##_1, piece_r2_##DT##_2, piece_r2_##DT##_3, piece_r2_##DT##_4}
    static const piece_r1_fnp p2[4][4] = {PT_ROW(0), PT_ROW(1), PT_ROW(2), PT_ROW(3)};
#undef PT_ROW
    return p2[dt][nc - 1];
}

/* NAME_fn: the instance of PT_PIECES(NAME, ...) for a texel type and channel count, its AVX2
 * one when avx2 (and the build has them). */
#ifdef PT_AVX2
#define PT_PIECE_AVX2_ROWS(NAME)                                                             \
    static const piece_r1_fnp pa[4][4] = {PT_ROW(NAME##a, 0), PT_ROW(NAME##a, 1),            \
                                          PT_ROW(NAME##a, 2), PT_ROW(NAME##a, 3)};           \
    if (avx2)                                                                                \
        return pa[dt][nc - 1];
#else
#define PT_PIECE_AVX2_ROWS(NAME)
#endif
#define PT_ROW(N, DT) {N##_##DT##_1, N##_##DT##_2, N##_##DT##_3, N##_##DT##_4}
#define PT_PIECE_FN(NAME)                                                                    \
    static piece_r1_fnp NAME##_fn(unsigned dt, unsigned nc, int avx2)                        \
    {                                                                                        \
        static const piece_r1_fnp p[4][4] = {PT_ROW(NAME, 0), PT_ROW(NAME, 1),               \
                                             PT_ROW(NAME, 2), PT_ROW(NAME, 3)};              \
        PT_PIECE_AVX2_ROWS(NAME)                                                             \
        (void)avx2;                                                                          \
        return p[dt][nc - 1];                                                                \
    }
PT_PIECE_FN(piece_r4)
PT_PIECE_FN(piece_rn)
#undef PT_PIECE_FN
#undef PT_ROW
#undef PT_PIECE_AVX2_ROWS

/* SW_WEIGHT reads nothing: the lean instance, the general one and one with the per-tap expf
 * (tc.wt; kf: the piece's factors, shared by its two sweeps, the same values either sweep
 * would make). */
__attribute__((noinline)) static float sweep_weight_pertap(tc *c, const ti *it, pt_kf *kf)
{
    (void)kf;
    return sweep_t(c, it, NULL, 0, SW_WEIGHT, 0, NULL, NULL, ST_DT_F32, 1);
}

__attribute__((noinline)) static float sweep_weight_general(tc *c, const ti *it, pt_kf *kf)
{
    return sweep_t(c, it, NULL, 0, SW_WEIGHT, 1, kf, NULL, ST_DT_F32, 1);
}

__attribute__((noinline)) static float sweep_weight_lean(tc *c, const ti *it, pt_kf *kf)
{
    return sweep_t(c, it, NULL, 0, SW_WEIGHT, 2, kf, NULL, ST_DT_F32, 1);
}

#ifdef PT_AVX2
__attribute__((noinline, target("avx2"))) static float sweep_weight_lean_avx2(tc *c,
                                                                            const ti *it,
                                                                            pt_kf *kf)
{
    return sweep_t(c, it, NULL, 0, SW_WEIGHT, 2, kf, NULL, ST_DT_F32, 1);
}
#endif

/* Whether the lean sweeps' AVX2 instances run (PT_LEAN on a CPU with AVX2: what libgcc found
 * at start-up). */
static int lean_avx2(int wmode)
{
#ifdef PT_AVX2
    return wmode == PT_LEAN && __builtin_cpu_supports("avx2");
#else
    (void)wmode;
    return 0;
#endif
}

/* The read and fold sweeps of texel type dt (0..3) with nc (1..4) channels (pertap: the fold
 * sweeps with one libm expf per tap). */
static void sweep_fns(unsigned dt, unsigned nc, int wmode, sweep_fn *rd, sweep_fn *fold)
{
#define PT_ROW(F, DT) {F##_##DT##_1, F##_##DT##_2, F##_##DT##_3, F##_##DT##_4}
    static const sweep_fn r[4][4] = {PT_ROW(sweep_r, 0), PT_ROW(sweep_r, 1),
                                     PT_ROW(sweep_r, 2), PT_ROW(sweep_r, 3)};
    static const sweep_fn rp[4][4] = {PT_ROW(sweep_rp, 0), PT_ROW(sweep_rp, 1),
                                      PT_ROW(sweep_rp, 2), PT_ROW(sweep_rp, 3)};
    static const sweep_fn f[4][4] = {PT_ROW(sweep_f, 0), PT_ROW(sweep_f, 1),
                                     PT_ROW(sweep_f, 2), PT_ROW(sweep_f, 3)};
    static const sweep_fn fp[4][4] = {PT_ROW(sweep_fp, 0), PT_ROW(sweep_fp, 1),
                                      PT_ROW(sweep_fp, 2), PT_ROW(sweep_fp, 3)};
    static const sweep_fn fl[4][4] = {PT_ROW(sweep_fl, 0), PT_ROW(sweep_fl, 1),
                                      PT_ROW(sweep_fl, 2), PT_ROW(sweep_fl, 3)};
#ifdef PT_AVX2
    static const sweep_fn fla[4][4] = {PT_ROW(sweep_fla, 0), PT_ROW(sweep_fla, 1),
                                       PT_ROW(sweep_fla, 2), PT_ROW(sweep_fla, 3)};
    /* the read sweeps built for AVX2 (the same C: the same bits) */
    static const sweep_fn ra[4][4] = {PT_ROW(sweep_ra, 0), PT_ROW(sweep_ra, 1),
                                      PT_ROW(sweep_ra, 2), PT_ROW(sweep_ra, 3)};
    if (lean_avx2(wmode)) {
        *rd = ra[dt][nc - 1];
        *fold = fla[dt][nc - 1];
        return;
    }
#endif
#undef PT_ROW
    *rd = wmode == PT_PERTAP ? rp[dt][nc - 1] : r[dt][nc - 1];
    *fold = wmode == PT_PERTAP ? fp[dt][nc - 1] : wmode == PT_GENERAL ? f[dt][nc - 1]
                                                                      : fl[dt][nc - 1];
}

/* Applies the piece k to face f (inside it): resolution clamped to the face's, extent to the
 * triangle; its two sweeps are left in ev, od. */
__attribute__((always_inline)) static inline void apply_face_its_t(tc *c, tk *k, uint32_t f,
                                                                 ti *ev, ti *od, int AVX,
                                                                 int FUSE)
{
    const st_face *F = &c->s->faces[f];
    if (k->res > (int)F->ulog2)
        k->res = F->ulog2;
    /* FUSE (the caller does not read ev, od): a piece at resolution 0 by piece_r1 */
    if (FUSE && k->res == 0 && c->p1 &&
        c->p1(c, k, st_face_level(c->s, f, (F->flags & ST_FACE_CONSTANT) ? 0 : F->ulog2)))
        return;
    /* FUSE: a piece at resolution 1 of a face with texels by piece_r2 */
    if (FUSE && k->res == 1 && c->p2 && !(F->flags & ST_FACE_CONSTANT) &&
        c->p2(c, k, st_face_level(c->s, f, F->ulog2 - 1u)))
        return;
    /* FUSE: a piece at resolution 2 of a face with texels by piece_r4 */
    if (FUSE && k->res == 2 && c->p4 && !(F->flags & ST_FACE_CONSTANT) &&
        c->p4(c, k, st_face_level(c->s, f, F->ulog2 - 2u)))
        return;
    /* FUSE: a piece at resolution 3 or more of a face with texels by piece_rn */
    if (FUSE && k->res >= 3 && c->pn && !(F->flags & ST_FACE_CONSTANT) &&
        c->pn(c, k, st_face_level(c->s, f, F->ulog2 - (unsigned)k->res)))
        return;
#ifdef PT_TRAV_AVX2
    if (AVX)
        iterators_clamped_avx2(k, k->res, ev, od);
    else
#endif
        iterators_clamped(k, k->res, ev, od);
    if (!ev->valid && !od->valid)
        return;
    unsigned level = F->ulog2 - (unsigned)k->res;
    int constant = (F->flags & ST_FACE_CONSTANT) || k->res == 0;
    const uint8_t *data = st_face_level(c->s, f, (F->flags & ST_FACE_CONSTANT) ? 0 : level);
    c->rd(c, ev, od, data, constant);
}

static void apply_face_its(tc *c, tk *k, uint32_t f, ti *ev, ti *od)
{
    apply_face_its_t(c, k, f, ev, od, 0, 0);
}

static void apply_face(tc *c, tk *k, uint32_t f)
{
    ti ev, od;
    apply_face_its_t(c, k, f, &ev, &od, 0, 1);
}

/* Whether two sweeps of one kernel (same centre, ellipse and resolution) visit the same taps,
 * so that they sum the same weights in the same order. */
static int same_taps(const ti *a, const ti *b)
{
    if (a->valid != b->valid)
        return 0;
    if (!a->valid)
        return 1;
    for (int i = 0; i < 3; i++)
        if (a->lo[i] != b->lo[i] || a->hi[i] != b->hi[i])
            return 0;
    return 1;
}

/* Whether clamping k into its face, as iterators does with clamp, leaves its bounds as they
 * are (the kernel lies inside the face): then its clamped and unclamped sweeps are the same. */
static inline int kernel_in_face(const tk *k)
{
    return k->lo[0] >= 0.0f && k->lo[1] >= 0.0f && k->lo[2] >= 0.0f &&
           k->hi[0] <= 1.0f - (k->lo[1] + k->lo[2]) && k->hi[1] <= 1.0f - (k->lo[2] + k->lo[0]) &&
           k->hi[2] <= 1.0f - (k->lo[0] + k->lo[1]);
}

/* Traverse: splits k at each edge it overhangs into a neighbour (u, then v, then w) and
 * applies every piece where it lands. */
#define PT_SPLIT(SUF, ATTR, AVX)                                                             \
    ATTR PT_NO_SLP static void split_apply##SUF(tc *c, tk *k, uint32_t f, unsigned depth)     \
    {                                                                                        \
        static const unsigned edge_of[3] = {2, 0, 1}; /* u, v, w is 0 on edge 2, 0, 1 */     \
        const st_face *F = &c->s->faces[f];                                                  \
        for (unsigned i = 0; i < 3; i++) {                                                   \
            unsigned e = edge_of[i];                                                         \
            if (!(k->lo[i] < 0.0f) || F->adjface[e] < 0)                                     \
                continue;                                                                    \
            if (depth >= PT_MAX_DEPTH || c->pieces >= PT_MAX_PIECES)                         \
                continue; /* dropped: the piece stays and is clamped into this face */      \
            tk ka;                                                                           \
            across##SUF(k, i, e, F->adjedge[e], &ka);                                        \
            k->lo[i] = 0.0f;                                                                 \
            c->pieces++;                                                                     \
            split_apply##SUF(c, &ka, (uint32_t)F->adjface[e], depth + 1);                    \
        }                                                                                    \
        ti ev, od;                                                                           \
        apply_face_its_t(c, k, f, &ev, &od, AVX, 1);                                         \
    }
PT_SPLIT(, , 0)
#ifdef PT_TRAV_AVX2
PT_SPLIT(_avx2, __attribute__((target("avx2"))), 1)
#endif

/* Discard: k applied to face f, and its whole weight on f's lattice at its clamped
 * resolution, extended past the face (the coverage's denominator). When clamping k into the
 * face leaves its taps as they are (a kernel inside the face: kernel_in_face, or the same
 * taps after clamping), the whole weight is the weight just applied, summed by the same
 * sweeps. When nothing was kept (weight not above 0: a kernel past the face), tri_eval sets
 * the coverage to 0 without reading the whole weight, so it is not summed. */
static float apply_discard(tc *c, tk *k, uint32_t f)
{
    const st_face *F = &c->s->faces[f];
    int res = k->res > (int)F->ulog2 ? (int)F->ulog2 : k->res;
    ti wev, wod, ev, od;
    if (kernel_in_face(k)) { /* clamping leaves its bounds: the same taps as below */
        apply_face(c, k, f);
        return c->weight;
    }
    apply_face_its(c, k, f, &ev, &od);
    if (!(c->weight > 0.0f))
        return 0.0f; /* nothing kept: the coverage is 0 whatever the whole weight */
    iterators(c->avx2, k, res, &wev, &wod);
    if (same_taps(&ev, &wev) && same_taps(&od, &wod))
        return c->weight; /* 0 + the even sweep's + the odd sweep's, as below */
    float w = 0.0f;
    pt_kf kf; /* only .set is read before kf_set fills the rest */
    kf.set = 0;
    if (wev.valid)
        w += c->wt(c, &wev, &kf);
    if (wod.valid)
        w += c->wt(c, &wod, &kf);
    return w;
}

/* Clamp: every tap of the whole kernel, folded into the face. */
static void apply_folded(tc *c, const tk *k, uint32_t f)
{
    const st_face *F = &c->s->faces[f];
    int res = k->res > (int)F->ulog2 ? (int)F->ulog2 : k->res;
    int constant = (F->flags & ST_FACE_CONSTANT) || res == 0;
    /* a kernel inside the face (clamping it into the face, as iterators does, would leave its
     * bounds as they are) reads every tap in place: the read sweeps, Traverse's and Discard's
     * for such a kernel, the same taps and sums as the fold sweep with the per-tap expf. It is
     * applied as Traverse applies a piece (apply_face: its sweeps clamped, which leaves them as
     * they are, nothing when neither is valid, and the lean builds' pieces applied whole,
     * piece_r1 .. piece_rn: the same bits as the read sweeps; docs/ptex-log.md, "tri30"). */
    if (!constant && kernel_in_face(k)) {
        tk kc = *k;
        apply_face(c, &kc, f);
        return;
    }
    ti ev, od;
    iterators(c->avx2, k, res, &ev, &od);
    const uint8_t *data = st_face_level(c->s, f, (F->flags & ST_FACE_CONSTANT) ? 0
                                                     : F->ulog2 - (unsigned)res);
    if (!ev.valid && !od.valid)
        return;
    c->fold(c, &ev, &od, data, constant);
}

static float one_value(unsigned dt)
{
    return dt == ST_DT_U8 ? 255.0f : dt == ST_DT_U16 ? 65535.0f : 1.0f;
}

/* PtexPointFilterTri: the level-0 small triangle holding (u, v). */
static void point(const st_set *s, uint32_t f, float u, float v, float *out)
{
    const st_face *F = &s->faces[f];
    const uint8_t *p = st_face_level(s, f, 0);
    if (!(F->flags & ST_FACE_CONSTANT)) {
        uint32_t x, y;
        st_tri_texel(F->w, u, v, &x, &y);
        p += ((size_t)y * F->w + x) * st_texel_size(s);
    }
    for (unsigned ch = 0; ch < s->info.nchan; ch++)
        out[ch] = st_channel_get(s->info.dtype, p, ch);
}

/* One triangle-filter query (not the point filter: point_batch_t); returns its st_qstatus.
 * want_cov: the caller keeps the coverage (else Discard skips the sweeps of its denominator,
 * the whole kernel's weight, which nothing else reads; *cov is then not meaningful). Inlined
 * into its one caller, as GCC did on its own before want_cov (a call a query otherwise). */
__attribute__((always_inline)) static inline int tri_eval(const st_set *s, const st_ptexres *t,
                                                          const st_sample_opts *o,
                                                          const st_query *q, float *out,
                                                          float *cov, int want_cov,
                                                          const tc *proto, tk_cache *kc)
{
    uint32_t f = q->face;
    const st_face *F = &s->faces[f];
    unsigned nc = s->info.nchan, dt = s->info.dtype;
    *cov = 1.0f;
    if (o->mode == ST_MODE_TRAVERSE && t && t->ptxflags &&
        (t->ptxflags[f] & PTX_FLAG_NBCONSTANT)) {
        /* Ptex: a face whose neighbourhood is constant returns its value */
        const uint8_t *p = st_face_level(s, f, (F->flags & ST_FACE_CONSTANT) ? 0
                                                                             : F->nlevels - 1u);
        for (unsigned ch = 0; ch < nc; ch++)
            out[ch] = st_channel_get(dt, p, ch);
        return ST_Q_OK;
    }
    float u = q->u < 0.0f ? 0.0f : q->u > 1.0f ? 1.0f : q->u;
    float v = q->v < 0.0f ? 0.0f : q->v > 1.0f ? 1.0f : q->v;
    tk k;
    build_kernel(&k, u, v, q, o->width > 0.0f ? o->width : 1.0f, o->blur, F->ulog2, kc);
    tc c = *proto;
    if (o->mode == ST_MODE_TRAVERSE) {
#ifdef PT_TRAV_AVX2
        if (c.avx2)
            split_apply_avx2(&c, &k, f, 0);
        else
#endif
            split_apply(&c, &k, f, 0);
    } else if (o->mode == ST_MODE_DISCARD && !want_cov) {
        apply_face(&c, &k, f);
    } else if (o->mode == ST_MODE_DISCARD) {
        float whole = apply_discard(&c, &k, f);
        *cov = whole > 0.0f && c.weight < whole ? c.weight / whole : 1.0f;
    } else {
        apply_folded(&c, &k, f);
    }
    if (!(c.weight > 0.0f)) {
        /* nothing of the kernel fell on a texel (a point far past a boundary edge) */
        *cov = 0.0f;
        if (o->zero_rule == ST_ZERO_CLAMP) {
            float cu = u, cv = v;
            if (cu + cv > 1.0f) {
                float d = 0.5f * (cu + cv - 1.0f);
                cu -= d;
                cv -= d;
            }
            point(s, f, cu < 0.0f ? 0.0f : cu, cv < 0.0f ? 0.0f : cv, out);
            return ST_Q_OK;
        }
        for (unsigned ch = 0; ch < nc; ch++)
            out[ch] = NAN;
        return ST_Q_ZERO_COVERAGE;
    }
    float scale = 1.0f / (c.weight * one_value(dt));
    for (unsigned ch = 0; ch < nc; ch++)
        out[ch] = c.acc[ch] * scale;
    return ST_Q_OK;
}

/* The checks of a query: its status (ST_Q_OK when it may be sampled). */
static inline int query_status(const st_set *s, const st_query *qi)
{
    /* the common case in one pass: every compare fails on a NaN or an infinity */
    if (__builtin_expect(qi->face < s->info.nfaces && fabsf(qi->u) <= ST_MAX_COORD &&
                             fabsf(qi->v) <= ST_MAX_COORD && fabsf(qi->dudx) <= ST_MAX_DERIV &&
                             fabsf(qi->dvdx) <= ST_MAX_DERIV && fabsf(qi->dudy) <= ST_MAX_DERIV &&
                             fabsf(qi->dvdy) <= ST_MAX_DERIV, 1))
        return ST_Q_OK;
    if (qi->face >= s->info.nfaces)
        return ST_Q_BAD_FACE;
    if (!(isfinite(qi->u) && isfinite(qi->v) && isfinite(qi->dudx) && isfinite(qi->dvdx) &&
          isfinite(qi->dudy) && isfinite(qi->dvdy)))
        return ST_Q_NONFINITE;
    if (!(fabsf(qi->u) <= ST_MAX_COORD && fabsf(qi->v) <= ST_MAX_COORD &&
          fabsf(qi->dudx) <= ST_MAX_DERIV && fabsf(qi->dvdx) <= ST_MAX_DERIV &&
          fabsf(qi->dudy) <= ST_MAX_DERIV && fabsf(qi->dvdy) <= ST_MAX_DERIV))
        return ST_Q_BAD_FOOTPRINT;
    return ST_Q_OK;
}

/* The point filter over a batch for texel type DT with NC channels: point() with the type's
 * loads, one query after another (the same values, coverage and status as tri_eval gives). */
__attribute__((always_inline)) static inline int point_batch_t(const st_set *s,
                                                               const st_query *q, size_t n,
                                                               float *out, float *coverage,
                                                               uint8_t *status, unsigned DT,
                                                               unsigned NC)
{
    const size_t ts = st_dtype_size(DT) * NC;
    int bad = 0;
    for (size_t i = 0; i < n; i++) {
        const st_query *qi = &q[i];
        float *oi = out + i * NC;
        int st = query_status(s, qi);
        if (st == ST_Q_OK) {
            const st_face *F = &s->faces[qi->face];
            const uint8_t *p = st_face_level(s, qi->face, 0);
            if (!(F->flags & ST_FACE_CONSTANT)) {
                uint32_t x, y;
                st_tri_texel(F->w, qi->u, qi->v, &x, &y);
                p += ((size_t)y * F->w + x) * ts;
            }
            for (unsigned ch = 0; ch < NC; ch++)
                oi[ch] = st_channel_get(DT, p, ch);
        } else {
            for (unsigned ch = 0; ch < NC; ch++)
                oi[ch] = NAN;
        }
        if (coverage)
            coverage[i] = st == ST_Q_OK ? 1.0f : 0.0f;
        if (status)
            status[i] = (uint8_t)st;
        bad += st != ST_Q_OK;
    }
    return bad;
}

typedef int (*point_batch_fn)(const st_set *s, const st_query *q, size_t n, float *out,
                              float *coverage, uint8_t *status);

#define PT_POINT(DT, NC)                                                                     \
    static int point_##DT##_##NC(const st_set *s, const st_query *q, size_t n, float *out,   \
                                 float *coverage, uint8_t *status)                           \
    {                                                                                        \
        return point_batch_t(s, q, n, out, coverage, status, DT, NC);                        \
    }
#define PT_POINT_NC(DT) PT_POINT(DT, 1) PT_POINT(DT, 2) PT_POINT(DT, 3) PT_POINT(DT, 4)
PT_POINT_NC(0)
PT_POINT_NC(1)
PT_POINT_NC(2)
PT_POINT_NC(3)

__attribute__((always_inline)) static inline int tri_batch(const st_set *s,
                                                            const st_sample_opts *o,
                                                            const st_query *q, size_t n,
                                                            float *out, float *coverage,
                                                            uint8_t *status, int wmode)
{
    unsigned nc = s->info.nchan;
    if (o->filter == ST_FILTER_PTEX_POINT) {
#define PT_ROW(DT) {point_##DT##_1, point_##DT##_2, point_##DT##_3, point_##DT##_4}
        static const point_batch_fn pt[4][4] = {PT_ROW(0), PT_ROW(1), PT_ROW(2), PT_ROW(3)};
#undef PT_ROW
        return pt[s->info.dtype][nc - 1](s, q, n, out, coverage, status);
    }
    const st_ptexres *t = st_ptexres_get(s); /* the record (flags); its table is not needed */
    tc proto = {.s = s, .nc = nc, .dt = s->info.dtype}; /* once a batch */
    sweep_fns(proto.dt, nc, wmode, &proto.rd, &proto.fold);
    proto.wt = wmode == PT_PERTAP    ? sweep_weight_pertap
               : wmode == PT_GENERAL ? sweep_weight_general
                                     : sweep_weight_lean;
#ifdef PT_AVX2
    if (lean_avx2(wmode))
        proto.wt = sweep_weight_lean_avx2;
#endif
    proto.avx2 = lean_avx2(wmode);
    /* the lean builds' own shortcuts (the kernel's shape reused, piece_r1): the general and
     * per-tap builds keep the long way, which the tests compare them with */
    const int lean = wmode == PT_LEAN || wmode == PT_LEAN_BASE;
    proto.p1 = lean ? piece_r1_fn(proto.dt, nc) : NULL;
    proto.p2 = lean ? piece_r2_fn(proto.dt, nc) : NULL;
    proto.p4 = lean ? piece_r4_fn(proto.dt, nc, proto.avx2) : NULL;
    proto.pn = lean ? piece_rn_fn(proto.dt, nc, proto.avx2) : NULL;
    tk_cache kc = {.valid = 0};
    pt_kfc kfc = {.valid = 0};
    proto.kfc = lean ? &kfc : NULL;
    int bad = 0;

    for (size_t i = 0; i < n; i++) {
        const st_query *qi = &q[i];
        float *oi = out + i * nc, cov = 0.0f;
        int st = query_status(s, qi);
        if (st == ST_Q_OK) {
            st = tri_eval(s, t, o, qi, oi, &cov, coverage != NULL, &proto,
                          lean ? &kc : NULL);
        } else {
            for (unsigned ch = 0; ch < nc; ch++)
                oi[ch] = NAN;
        }
        if (coverage)
            coverage[i] = cov;
        if (status)
            status[i] = (uint8_t)st;
        bad += st != ST_Q_OK;
    }
    return bad;
}

int st_ptextri_batch(const st_set *s, const st_sample_opts *o, const st_query *q, size_t n,
                     float *out, float *coverage, uint8_t *status)
{
    int lrc = st_set_levels(s, NULL); /* a deferred Ptex import's levels (set.h) */
    return lrc ? lrc : tri_batch(s, o, q, n, out, coverage, status, PT_LEAN);
}

int st_ptextri_batch_pertap(const st_set *s, const st_sample_opts *o, const st_query *q,
                            size_t n, float *out, float *coverage, uint8_t *status)
{
    int lrc = st_set_levels(s, NULL);
    return lrc ? lrc : tri_batch(s, o, q, n, out, coverage, status, PT_PERTAP);
}

int st_ptextri_batch_baseline(const st_set *s, const st_sample_opts *o, const st_query *q,
                              size_t n, float *out, float *coverage, uint8_t *status)
{
    int lrc = st_set_levels(s, NULL);
    return lrc ? lrc : tri_batch(s, o, q, n, out, coverage, status, PT_LEAN_BASE);
}

int st_ptextri_batch_general(const st_set *s, const st_sample_opts *o, const st_query *q,
                             size_t n, float *out, float *coverage, uint8_t *status)
{
    int lrc = st_set_levels(s, NULL);
    return lrc ? lrc : tri_batch(s, o, q, n, out, coverage, status, PT_GENERAL);
}

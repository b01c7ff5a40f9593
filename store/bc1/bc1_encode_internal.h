/* store/bc1/bc1_encode_internal.h - what the stage files of the BC1 block encoder share; not
 * an interface (bc1.h is).
 *
 * Owns: the block's working types (blk: the colours and weights of one block; cand: a
 * candidate encoding; axis, sorted, nbase, profile), the small inline helpers every stage
 * uses (565 rounding, the exact palette as floats, the selection constants, the split merge
 * rule of the vector scans), the functions one stage calls in another, and the run-time
 * choice of the AVX2 twins. Does not own: anything outside one 4x4 block.
 *
 * The files (the method is written up in bc1_encode.c):
 *   bc1_encode.c       entry points (blocks, images), the levels (profiles) and encode_colours,
 *                      which runs the stages below in a level's order;
 *   bc1_fit.c          principal axis, least-squares endpoints, exact per-channel refinement,
 *                      the 4-colour rounds, FAST's projected selection;
 *   bc1_cluster.c      the ranking along the axis, the 4- and 3-colour cluster fits;
 *   bc1_select.c       exact selection (every palette distance), candidates (try4/try3), the
 *                      steepest-descent +-1 search over the 565 components;
 *   bc1_encode_avx2.c  the AVX2 twins of the hot loops and the CPU check.
 * SSE2 is the x86-64 baseline; the plain C paths (#else of __SSE2__) are for other CPUs.
 * Every AVX2 twin computes what its SSE2 twin does, lane by lane and in the same order of
 * every sum, so the blocks are byte-identical either way (tests/unit/test_bc1_simd.c).
 */
#ifndef ST_BC1_ENCODE_INTERNAL_H
#define ST_BC1_ENCODE_INTERNAL_H

#include <stdint.h>
#include <string.h>

#include "bc1_texel.h"

#ifdef __SSE2__
#include <emmintrin.h>
#endif
/* The AVX2 twins exist where GCC-style target attributes and x86-64 do (bc1_encode_avx2.c);
 * elsewhere ST_BC1_AVX2 is 0, st_bc1e_cpu_avx2() answers 0 and the calls compile away. */
#if defined(__SSE2__) && defined(__GNUC__) && defined(__x86_64__)
#include <immintrin.h>
#define ST_BC1_AVX2 1
#else
#define ST_BC1_AVX2 0
#endif

/* The pragma below applies to every file of the encoder (they all include this header first
 * among their own). */

/* GCC at -O2 does not unroll the short fixed loops over palette entries, texel groups and
 * split rows; unrolled they run ~5% faster (measured, docs/bc1.md). Clang unrolls them on its
 * own. */
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC optimize("unroll-loops")
#endif

#ifdef __SSE2__
static inline float hsum(__m128 v)
{
    __m128 h = _mm_add_ps(v, _mm_movehl_ps(v, v));
    return _mm_cvtss_f32(_mm_add_ss(h, _mm_shuffle_ps(h, h, 1)));
}
#endif

/* A block's opaque colours, channel-planar. Always 16 entries: texels that do not count
 * (transparent ones) have weight 0, so every loop below has a fixed trip count of 16 and the
 * compiler vectorises it. */
typedef struct blk {
    float r[16], g[16], b[16], w[16];
    int   n;              /* texels of weight 1 */
    int   unit;           /* every weight is 1 (opaque, unweighted) */
    int   avx2;           /* run the AVX2 twins (bc1_encode_avx2.c): the CPU has AVX2; the
                             entry point decides once per block (BC1_AVX2 below) */
} blk;

typedef struct cand {
    uint16_t c0, c1;      /* as written to the block */
    uint8_t  sel[16];
    float    err;
} cand;

static inline uint16_t pack565(int r5, int g6, int b5)
{
    return (uint16_t)((r5 << 11) | (g6 << 5) | b5);
}

static inline int clampi(int v, int lo, int hi) { return v < lo ? lo : v > hi ? hi : v; }

/* Rounds an 8-bit-scale colour to 565 (nearest expanded value, via the usual scaling). */
static inline uint16_t round565(float r, float g, float b)
{
#if defined(__SSE2__) && defined(__x86_64__)
    /* the same truncation of x * scale + 0.5 and clamp, three channels at once */
    __m128 v = _mm_add_ps(_mm_mul_ps(_mm_set_ps(0.0f, b, g, r),
                                     _mm_set_ps(0.0f, 31.0f / 255.0f, 63.0f / 255.0f,
                                                31.0f / 255.0f)),
                          _mm_set1_ps(0.5f));
    __m128i q = _mm_cvttps_epi32(v);
    q = _mm_packs_epi32(q, q);
    q = _mm_max_epi16(q, _mm_setzero_si128());
    q = _mm_min_epi16(q, _mm_set_epi16(0, 0, 0, 0, 0, 31, 63, 31));
    uint64_t w = (uint64_t)_mm_cvtsi128_si64(q);
    return pack565((int)(w & 0xFFFF), (int)(w >> 16 & 0xFFFF), (int)(w >> 32 & 0xFFFF));
#else
    int r5 = clampi((int)(r * (31.0f / 255.0f) + 0.5f), 0, 31);
    int g6 = clampi((int)(g * (63.0f / 255.0f) + 0.5f), 0, 63);
    int b5 = clampi((int)(b * (31.0f / 255.0f) + 0.5f), 0, 31);
    return pack565(r5, g6, b5);
#endif
}

/* Exact palette as floats: pal[k][j] (channel-major); four = 4-colour mode. */
static inline void palette_f(uint16_t c0, uint16_t c1, int four, float pal[3][4])
{
#ifdef __SSE2__
    /* the same values four lanes (r, g, b, -) at a time: bit replication by shifts (the
     * 6-bit green lane blended in), the thirds by the product with the float nearest 1/3
     * truncated (exact for every pair of 8-bit values, checked exhaustively), then a
     * transpose to the channel-major layout */
    __m128i q0 = _mm_set_epi32(0, c0 & 31, (c0 >> 5) & 63, c0 >> 11);
    __m128i q1 = _mm_set_epi32(0, c1 & 31, (c1 >> 5) & 63, c1 >> 11);
    const __m128i g6 = _mm_set_epi32(0, 0, -1, 0);
    __m128i x0 = _mm_or_si128(
        _mm_andnot_si128(g6, _mm_or_si128(_mm_slli_epi32(q0, 3), _mm_srli_epi32(q0, 2))),
        _mm_and_si128(g6, _mm_or_si128(_mm_slli_epi32(q0, 2), _mm_srli_epi32(q0, 4))));
    __m128i x1 = _mm_or_si128(
        _mm_andnot_si128(g6, _mm_or_si128(_mm_slli_epi32(q1, 3), _mm_srli_epi32(q1, 2))),
        _mm_and_si128(g6, _mm_or_si128(_mm_slli_epi32(q1, 2), _mm_srli_epi32(q1, 4))));
    __m128 fa = _mm_cvtepi32_ps(x0), fb = _mm_cvtepi32_ps(x1), f2, f3;
    if (four) {
        const __m128 third = _mm_set1_ps(1.0f / 3.0f);
        f2 = _mm_cvtepi32_ps(_mm_cvttps_epi32(_mm_mul_ps(_mm_add_ps(_mm_add_ps(fa, fa), fb), third)));
        f3 = _mm_cvtepi32_ps(_mm_cvttps_epi32(_mm_mul_ps(_mm_add_ps(_mm_add_ps(fb, fb), fa), third)));
    } else {
        f2 = _mm_cvtepi32_ps(_mm_srai_epi32(_mm_add_epi32(x0, x1), 1));
        f3 = _mm_set1_ps(2000.0f); /* never chosen: far from 0..255 */
    }
    _MM_TRANSPOSE4_PS(fa, fb, f2, f3);
    _mm_storeu_ps(pal[0], fa);
    _mm_storeu_ps(pal[1], fb);
    _mm_storeu_ps(pal[2], f2);
#else
    uint8_t e0[3], e1[3];
    st_bc1_565_to_rgb8(c0, e0);
    st_bc1_565_to_rgb8(c1, e1);
    for (int k = 0; k < 3; k++) {
        int a = e0[k], b = e1[k];
        pal[k][0] = (float)a;
        pal[k][1] = (float)b;
        if (four) {
            pal[k][2] = (float)((2 * a + b) / 3);
            pal[k][3] = (float)((a + 2 * b) / 3);
        } else {
            pal[k][2] = (float)((a + b) / 2);
            pal[k][3] = 2000.0f; /* never chosen: far from 0..255 */
        }
    }
#endif
}

#ifdef __SSE2__
/* The selection constants of a pair, per entry j: kv[0..2][j] = -8 times the entry's r, g, b
 * and kv[3][j] = 4 |p_j|^2 + j (integers: exact in any order of operations). */
static inline void palette_keys(uint16_t c0, uint16_t c1, float kv[4][4])
{
    float pal[3][4];
    palette_f(c0, c1, c0 > c1, pal);
    __m128 R = _mm_loadu_ps(pal[0]), G = _mm_loadu_ps(pal[1]), Bv = _mm_loadu_ps(pal[2]);
    const __m128 m8 = _mm_set1_ps(-8.0f);
    _mm_storeu_ps(kv[0], _mm_mul_ps(R, m8));
    _mm_storeu_ps(kv[1], _mm_mul_ps(G, m8));
    _mm_storeu_ps(kv[2], _mm_mul_ps(Bv, m8));
    __m128 n = _mm_add_ps(_mm_add_ps(_mm_mul_ps(R, R), _mm_mul_ps(G, G)), _mm_mul_ps(Bv, Bv));
    _mm_storeu_ps(kv[3], _mm_add_ps(_mm_mul_ps(n, _mm_set1_ps(4.0f)),
                                    _mm_set_ps(3.0f, 2.0f, 1.0f, 0.0f)));
}
#endif

/* Principal axis endpoints: e0 at the largest projection, e1 at the smallest. inset: fraction
 * of the range moved inwards at both ends. */
typedef struct axis {
    float m[3], v[3], len2, lo, hi;
    float var;            /* weighted sum of squared distances to the mean (trace of C) */
    float tot[4];         /* sums of w, w r, w g, w b */
} axis;

/* The neighbourhood search moves one channel of one endpoint by +-1, so the squared distance
 * of texel i to palette entry j changes only in that channel's term. For the current pair,
 * other[k][j][i] = the distance without channel k; a move in channel k then costs one
 * subtraction, multiplication, addition and minimum per entry and texel:
 * distance = other + (x_k - p_jk)^2. Every value is an integer below 2^18 (exact in float),
 * so the minimum is the exact palette distance the selection would find. */
typedef struct nbase {
    float other[3][4][16];
} nbase;

/* What a level does (see the method in bc1_encode.c). */
typedef struct profile {
    float inset;        /* of the initial axis endpoints */
    int   seed;         /* projected least-squares rounds before the exact ones (HQ) */
    int   rounds;       /* round -> select -> least squares rounds, 4-colour */
    int   neigh;        /* rounds of the steepest-descent +-1 search, 4-colour */
    int   rounds3;      /* 3-colour trial rounds for opaque blocks (0 = no trial) */
    int   neigh3;       /* search rounds of the 3-colour trial */
    float r3ratio;      /* the trial's rounds go on only when its first error is within this
                           factor of the 4-colour error */
    float n3ratio;      /* ... and its neighbourhood search only when within this */
    int   radius;       /* exact per-channel search radius after each least squares (0 = round) */
    float inset2;       /* a second start with this inset (< 0: none) */
    int   cluster;      /* a start from the cluster fit over the splits within +-cluster */
    int   proj;         /* FAST: least-squares rounds on projected selectors (0 = the exact
                           rounds above) */
    int   proj_final;   /* FAST: the last selection by projection too (no palette distance) */
    int   fit3;         /* blocks of weight 1: the 3-colour trial starts from the 3-colour
                           cluster fit and runs this many rounds (0: from the axis) */
} profile;

/* The block's texels ranked along the axis (descending projection) and the prefix sums of
 * weight and weighted colour in that order, the colours taken relative to their mean (the fits
 * are translation invariant, the sums stay small and P_16 = 0); padded to 24: the vector
 * loops read up to 7 past 16. */
typedef struct sorted {
    float pw[24], pr[24], pg[24], pb[24];
} sorted;

#ifdef __SSE2__
/* Descending order without branches. Keys: the projection's bits made monotone as signed
 * integers, the low 4 bits replaced by 15 - i (projections closer than 2^-19 relative count
 * as equal and keep texel order), so the keys are distinct and rank(i) = #{j: key_j > key_i}:
 * one comparison per pair. */
static inline __m128i rank_keys_sse(__m128 p, __m128i lanes15)
{
    __m128i b = _mm_castps_si128(p);
    b = _mm_xor_si128(b, _mm_and_si128(_mm_srai_epi32(b, 31), _mm_set1_epi32(0x7fffffff)));
    return _mm_or_si128(_mm_and_si128(b, _mm_set1_epi32(~15)), lanes15);
}

/* Lane by lane the better of (a, ai) and (b, bi): higher score, on a tie the lower index
 * (index -1: nothing found). */
static inline void split_pick_sse(__m128 *a, __m128i *ai, __m128 b, __m128i bi)
{
    __m128 take = _mm_or_ps(_mm_cmpgt_ps(b, *a),
                            _mm_and_ps(_mm_cmpeq_ps(b, *a),
                                       _mm_castsi128_ps(_mm_and_si128(
                                           _mm_cmplt_epi32(bi, *ai),
                                           _mm_cmpgt_epi32(bi, _mm_set1_epi32(-1))))));
    *a = _mm_or_ps(_mm_and_ps(take, b), _mm_andnot_ps(take, *a));
    __m128i t = _mm_castps_si128(take);
    *ai = _mm_or_si128(_mm_and_si128(t, bi), _mm_andnot_si128(t, *ai));
}
#endif

/* ---- across the stages ------------------------------------------------------------------ */

/* The CPU check (bc1_encode_avx2.c): 1 when the AVX2 twins may run. */
int st_bc1e_cpu_avx2(void);
/* Whether block B takes the AVX2 twin at a call site (a plain if: no #if in the logic). */
#define BC1_AVX2(B) (ST_BC1_AVX2 && (B)->avx2)

/* The block encoder behind the entry points (bc1_encode.c); avx2: run the AVX2 twins (only
 * when st_bc1e_cpu_avx2() says so; 0 = the SSE2 paths, as test_bc1_simd compares). */
void st_bc1e_encode_block(const uint8_t rgba[64], const float weight[16], int level, int avx2,
                          uint8_t out[8]);

/* bc1_select.c */
void st_bc1e_try4(const blk *B, uint16_t a, uint16_t b, cand *best);
void st_bc1e_try3(const blk *B, uint16_t a, uint16_t b, cand *best);
void st_bc1e_neighbourhood(const blk *B, cand *best, int four, int rounds);

/* bc1_fit.c */
void st_bc1e_axis_compute(const blk *B, axis *A);
void st_bc1e_axis_endpoints(const axis *A, float inset, float e0[3], float e1[3]);
int st_bc1e_ls_endpoints(const blk *B, const uint8_t *sel, int four, const float tot[4],
                         float e0[3], float e1[3]);
void st_bc1e_refine_exact(const blk *B, const uint8_t *sel, int four, const float e0[3],
                          const float e1[3], int radius, uint16_t *c0, uint16_t *c1);
void st_bc1e_rounds4(const blk *B, const profile *P, const axis *A, float e0[3], float e1[3],
                     cand *best);
void st_bc1e_proj_rounds(const blk *B, const axis *A, float inset, int rounds, float e0[3],
                         float e1[3]);
void st_bc1e_encode_fast4(const blk *B, const profile *P, const axis *A, cand *best);

/* bc1_cluster.c */
void st_bc1e_sort_prefix(const blk *B, const axis *A, sorted *S);
int st_bc1e_cluster_fit(const blk *B, const axis *A, const sorted *S, const int lo[3],
                        const int hi[3], float e0[3], float e1[3]);
#ifdef __SSE2__
int st_bc1e_cluster_fit3(const blk *B, const axis *A, const sorted *S, float e0[3],
                         float e1[3], float *cont);
#endif

/* bc1_encode_avx2.c: the twins (defined only when ST_BC1_AVX2) */
#ifdef __SSE2__
float st_bc1e_select_avx2(const blk *B, uint16_t c0, uint16_t c1, uint8_t *sel, float limit);
void st_bc1e_nbase_fill_avx2(const blk *B, uint16_t c0, uint16_t c1, nbase *N);
void st_bc1e_moves_eval_avx2(const blk *B, const nbase *N, int k, const float p2[4][4],
                             int three, float err[4]);
void st_bc1e_rank16_avx2(const float proj[16], int32_t rank[16]);
void st_bc1e_cluster_scan_avx2(const float *q3r, const float *q3g, const float *q3b,
                               const float *w9, const float *w29, float wsum, const int lo[3],
                               const int hi[3], __m128 *best4, __m128i *idx4);
void st_bc1e_split_scan_tab_avx2(const float *pr, const float *pg, const float *pb,
                                 const int lo[3], const int hi[3], __m128 *best4,
                                 __m128i *idx4);
void st_bc1e_split3_scan_avx2(const float *pr, const float *pg, const float *pb,
                              __m128 *best4, __m128i *idx4);
#endif

#endif

/* store/bc1/bc1_encode.c - the BC1 block encoder (fast and high-quality levels) and the threaded
 * image encoder.
 *
 * Owns: choosing endpoints and selectors for one 4x4 block, measured with the exact
 * truncating decoder (bc1_texel.h); splitting an image over threads. Does not own: sets,
 * seams or files (bc1_set.c, bc1_seam.c, seammask.c, dds.c).
 *
 * Method (written from scratch; ideas are the usual ones):
 *   1. principal axis of the block's colours (weighted moments, covariance, C^5 applied to
 *      the axis of largest variance by two squarings);
 *   2. initial endpoints: the extreme projections on the axis, inset by 1/16;
 *   3. FAST: round to RGB565 -> selectors by projection on the line through the decoded
 *      endpoints (rounded to thirds) -> least-squares endpoints -> round -> selectors by
 *      projection with the thresholds halfway between the exact palette entries. No palette
 *      distance is computed.
 *   4. HQ and BEST: rounds of: round -> every selector by the exact palette distance ->
 *      least squares for those selectors (HQ: one); a cluster fit (texels ranked along the
 *      axis, ordered splits into the four palette runs, the least-squares score of each split
 *      from prefix sums of centred colours; HQ tries the splits within +-3 of those the best
 *      selectors imply for the first two split points and eight values of the third, BEST
 *      all 969); a steepest-descent search over the six
 *      565 components of the best pair (each round measures all twelve +-1 moves from one
 *      table of per-channel distances and takes the best; HQ at most 4 rounds); then a
 *      3-colour trial (c0 <= c1, selectors 0..2, weights 0, 1/2, 1) that starts from the
 *      3-colour cluster fit over all 153 splits of the same ranking, is dropped when even
 *      that fit's unquantised error is not below the 4-colour error, and gets up to 2 rounds
 *      of the search (HQ: only when within 10% of the 4-colour error); kept when its exact
 *      error is lower. Opaque input never gets selector 3 in 3-colour mode, which would be
 *      transparent black. Blocks of 16 texels of weight 1 (opaque, unweighted: the common
 *      case) score the splits with the generated 1/determinant tables of bc1_tables.h (no
 *      division); weighted blocks compute the determinants.
 *   5. a block of one colour uses the generated optimal tables (bc1_tables.h).
 * SSE2 throughout (x86-64 baseline; plain C elsewhere); on CPUs with AVX2 (checked at run
 * time) the hot loops run eight texels / splits at a time with the same arithmetic lane by
 * lane (and the same order of every sum), so the output is byte-identical either way
 * (tests/unit/test_bc1_simd.c compiles this file a second time with AVX2 off and compares).
 * Texels with alpha < 128 force 3-colour mode with selector 3 on them.
 */
#include "bc1.h"
#include "bc1_tables.h"
#include "bc1_texel.h"

#include <math.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif
/* AVX2 is used only in functions that say so, chosen at run time (__builtin_cpu_supports);
 * every such function computes exactly what its SSE2 twin does. */
#if defined(__SSE2__) && defined(__GNUC__) && defined(__x86_64__)
#include <immintrin.h>
#define ST_BC1_AVX2 1
#else
#define ST_BC1_AVX2 0
#endif
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

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

/* Picks selectors for (c0, c1) in the mode implied by their order and returns the squared
 * error. The caller guarantees c0 > c1 for 4-colour and c0 <= c1 for 3-colour. `limit`: the
 * caller only keeps a result below it, so the evaluation may stop as soon as the running
 * error reaches it (the return value is then >= limit and sel is unspecified). */
#ifdef __SSE2__
static float select_sse(const blk *B, uint16_t c0, uint16_t c1, uint8_t *sel, float limit)
{
    /* |x - p|^2 = |x|^2 + (|p|^2 - 2 x.p): the minimum of the bracket picks the entry.
     * key = 4 * bracket + selector as a float (integers, |key| < 2^21: exact) gives both,
     * ties going to the lower selector; the unused 3-colour entry is never the minimum. */
    float kv[4][4];
    palette_keys(c0, c1, kv);
    __m128 pr[4], pg[4], pb[4], pk[4];
    for (int j = 0; j < 4; j++) {
        pr[j] = _mm_set1_ps(kv[0][j]);
        pg[j] = _mm_set1_ps(kv[1][j]);
        pb[j] = _mm_set1_ps(kv[2][j]);
        pk[j] = _mm_set1_ps(kv[3][j]);
    }
    const __m128i three = _mm_set1_epi32(3);
    const __m128 quarter = _mm_set1_ps(0.25f);
    __m128i sg[4];
    __m128 acc = _mm_setzero_ps();
    for (int g = 0; g < 16; g += 4) {
        __m128 r = _mm_loadu_ps(B->r + g), gg = _mm_loadu_ps(B->g + g), b = _mm_loadu_ps(B->b + g);
        __m128 key = _mm_add_ps(_mm_add_ps(_mm_mul_ps(r, pr[0]), _mm_mul_ps(gg, pg[0])),
                                _mm_add_ps(_mm_mul_ps(b, pb[0]), pk[0]));
        for (int j = 1; j < 4; j++) {
            __m128 k = _mm_add_ps(_mm_add_ps(_mm_mul_ps(r, pr[j]), _mm_mul_ps(gg, pg[j])),
                                  _mm_add_ps(_mm_mul_ps(b, pb[j]), pk[j]));
            key = _mm_min_ps(key, k);
        }
        /* key = 4 (|p|^2 - 2 x.p) + j, j = key mod 4 (key may be negative: two's
         * complement & 3 is still the residue) */
        __m128i ki = _mm_cvtps_epi32(key);
        __m128i s = _mm_and_si128(ki, three);
        __m128 bracket = _mm_mul_ps(_mm_sub_ps(key, _mm_cvtepi32_ps(s)), quarter);
        __m128 x2 = _mm_add_ps(_mm_add_ps(_mm_mul_ps(r, r), _mm_mul_ps(gg, gg)), _mm_mul_ps(b, b));
        acc = _mm_add_ps(acc, _mm_mul_ps(_mm_add_ps(x2, bracket), _mm_loadu_ps(B->w + g)));
        sg[g >> 2] = s;
        if (g < 12 && hsum(acc) >= limit)
            return hsum(acc);
    }
    /* the sixteen selectors in one store (a later 16-byte load of them is then forwarded) */
    _mm_storeu_si128((__m128i *)sel, _mm_packus_epi16(_mm_packs_epi32(sg[0], sg[1]),
                                                      _mm_packs_epi32(sg[2], sg[3])));
    return hsum(acc);
}
#else
static float select_eval(const blk *B, uint16_t c0, uint16_t c1, uint8_t *sel, float limit)
{
    (void)limit;
    float pal[3][4];
    palette_f(c0, c1, c0 > c1, pal);
    /* key = distance << 2 | selector: one integer minimum picks both (distances are
     * integers below 2^18, the unused 4th entry of 3-colour mode sits far away) */
    int key[16];
    for (int i = 0; i < 16; i++) {
        int m = 0x7fffffff;
        for (int j = 0; j < 4; j++) {
            float dr = B->r[i] - pal[0][j], dg = B->g[i] - pal[1][j], db = B->b[i] - pal[2][j];
            int k = ((int)(dr * dr + dg * dg + db * db) << 2) | j;
            m = k < m ? k : m;
        }
        key[i] = m;
    }
    float err = 0;
    for (int i = 0; i < 16; i++) {
        err += (float)(key[i] >> 2) * B->w[i];
        sel[i] = (uint8_t)(key[i] & 3);
    }
    return err;
}
#endif

#if ST_BC1_AVX2
/* The lane sums of 16 texels in the SSE2 order (lane l: ((t_l + t_4+l) + t_8+l) + t_12+l,
 * then across lanes), so that both paths return the same float for any weights. */
__attribute__((target("avx2"))) static inline float sum16_avx2(__m256 a, __m256 b)
{
    __m128 t = _mm_add_ps(_mm256_castps256_ps128(a), _mm256_extractf128_ps(a, 1));
    t = _mm_add_ps(t, _mm256_castps256_ps128(b));
    t = _mm_add_ps(t, _mm256_extractf128_ps(b, 1));
    return hsum(t);
}

/* select_sse eight texels at a time (AVX2 CPUs, chosen at run time): the same keys, so the
 * same selectors and error. */
__attribute__((target("avx2"))) static float select_avx2(const blk *B, uint16_t c0,
                                                          uint16_t c1, uint8_t *sel,
                                                          float limit)
{
    float kv[4][4];
    palette_keys(c0, c1, kv);
    __m256 pr[4], pg[4], pb[4], pk[4];
    for (int j = 0; j < 4; j++) {
        pr[j] = _mm256_broadcast_ss(&kv[0][j]);
        pg[j] = _mm256_broadcast_ss(&kv[1][j]);
        pb[j] = _mm256_broadcast_ss(&kv[2][j]);
        pk[j] = _mm256_broadcast_ss(&kv[3][j]);
    }
    const __m256i three = _mm256_set1_epi32(3);
    const __m256 quarter = _mm256_set1_ps(0.25f);
    __m256 part[2];
    __m128i sv[2];
    for (int h = 0; h < 2; h++) {
        int g = 8 * h;
        __m256 r = _mm256_loadu_ps(B->r + g), gg = _mm256_loadu_ps(B->g + g),
               b = _mm256_loadu_ps(B->b + g);
        __m256 key = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(r, pr[0]), _mm256_mul_ps(gg, pg[0])),
                                   _mm256_add_ps(_mm256_mul_ps(b, pb[0]), pk[0]));
        for (int j = 1; j < 4; j++) {
            __m256 k = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(r, pr[j]), _mm256_mul_ps(gg, pg[j])),
                                     _mm256_add_ps(_mm256_mul_ps(b, pb[j]), pk[j]));
            key = _mm256_min_ps(key, k);
        }
        __m256i s = _mm256_and_si256(_mm256_cvtps_epi32(key), three);
        __m256 bracket = _mm256_mul_ps(_mm256_sub_ps(key, _mm256_cvtepi32_ps(s)), quarter);
        __m256 x2 = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(r, r), _mm256_mul_ps(gg, gg)),
                                  _mm256_mul_ps(b, b));
        part[h] = _mm256_mul_ps(_mm256_add_ps(x2, bracket), _mm256_loadu_ps(B->w + g));
        sv[h] = _mm_packs_epi32(_mm256_castsi256_si128(s), _mm256_extracti128_si256(s, 1));
    }
    /* the sixteen selectors in one store (a later 16-byte load of them is then forwarded) */
    _mm_storeu_si128((__m128i *)sel, _mm_packus_epi16(sv[0], sv[1]));
    (void)limit; /* no early exit: the horizontal sum costs more than it saves here */
    return sum16_avx2(part[0], part[1]);
}
#endif

#ifdef __SSE2__
static float select_eval(const blk *B, uint16_t c0, uint16_t c1, uint8_t *sel, float limit)
{
#if ST_BC1_AVX2
    if (__builtin_cpu_supports("avx2"))
        return select_avx2(B, c0, c1, sel, limit);
#endif
    return select_sse(B, c0, c1, sel, limit);
}
#endif

/* Evaluates a 4-colour candidate given as a possibly unordered pair: orders it, handles
 * c0 == c1 (which would decode in 3-colour mode: all selectors 0 then). */
static void try4(const blk *B, uint16_t a, uint16_t b, cand *best)
{
    cand c;
    if (a == b) {
        uint8_t e[3];
        st_bc1_565_to_rgb8(a, e);
        float err = 0;
        for (int i = 0; i < 16; i++) {
            float dr = B->r[i] - e[0], dg = B->g[i] - e[1], db = B->b[i] - e[2];
            err += (dr * dr + dg * dg + db * db) * B->w[i];
        }
        if (err < best->err) {
            best->c0 = best->c1 = a;
            memset(best->sel, 0, sizeof best->sel);
            best->err = err;
        }
        return;
    }
    c.c0 = a > b ? a : b;
    c.c1 = a > b ? b : a;
    if (best->err < 1e30f && c.c0 == best->c0 && c.c1 == best->c1)
        return; /* the best itself: nothing to gain */
    c.err = select_eval(B, c.c0, c.c1, c.sel, best->err);
    if (c.err < best->err)
        *best = c;
}

/* 3-colour candidate (selectors 0..2): orders the pair so that c0 <= c1. */
static void try3(const blk *B, uint16_t a, uint16_t b, cand *best)
{
    cand c;
    c.c0 = a < b ? a : b;
    c.c1 = a < b ? b : a;
    if (best->err < 1e30f && c.c0 == best->c0 && c.c1 == best->c1)
        return; /* the best itself: nothing to gain */
    c.err = select_eval(B, c.c0, c.c1, c.sel, best->err);
    if (c.err < best->err)
        *best = c;
}

/* Least-squares endpoints for per-texel weights t of endpoint 1 (texel ~ (1-t) e0 + t e1),
 * given the block's sums of w and w x (tot, from the axis): with S = sum w t,
 * S2 = sum w t^2 and X1 = sum w t x, aa = W - 2 S + S2, ab = S - S2, bb = S2,
 * ax = sum w x - X1, bx = X1. Returns 0 when the system is singular (all texels on one
 * weight). */
static int ls_t(const blk *B, const float tv[16], const float tot[4], float e0[3],
                  float e1[3])
{
#ifdef __SSE2__
    __m128 z = _mm_setzero_ps(), st = z, stt = z, sr = z, sg = z, sb = z;
    for (int i = 0; i < 16; i += 4) {
        __m128 t = _mm_loadu_ps(tv + i);
        __m128 wt = _mm_mul_ps(_mm_loadu_ps(B->w + i), t);
        st = _mm_add_ps(st, wt);
        stt = _mm_add_ps(stt, _mm_mul_ps(wt, t));
        sr = _mm_add_ps(sr, _mm_mul_ps(wt, _mm_loadu_ps(B->r + i)));
        sg = _mm_add_ps(sg, _mm_mul_ps(wt, _mm_loadu_ps(B->g + i)));
        sb = _mm_add_ps(sb, _mm_mul_ps(wt, _mm_loadu_ps(B->b + i)));
    }
    _MM_TRANSPOSE4_PS(st, stt, sr, sg);
    float h[4];
    _mm_storeu_ps(h, _mm_add_ps(_mm_add_ps(st, stt), _mm_add_ps(sr, sg)));
    float S = h[0], S2 = h[1], bx[3] = {h[2], h[3], hsum(sb)};
#else
    float S = 0, S2 = 0, bx[3] = {0, 0, 0};
    for (int i = 0; i < 16; i++) {
        float wt = B->w[i] * tv[i];
        S += wt;
        S2 += wt * tv[i];
        bx[0] += wt * B->r[i];
        bx[1] += wt * B->g[i];
        bx[2] += wt * B->b[i];
    }
#endif
    float aa = tot[0] - 2 * S + S2, ab = S - S2, bb = S2;
    float det = aa * bb - ab * ab;
    if (!(det > 1e-5f * aa * bb))
        return 0;
    float inv = 1.0f / det;
    for (int k = 0; k < 3; k++) {
        float ax = tot[k + 1] - bx[k];
        float v0 = (bb * ax - ab * bx[k]) * inv, v1 = (aa * bx[k] - ab * ax) * inv;
        e0[k] = v0 < 0 ? 0 : v0 > 255 ? 255 : v0;
        e1[k] = v1 < 0 ? 0 : v1 > 255 ? 255 : v1;
    }
    return 1;
}

/* Least-squares endpoints for the selectors `sel` (4-colour weights when four, else
 * 3-colour). Returns 0 when the system is singular (all texels on one weight). */
static int ls_endpoints(const blk *B, const uint8_t *sel, int four, const float tot[4],
                        float e0[3], float e1[3])
{
    /* weight of endpoint 1 per selector */
    static const float t4[4] = {0.0f, 1.0f, 1.0f / 3.0f, 2.0f / 3.0f}, t3[4] = {0.0f, 1.0f, 0.5f, 0.0f};
    const float *tw = four ? t4 : t3;
    float tv[16];
    for (int i = 0; i < 16; i++)
        tv[i] = tw[sel[i]];
    return ls_t(B, tv, tot, e0, e1);
}

/* With the selectors fixed the error separates by channel, and with per-selector sums it
 * costs O(4) to evaluate one endpoint pair exactly (truncating palette included). For each
 * channel, tries every (q0, q1) within +-radius of the least-squares values e0, e1 (8-bit
 * scale) and keeps the best; returns the pair as 565 (unordered: the caller orders it). */
static void refine_exact(const blk *B, const uint8_t *sel, int four, const float e0[3],
                         const float e1[3], int radius, uint16_t *c0, uint16_t *c1)
{
    float cnt[4] = {0, 0, 0, 0}, s1[3][4];
    memset(s1, 0, sizeof s1);
    for (int i = 0; i < 16; i++) {
        int j = sel[i];
        cnt[j] += B->w[i];
        s1[0][j] += B->r[i] * B->w[i];
        s1[1][j] += B->g[i] * B->w[i];
        s1[2][j] += B->b[i] * B->w[i];
    }
    int q[2][3];
    for (int k = 0; k < 3; k++) {
        int bits = k == 1 ? 6 : 5, mx = (1 << bits) - 1;
        float sc = (float)mx / 255.0f;
        int a0 = clampi((int)(e0[k] * sc + 0.5f), 0, mx), b0 = clampi((int)(e1[k] * sc + 0.5f), 0, mx);
        float best = 3e30f;
        int ba = a0, bb = b0;
        for (int qa = a0 - radius; qa <= a0 + radius; qa++) {
            if (qa < 0 || qa > mx)
                continue;
            int ea = bits == 5 ? (qa << 3) | (qa >> 2) : (qa << 2) | (qa >> 4);
            for (int qb = b0 - radius; qb <= b0 + radius; qb++) {
                if (qb < 0 || qb > mx)
                    continue;
                int eb = bits == 5 ? (qb << 3) | (qb >> 2) : (qb << 2) | (qb >> 4);
                float p[4];
                p[0] = (float)ea;
                p[1] = (float)eb;
                if (four) {
                    p[2] = (float)((2 * ea + eb) / 3);
                    p[3] = (float)((ea + 2 * eb) / 3);
                } else {
                    p[2] = (float)((ea + eb) / 2);
                    p[3] = 0;
                }
                float err = 0;
                for (int j = 0; j < 4; j++)
                    err += p[j] * (cnt[j] * p[j] - 2.0f * s1[k][j]);
                if (err < best) {
                    best = err;
                    ba = qa;
                    bb = qb;
                }
            }
        }
        q[0][k] = ba;
        q[1][k] = bb;
    }
    *c0 = pack565(q[0][0], q[0][1], q[0][2]);
    *c1 = pack565(q[1][0], q[1][1], q[1][2]);
}

/* Principal axis endpoints: e0 at the largest projection, e1 at the smallest. inset: fraction
 * of the range moved inwards at both ends. */
typedef struct axis {
    float m[3], v[3], len2, lo, hi;
    float var;            /* weighted sum of squared distances to the mean (trace of C) */
    float tot[4];         /* sums of w, w r, w g, w b */
} axis;

static void axis_compute(const blk *B, axis *A)
{
#ifdef __SSE2__
    float m[3], c[6]; /* c: rr rg rb gg gb bb */
    {
        /* raw weighted moments (independent of each other: no mean first), then
         * c = S_xy - S_x S_y / S_w; four horizontal sums at a time by a transpose */
        __m128 z = _mm_setzero_ps();
        __m128 sr = z, sg = z, sb = z, sw = z, rr = z, rg = z, rb = z, gg = z, gb = z, bb = z;
        for (int i = 0; i < 16; i += 4) {
            __m128 w = _mm_loadu_ps(B->w + i);
            __m128 r = _mm_loadu_ps(B->r + i), g = _mm_loadu_ps(B->g + i),
                   b = _mm_loadu_ps(B->b + i);
            __m128 wr = _mm_mul_ps(w, r), wg = _mm_mul_ps(w, g), wb = _mm_mul_ps(w, b);
            sw = _mm_add_ps(sw, w);
            sr = _mm_add_ps(sr, wr);
            sg = _mm_add_ps(sg, wg);
            sb = _mm_add_ps(sb, wb);
            rr = _mm_add_ps(rr, _mm_mul_ps(wr, r));
            rg = _mm_add_ps(rg, _mm_mul_ps(wr, g));
            rb = _mm_add_ps(rb, _mm_mul_ps(wr, b));
            gg = _mm_add_ps(gg, _mm_mul_ps(wg, g));
            gb = _mm_add_ps(gb, _mm_mul_ps(wg, b));
            bb = _mm_add_ps(bb, _mm_mul_ps(wb, b));
        }
        _MM_TRANSPOSE4_PS(sw, sr, sg, sb);
        __m128 s1 = _mm_add_ps(_mm_add_ps(sw, sr), _mm_add_ps(sg, sb)); /* w r g b */
        _MM_TRANSPOSE4_PS(rr, rg, rb, gg);
        __m128 s2 = _mm_add_ps(_mm_add_ps(rr, rg), _mm_add_ps(rb, gg)); /* rr rg rb gg */
        float f1[4], f2[4];
        _mm_storeu_ps(f1, s1);
        _mm_storeu_ps(f2, s2);
        float sgb = hsum(gb), sbb = hsum(bb);
        float wsum = f1[0];
        for (int k = 0; k < 4; k++)
            A->tot[k] = f1[k];
        float inv = 1.0f / (wsum > 0 ? wsum : 1.0f);
        m[0] = f1[1] * inv;
        m[1] = f1[2] * inv;
        m[2] = f1[3] * inv;
        c[0] = f2[0] - f1[1] * m[0];
        c[1] = f2[1] - f1[1] * m[1];
        c[2] = f2[2] - f1[1] * m[2];
        c[3] = f2[3] - f1[2] * m[1];
        c[4] = sgb - f1[2] * m[2];
        c[5] = sbb - f1[3] * m[2];
    }
#else
    float m[3] = {0, 0, 0};
    for (int i = 0; i < 16; i++) {
        m[0] += B->r[i] * B->w[i];
        m[1] += B->g[i] * B->w[i];
        m[2] += B->b[i] * B->w[i];
    }
    float wsum = 0;
    for (int i = 0; i < 16; i++)
        wsum += B->w[i];
    A->tot[0] = wsum;
    A->tot[1] = m[0];
    A->tot[2] = m[1];
    A->tot[3] = m[2];
    float inv = 1.0f / (wsum > 0 ? wsum : 1.0f);
    m[0] *= inv;
    m[1] *= inv;
    m[2] *= inv;
    float c[6] = {0, 0, 0, 0, 0, 0}; /* rr rg rb gg gb bb */
    for (int i = 0; i < 16; i++) {
        float r = (B->r[i] - m[0]) * B->w[i], g = (B->g[i] - m[1]) * B->w[i],
              b = (B->b[i] - m[2]) * B->w[i];
        c[0] += r * r;
        c[1] += r * g;
        c[2] += r * b;
        c[3] += g * g;
        c[4] += g * b;
        c[5] += b * b;
    }
#endif
    /* v = C^4 applied to the unit vector of C's largest diagonal, C scaled by 1/trace (its
     * eigenvalues then lie in 0..1: no overflow, and the dominant one is >= 1/3); C^2 and
     * C^4 by squaring, which is shorter than four dependent power iterations. */
    float tr = c[0] + c[3] + c[5];
    float v[3] = {0, 0, 0};
    if (tr > 1e-12f) {
        /* a power of two near 1 / trace instead of a division on every block's critical
         * path: the exponent of tr negated (the eigenvalues then lie in 0..2) */
        uint32_t tb;
        memcpy(&tb, &tr, 4);
        uint32_t ib = (uint32_t)(254u - (tb >> 23)) << 23;
        float it;
        memcpy(&it, &ib, 4);
        float q[6];
        for (int k = 0; k < 6; k++)
            q[k] = c[k] * it;
        for (int sq = 0; sq < 2; sq++) { /* q = q * q (symmetric) */
            float n0 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2];
            float n1 = q[0] * q[1] + q[1] * q[3] + q[2] * q[4];
            float n2 = q[0] * q[2] + q[1] * q[4] + q[2] * q[5];
            float n3 = q[1] * q[1] + q[3] * q[3] + q[4] * q[4];
            float n4 = q[1] * q[2] + q[3] * q[4] + q[4] * q[5];
            float n5 = q[2] * q[2] + q[4] * q[4] + q[5] * q[5];
            q[0] = n0; q[1] = n1; q[2] = n2; q[3] = n3; q[4] = n4; q[5] = n5;
        }
        /* the row (= column) of C^4 through the largest diagonal of C, times C once more */
        float r0, r1, r2;
        if (c[0] >= c[3] && c[0] >= c[5]) {
            r0 = q[0]; r1 = q[1]; r2 = q[2];
        } else if (c[3] >= c[5]) {
            r0 = q[1]; r1 = q[3]; r2 = q[4];
        } else {
            r0 = q[2]; r1 = q[4]; r2 = q[5];
        }
        v[0] = (c[0] * r0 + c[1] * r1 + c[2] * r2) * it;
        v[1] = (c[1] * r0 + c[3] * r1 + c[4] * r2) * it;
        v[2] = (c[2] * r0 + c[4] * r1 + c[5] * r2) * it;
    }
    float len2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    if (len2 < 1e-12f) {
        v[0] = v[1] = v[2] = 1;
        len2 = 3;
    }
    float lo = 1e30f, hi = -1e30f;
#ifdef __SSE2__
    {
        __m128 vr = _mm_set1_ps(v[0]), vg = _mm_set1_ps(v[1]), vb = _mm_set1_ps(v[2]);
        __m128 mr = _mm_set1_ps(m[0]), mg = _mm_set1_ps(m[1]), mb = _mm_set1_ps(m[2]);
        __m128 vlo = _mm_set1_ps(1e30f), vhi = _mm_set1_ps(-1e30f), zero = _mm_setzero_ps();
        for (int i = 0; i < 16; i += 4) { /* texels of weight 0 do not widen the range */
            __m128 p = _mm_add_ps(
                _mm_add_ps(_mm_mul_ps(_mm_sub_ps(_mm_loadu_ps(B->r + i), mr), vr),
                           _mm_mul_ps(_mm_sub_ps(_mm_loadu_ps(B->g + i), mg), vg)),
                _mm_mul_ps(_mm_sub_ps(_mm_loadu_ps(B->b + i), mb), vb));
            __m128 in = _mm_cmpgt_ps(_mm_loadu_ps(B->w + i), zero);
            vlo = _mm_min_ps(vlo, _mm_or_ps(_mm_and_ps(in, p), _mm_andnot_ps(in, vlo)));
            vhi = _mm_max_ps(vhi, _mm_or_ps(_mm_and_ps(in, p), _mm_andnot_ps(in, vhi)));
        }
        vlo = _mm_min_ps(vlo, _mm_movehl_ps(vlo, vlo));
        vlo = _mm_min_ss(vlo, _mm_shuffle_ps(vlo, vlo, 1));
        vhi = _mm_max_ps(vhi, _mm_movehl_ps(vhi, vhi));
        vhi = _mm_max_ss(vhi, _mm_shuffle_ps(vhi, vhi, 1));
        lo = _mm_cvtss_f32(vlo);
        hi = _mm_cvtss_f32(vhi);
    }
#else
    for (int i = 0; i < 16; i++) { /* texels of weight 0 do not widen the range */
        float p = (B->r[i] - m[0]) * v[0] + (B->g[i] - m[1]) * v[1] + (B->b[i] - m[2]) * v[2];
        if (B->w[i] > 0) {
            lo = p < lo ? p : lo;
            hi = p > hi ? p : hi;
        }
    }
#endif
    if (lo > hi)
        lo = hi = 0;
    for (int k = 0; k < 3; k++) {
        A->m[k] = m[k];
        A->v[k] = v[k];
    }
    A->len2 = len2;
    A->var = tr;
    A->lo = lo;
    A->hi = hi;
}

static void axis_endpoints(const axis *A, float inset, float e0[3], float e1[3])
{
    float d = (A->hi - A->lo) * inset, il = 1.0f / A->len2;
    float lo = (A->lo + d) * il, hi = (A->hi - d) * il;
    for (int k = 0; k < 3; k++) {
        float a = A->m[k] + A->v[k] * hi, b = A->m[k] + A->v[k] * lo;
        e0[k] = a < 0 ? 0 : a > 255 ? 255 : a;
        e1[k] = b < 0 ? 0 : b > 255 ? 255 : b;
    }
}

/* The neighbourhood search moves one channel of one endpoint by +-1, so the squared distance
 * of texel i to palette entry j changes only in that channel's term. For the current pair,
 * other[k][j][i] = the distance without channel k; a move in channel k then costs one
 * subtraction, multiplication, addition and minimum per entry and texel:
 * distance = other + (x_k - p_jk)^2. Every value is an integer below 2^18 (exact in float),
 * so the minimum is the exact palette distance the selection would find. */
typedef struct nbase {
    float other[3][4][16];
} nbase;

static void nbase_fill(const blk *B, uint16_t c0, uint16_t c1, nbase *N)
{
    float pal[3][4];
    palette_f(c0, c1, c0 > c1, pal);
    for (int j = 0; j < 4; j++) {
#ifdef __SSE2__
        __m128 pr = _mm_set1_ps(pal[0][j]), pg = _mm_set1_ps(pal[1][j]),
               pb = _mm_set1_ps(pal[2][j]);
        for (int g = 0; g < 16; g += 4) {
            __m128 dr = _mm_sub_ps(_mm_loadu_ps(B->r + g), pr);
            __m128 dg = _mm_sub_ps(_mm_loadu_ps(B->g + g), pg);
            __m128 db = _mm_sub_ps(_mm_loadu_ps(B->b + g), pb);
            dr = _mm_mul_ps(dr, dr);
            dg = _mm_mul_ps(dg, dg);
            db = _mm_mul_ps(db, db);
            _mm_storeu_ps(N->other[0][j] + g, _mm_add_ps(dg, db));
            _mm_storeu_ps(N->other[1][j] + g, _mm_add_ps(dr, db));
            _mm_storeu_ps(N->other[2][j] + g, _mm_add_ps(dr, dg));
        }
#else
        for (int i = 0; i < 16; i++) {
            float dr = B->r[i] - pal[0][j], dg = B->g[i] - pal[1][j], db = B->b[i] - pal[2][j];
            N->other[0][j][i] = dg * dg + db * db;
            N->other[1][j][i] = dr * dr + db * db;
            N->other[2][j][i] = dr * dr + dg * dg;
        }
#endif
    }
}

#if ST_BC1_AVX2
/* nbase_fill eight texels at a time (the same values). */
__attribute__((target("avx2"))) static void nbase_fill_avx2(const blk *B, uint16_t c0,
                                                             uint16_t c1, nbase *N)
{
    float pal[3][4];
    palette_f(c0, c1, c0 > c1, pal);
    for (int h = 0; h < 16; h += 8) {
        __m256 r = _mm256_loadu_ps(B->r + h), g = _mm256_loadu_ps(B->g + h),
               b = _mm256_loadu_ps(B->b + h);
        for (int j = 0; j < 4; j++) {
            __m256 dr = _mm256_sub_ps(r, _mm256_set1_ps(pal[0][j]));
            __m256 dg = _mm256_sub_ps(g, _mm256_set1_ps(pal[1][j]));
            __m256 db = _mm256_sub_ps(b, _mm256_set1_ps(pal[2][j]));
            dr = _mm256_mul_ps(dr, dr);
            dg = _mm256_mul_ps(dg, dg);
            db = _mm256_mul_ps(db, db);
            _mm256_storeu_ps(N->other[0][j] + h, _mm256_add_ps(dg, db));
            _mm256_storeu_ps(N->other[1][j] + h, _mm256_add_ps(dr, db));
            _mm256_storeu_ps(N->other[2][j] + h, _mm256_add_ps(dr, dg));
        }
    }
}
#endif

/* The errors of four pairs whose palettes differ from the base's only in channel k, where
 * move m has the entries p2[j][m] (column layout: p2[j] holds entry j of the four moves).
 * Moves 0 and 1 change endpoint 0 only (entry 1 is the same for both), moves 2 and
 * 3 endpoint 1 only (entry 0 the same): those terms are computed once. Sums in the order of
 * select_sse (lane l: texels l, 4+l, 8+l, 12+l, then (l0 + l2) + (l1 + l3)), the four moves
 * reduced together by a transpose. `three`: 3-colour palettes, whose entry 3 is never chosen
 * and is left out; `unit`: every weight is 1 (the multiplication is left out). The bodies are
 * inlined with constant m, three and unit. */
#ifdef __SSE2__
__attribute__((always_inline)) static inline __m128
move_key_sse(__m128 x2, __m128 o0, __m128 o1, __m128 o2, __m128 o3, __m128 keep0, __m128 keep1,
             const float p2[4][4], int m, int three)
{
    __m128 tm = _mm_sub_ps(x2, _mm_set1_ps(m < 2 ? p2[0][m] : p2[1][m]));
    __m128 own = _mm_add_ps(m < 2 ? o0 : o1, _mm_mul_ps(tm, tm));
    __m128 t2 = _mm_sub_ps(x2, _mm_set1_ps(p2[2][m]));
    __m128 key = _mm_min_ps(m < 2 ? _mm_min_ps(own, keep1) : _mm_min_ps(keep0, own),
                            _mm_add_ps(o2, _mm_mul_ps(t2, t2)));
    if (!three) {
        __m128 t3 = _mm_sub_ps(x2, _mm_set1_ps(p2[3][m]));
        key = _mm_min_ps(key, _mm_add_ps(o3, _mm_mul_ps(t3, t3)));
    }
    return key;
}

__attribute__((always_inline)) static inline void
moves_body_sse(const blk *B, const nbase *N, int k, const float p2[4][4], int three, int unit,
               float err[4])
{
    const float *x = k == 0 ? B->r : k == 1 ? B->g : B->b;
    __m128 a0 = _mm_setzero_ps(), a1 = a0, a2 = a0, a3 = a0;
    for (int g = 0; g < 16; g += 4) {
        __m128 x2 = _mm_loadu_ps(x + g), w = _mm_loadu_ps(B->w + g);
        __m128 o0 = _mm_loadu_ps(N->other[k][0] + g), o1 = _mm_loadu_ps(N->other[k][1] + g),
               o2 = _mm_loadu_ps(N->other[k][2] + g), o3 = _mm_loadu_ps(N->other[k][3] + g);
        __m128 t = _mm_sub_ps(x2, _mm_set1_ps(p2[1][0]));
        __m128 keep1 = _mm_add_ps(o1, _mm_mul_ps(t, t)); /* entry 1 of moves 0, 1 */
        t = _mm_sub_ps(x2, _mm_set1_ps(p2[0][2]));
        __m128 keep0 = _mm_add_ps(o0, _mm_mul_ps(t, t)); /* entry 0 of moves 2, 3 */
        __m128 k0 = move_key_sse(x2, o0, o1, o2, o3, keep0, keep1, p2, 0, three);
        __m128 k1 = move_key_sse(x2, o0, o1, o2, o3, keep0, keep1, p2, 1, three);
        __m128 k2 = move_key_sse(x2, o0, o1, o2, o3, keep0, keep1, p2, 2, three);
        __m128 k3 = move_key_sse(x2, o0, o1, o2, o3, keep0, keep1, p2, 3, three);
        a0 = _mm_add_ps(a0, unit ? k0 : _mm_mul_ps(k0, w));
        a1 = _mm_add_ps(a1, unit ? k1 : _mm_mul_ps(k1, w));
        a2 = _mm_add_ps(a2, unit ? k2 : _mm_mul_ps(k2, w));
        a3 = _mm_add_ps(a3, unit ? k3 : _mm_mul_ps(k3, w));
    }
    _MM_TRANSPOSE4_PS(a0, a1, a2, a3);
    _mm_storeu_ps(err, _mm_add_ps(_mm_add_ps(a0, a2), _mm_add_ps(a1, a3)));
}
#endif

static void moves_eval(const blk *B, const nbase *N, int k, const float p2[4][4], int three,
                       float err[4])
{
#ifdef __SSE2__
    if (three) {
        if (B->unit)
            moves_body_sse(B, N, k, p2, 1, 1, err);
        else
            moves_body_sse(B, N, k, p2, 1, 0, err);
    } else {
        if (B->unit)
            moves_body_sse(B, N, k, p2, 0, 1, err);
        else
            moves_body_sse(B, N, k, p2, 0, 0, err);
    }
#else
    const float *x = k == 0 ? B->r : k == 1 ? B->g : B->b;
    for (int m = 0; m < 4; m++) {
        float e = 0;
        for (int i = 0; i < 16; i++) {
            float best = 3e30f;
            for (int j = 0; j < 4 - three; j++) {
                float t = x[i] - p2[j][m];
                float v = N->other[k][j][i] + t * t;
                best = v < best ? v : best;
            }
            e += best * B->w[i];
        }
        err[m] = e;
    }
#endif
}

#if ST_BC1_AVX2
/* moves_eval eight texels at a time: the same keys and the same sums. */
__attribute__((target("avx2"), always_inline)) static inline __m256
move_key_avx2(__m256 x2, __m256 o0, __m256 o1, __m256 o2, __m256 o3, __m256 keep0, __m256 keep1,
              const float p2[4][4], int m, int three)
{
    __m256 tm = _mm256_sub_ps(x2, _mm256_broadcast_ss(m < 2 ? &p2[0][m] : &p2[1][m]));
    __m256 own = _mm256_add_ps(m < 2 ? o0 : o1, _mm256_mul_ps(tm, tm));
    __m256 t2 = _mm256_sub_ps(x2, _mm256_broadcast_ss(&p2[2][m]));
    __m256 key = _mm256_min_ps(m < 2 ? _mm256_min_ps(own, keep1) : _mm256_min_ps(keep0, own),
                               _mm256_add_ps(o2, _mm256_mul_ps(t2, t2)));
    if (!three) {
        __m256 t3 = _mm256_sub_ps(x2, _mm256_broadcast_ss(&p2[3][m]));
        key = _mm256_min_ps(key, _mm256_add_ps(o3, _mm256_mul_ps(t3, t3)));
    }
    return key;
}

__attribute__((target("avx2"), always_inline)) static inline __m128
moves_half_avx2(__m256 a)
{
    return _mm_add_ps(_mm256_castps256_ps128(a), _mm256_extractf128_ps(a, 1));
}

__attribute__((target("avx2"), always_inline)) static inline void
moves_body_avx2(const blk *B, const nbase *N, int k, const float p2[4][4], int three, int unit,
                float err[4])
{
    const float *x = k == 0 ? B->r : k == 1 ? B->g : B->b;
    __m128 s[4];
    for (int h = 0; h < 2; h++) {
        int g = 8 * h;
        __m256 x2 = _mm256_loadu_ps(x + g), w = _mm256_loadu_ps(B->w + g);
        __m256 o0 = _mm256_loadu_ps(N->other[k][0] + g), o1 = _mm256_loadu_ps(N->other[k][1] + g),
               o2 = _mm256_loadu_ps(N->other[k][2] + g), o3 = _mm256_loadu_ps(N->other[k][3] + g);
        __m256 t = _mm256_sub_ps(x2, _mm256_broadcast_ss(&p2[1][0]));
        __m256 keep1 = _mm256_add_ps(o1, _mm256_mul_ps(t, t));
        t = _mm256_sub_ps(x2, _mm256_broadcast_ss(&p2[0][2]));
        __m256 keep0 = _mm256_add_ps(o0, _mm256_mul_ps(t, t));
        __m256 k0 = move_key_avx2(x2, o0, o1, o2, o3, keep0, keep1, p2, 0, three);
        __m256 k1 = move_key_avx2(x2, o0, o1, o2, o3, keep0, keep1, p2, 1, three);
        __m256 k2 = move_key_avx2(x2, o0, o1, o2, o3, keep0, keep1, p2, 2, three);
        __m256 k3 = move_key_avx2(x2, o0, o1, o2, o3, keep0, keep1, p2, 3, three);
        if (!unit) {
            k0 = _mm256_mul_ps(k0, w);
            k1 = _mm256_mul_ps(k1, w);
            k2 = _mm256_mul_ps(k2, w);
            k3 = _mm256_mul_ps(k3, w);
        }
        /* lane l of a half: texels g + l and g + 4 + l, added to the first half's in the
         * order of select_sse: ((t_l + t_4+l) + t_8+l) + t_12+l */
        if (h == 0) {
            s[0] = moves_half_avx2(k0);
            s[1] = moves_half_avx2(k1);
            s[2] = moves_half_avx2(k2);
            s[3] = moves_half_avx2(k3);
        } else {
            s[0] = _mm_add_ps(_mm_add_ps(s[0], _mm256_castps256_ps128(k0)), _mm256_extractf128_ps(k0, 1));
            s[1] = _mm_add_ps(_mm_add_ps(s[1], _mm256_castps256_ps128(k1)), _mm256_extractf128_ps(k1, 1));
            s[2] = _mm_add_ps(_mm_add_ps(s[2], _mm256_castps256_ps128(k2)), _mm256_extractf128_ps(k2, 1));
            s[3] = _mm_add_ps(_mm_add_ps(s[3], _mm256_castps256_ps128(k3)), _mm256_extractf128_ps(k3, 1));
        }
    }
    _MM_TRANSPOSE4_PS(s[0], s[1], s[2], s[3]);
    _mm_storeu_ps(err, _mm_add_ps(_mm_add_ps(s[0], s[2]), _mm_add_ps(s[1], s[3])));
}

__attribute__((target("avx2"))) static void moves_eval_avx2(const blk *B, const nbase *N, int k,
                                                             const float p2[4][4], int three,
                                                             float err[4])
{
    if (three) {
        if (B->unit)
            moves_body_avx2(B, N, k, p2, 1, 1, err);
        else
            moves_body_avx2(B, N, k, p2, 1, 0, err);
    } else {
        if (B->unit)
            moves_body_avx2(B, N, k, p2, 0, 1, err);
        else
            moves_body_avx2(B, N, k, p2, 0, 0, err);
    }
}
#endif

/* The palettes of channel k for the four moves m (0: q0 - 1, 1: q0 + 1, 2: q1 - 1,
 * 3: q1 + 1; out-of-range values give garbage that the caller ignores), column layout. */
static void moves_palette(int q0, int q1, int bits, int four, float p2[4][4])
{
#ifdef __SSE2__
    __m128i qa = _mm_add_epi32(_mm_set1_epi32(q0), _mm_set_epi32(0, 0, 1, -1));
    __m128i qb = _mm_add_epi32(_mm_set1_epi32(q1), _mm_set_epi32(1, -1, 0, 0));
    __m128i ea, eb;
    if (bits == 5) {
        ea = _mm_or_si128(_mm_slli_epi32(qa, 3), _mm_srai_epi32(qa, 2));
        eb = _mm_or_si128(_mm_slli_epi32(qb, 3), _mm_srai_epi32(qb, 2));
    } else {
        ea = _mm_or_si128(_mm_slli_epi32(qa, 2), _mm_srai_epi32(qa, 4));
        eb = _mm_or_si128(_mm_slli_epi32(qb, 2), _mm_srai_epi32(qb, 4));
    }
    __m128 fa = _mm_cvtepi32_ps(ea), fb = _mm_cvtepi32_ps(eb);
    __m128 f2, f3;
    if (four) {
        /* (2a + b) / 3 truncated: the product by the float nearest 1/3 (slightly above) stays
         * within 1e-5 of the quotient for these small integers, so truncation is exact */
        const __m128 third = _mm_set1_ps(1.0f / 3.0f);
        f2 = _mm_cvtepi32_ps(_mm_cvttps_epi32(_mm_mul_ps(_mm_add_ps(_mm_add_ps(fa, fa), fb), third)));
        f3 = _mm_cvtepi32_ps(_mm_cvttps_epi32(_mm_mul_ps(_mm_add_ps(_mm_add_ps(fb, fb), fa), third)));
    } else {
        f2 = _mm_cvtepi32_ps(_mm_srai_epi32(_mm_add_epi32(ea, eb), 1));
        f3 = _mm_set1_ps(2000.0f); /* not evaluated in 3-colour mode */
    }
    _mm_storeu_ps(p2[0], fa);
    _mm_storeu_ps(p2[1], fb);
    _mm_storeu_ps(p2[2], f2);
    _mm_storeu_ps(p2[3], f3);
#else
    int qa[4] = {q0 - 1, q0 + 1, q0, q0}, qb[4] = {q1, q1, q1 - 1, q1 + 1};
    for (int m = 0; m < 4; m++) {
        int a = qa[m] < 0 ? 0 : qa[m], b = qb[m] < 0 ? 0 : qb[m];
        int ea = bits == 5 ? (a << 3) | (a >> 2) : (a << 2) | (a >> 4);
        int eb = bits == 5 ? (b << 3) | (b >> 2) : (b << 2) | (b >> 4);
        p2[0][m] = (float)ea;
        p2[1][m] = (float)eb;
        p2[2][m] = (float)(four ? (2 * ea + eb) / 3 : (ea + eb) / 2);
        p2[3][m] = four ? (float)((ea + 2 * eb) / 3) : 2000.0f;
    }
#endif
}

/* Steepest-descent +-1 search over the six 565 components of the best pair, in its own mode:
 * each round measures all twelve moves against the current pair, takes the best one if it
 * lowers the error, and stops when none does (at most `rounds` rounds). The errors of
 * moves_eval are those select_eval returns (the same exact distances times the same weights,
 * summed in the same order), so only the final pair is selected again. */
static void neighbourhood(const blk *B, cand *best, int four, int rounds)
{
    static const int sh[3] = {11, 5, 0}, mx[3] = {31, 63, 31};
#if ST_BC1_AVX2
    const int avx2 = __builtin_cpu_supports("avx2");
#endif
    uint16_t c0 = best->c0, c1 = best->c1;
    float err = best->err;
    int moved = 0;
    for (int r = 0; r < rounds; r++) {
        nbase N;
#if ST_BC1_AVX2
        if (avx2)
            nbase_fill_avx2(B, c0, c1, &N);
        else
#endif
            nbase_fill(B, c0, c1, &N);
        float lim = err;
        int win = -1;
        for (int k = 0; k < 3; k++) {
            int q0 = (c0 >> sh[k]) & mx[k], q1 = (c1 >> sh[k]) & mx[k];
            float p2[4][4], e[4];
            moves_palette(q0, q1, k == 1 ? 6 : 5, four, p2);
#if ST_BC1_AVX2
            if (avx2)
                moves_eval_avx2(B, &N, k, p2, !four, e);
            else
#endif
                moves_eval(B, &N, k, p2, !four, e);
            /* most channels have no move below the limit: one comparison of the four */
#ifdef __SSE2__
            if (!_mm_movemask_ps(_mm_cmplt_ps(_mm_loadu_ps(e), _mm_set1_ps(lim))))
                continue;
#endif
            /* moves out of range, and 4-colour moves that make the pair equal (it would
             * decode in 3-colour mode), do not count */
            int rest_equal = four && ((c0 ^ c1) & ~(mx[k] << sh[k])) == 0;
            int ok[4] = {q0 > 0 && !(rest_equal && q0 - 1 == q1),
                         q0 < mx[k] && !(rest_equal && q0 + 1 == q1),
                         q1 > 0 && !(rest_equal && q1 - 1 == q0),
                         q1 < mx[k] && !(rest_equal && q1 + 1 == q0)};
            for (int m = 0; m < 4; m++)
                if (ok[m] && e[m] < lim) {
                    lim = e[m];
                    win = 4 * k + m;
                }
        }
        if (win < 0)
            break;
        int k = win >> 2, m = win & 3, e = m >> 1;
        uint16_t c[2] = {c0, c1};
        int q = ((c[e] >> sh[k]) & mx[k]) + (m & 1 ? 1 : -1);
        c[e] = (uint16_t)((c[e] & ~(mx[k] << sh[k])) | (q << sh[k]));
        c0 = four ? (c[0] > c[1] ? c[0] : c[1]) : (c[0] < c[1] ? c[0] : c[1]);
        c1 = four ? (c[0] > c[1] ? c[1] : c[0]) : (c[0] < c[1] ? c[1] : c[0]);
        err = lim;
        moved = 1;
    }
    if (moved) {
        best->c0 = c0;
        best->c1 = c1;
        best->err = select_eval(B, c0, c1, best->sel, 3e30f);
    }
}

/* What a level does (see the method at the top). */
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

static const profile PROFILES[3] = {
    /* ST_BC1_FAST: round, projected selectors, least squares, round, projected selectors */
    {.inset = 1.0f / 16, .rounds = 2, .inset2 = -1, .proj = 1, .proj_final = 1},
    /* ST_BC1_HQ: exact round from the axis, cluster splits within +-3, up to 4 + 2 search
     * rounds, 3-colour fit start. (Starting from FAST's projected round instead made every
     * block at least as good as FAST's but cost 6-7% of the time on the critical path; with
     * the window +-3 the mean is higher without it: docs/bc1.md.) */
    {.inset = 1.0f / 16, .seed = 0, .rounds = 1, .neigh = 4, .rounds3 = 3, .neigh3 = 2,
     .r3ratio = 3, .n3ratio = 1.1f, .inset2 = -1, .cluster = 3, .fit3 = 1},
    /* ST_BC1_BEST: every split */
    {.inset = 1.0f / 16, .rounds = 4, .neigh = 8, .rounds3 = 3, .neigh3 = 4, .r3ratio = 1e30f,
     .n3ratio = 1e30f, .inset2 = 0.125f, .cluster = 16, .fit3 = 2},
};

/* Encodes the block's opaque colours; four_ok = 0 forces 3-colour mode. */
#if ST_BC1_AVX2
/* The cluster fit's split scan with eight i2 at once (the +-3 window of i2 in one step), for
 * CPUs with AVX2; the same operations lane by lane as the SSE2 loop, so the same scores and
 * the same split. Leaves its best four lanes (scores and split indices) folded into the
 * 128-bit form the SSE2 loop ends with. */
__attribute__((target("avx2"))) static void
cluster_scan_avx2(const float *q3r, const float *q3g, const float *q3b, const float *w9,
                  const float *w29, float wsum, const int lo[3], const int hi[3], __m128 *best4,
                  __m128i *idx4)
{
    const __m256 eps = _mm256_set1_ps(1e-5f), ninf = _mm256_set1_ps(-3e30f),
                 one = _mm256_set1_ps(1.0f), Wv = _mm256_set1_ps(wsum);
    const __m256i lane = _mm256_set_epi32(7, 6, 5, 4, 3, 2, 1, 0);
    __m256 bestv = ninf;
    __m256i bidx = _mm256_setzero_si256();
    for (int i0 = lo[0]; i0 <= hi[0]; i0++)
        for (int i1 = i0 > lo[1] ? i0 : lo[1]; i1 <= hi[1]; i1++) {
            __m256 Xr = _mm256_set1_ps(q3r[i0] + q3r[i1]), Xg = _mm256_set1_ps(q3g[i0] + q3g[i1]),
                   Xb = _mm256_set1_ps(q3b[i0] + q3b[i1]);
            __m256 Ac = _mm256_set1_ps(5 * w9[i0] + 3 * w9[i1]), Bc = _mm256_set1_ps(-w29[i0]);
            int s0 = i1 > lo[2] ? i1 : lo[2];
            const __m256i lim = _mm256_set1_epi32(i0 * 289 + i1 * 17 + hi[2] + 1);
            for (int i2 = s0; i2 <= hi[2]; i2 += 8) {
                __m256 AA = _mm256_add_ps(Ac, _mm256_loadu_ps(w9 + i2));
                __m256 BB = _mm256_add_ps(Bc, _mm256_loadu_ps(w29 + i2));
                __m256 CC = _mm256_sub_ps(_mm256_sub_ps(Wv, _mm256_add_ps(AA, BB)), BB);
                __m256 D = _mm256_sub_ps(_mm256_mul_ps(AA, CC), _mm256_mul_ps(BB, BB));
                __m256 X = _mm256_add_ps(Xr, _mm256_loadu_ps(q3r + i2));
                __m256 num = _mm256_mul_ps(X, X);
                X = _mm256_add_ps(Xg, _mm256_loadu_ps(q3g + i2));
                num = _mm256_add_ps(num, _mm256_mul_ps(X, X));
                X = _mm256_add_ps(Xb, _mm256_loadu_ps(q3b + i2));
                num = _mm256_add_ps(num, _mm256_mul_ps(X, X));
                __m256i idx = _mm256_add_epi32(_mm256_set1_epi32(i0 * 289 + i1 * 17 + i2), lane);
                __m256 ok = _mm256_and_ps(_mm256_cmp_ps(D, _mm256_mul_ps(eps, _mm256_mul_ps(AA, CC)),
                                                        _CMP_GT_OQ),
                                          _mm256_castsi256_ps(_mm256_cmpgt_epi32(lim, idx)));
                __m256 gv = _mm256_div_ps(num, _mm256_blendv_ps(one, D, ok));
                gv = _mm256_blendv_ps(ninf, gv, ok);
                __m256 m = _mm256_cmp_ps(gv, bestv, _CMP_GT_OQ);
                bestv = _mm256_blendv_ps(bestv, gv, m);
                bidx = _mm256_castps_si256(_mm256_blendv_ps(_mm256_castsi256_ps(bidx),
                                                            _mm256_castsi256_ps(idx), m));
            }
        }
    /* fold the upper four lanes into the lower: the better score, on a tie the lower index */
    __m128 lo4 = _mm256_castps256_ps128(bestv), hi4 = _mm256_extractf128_ps(bestv, 1);
    __m128i loi = _mm256_castsi256_si128(bidx), hii = _mm256_extracti128_si256(bidx, 1);
    __m128 take = _mm_or_ps(_mm_cmpgt_ps(hi4, lo4),
                            _mm_and_ps(_mm_cmpeq_ps(hi4, lo4),
                                       _mm_castsi128_ps(_mm_cmplt_epi32(hii, loi))));
    *best4 = _mm_blendv_ps(lo4, hi4, take);
    *idx4 = _mm_castps_si128(_mm_blendv_ps(_mm_castsi128_ps(loi), _mm_castsi128_ps(hii), take));
}
#endif

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

static void rank16_sse(const float proj[16], int32_t rank[16])
{
    __m128i K[4], R[4];
    int32_t key[16];
    for (int g = 0; g < 4; g++) {
        K[g] = rank_keys_sse(_mm_loadu_ps(proj + 4 * g),
                             _mm_set_epi32(12 - 4 * g, 13 - 4 * g, 14 - 4 * g, 15 - 4 * g));
        _mm_storeu_si128((__m128i *)(key + 4 * g), K[g]);
        R[g] = _mm_setzero_si128();
    }
    for (int j = 0; j < 16; j++) {
        __m128i kj = _mm_set1_epi32(key[j]);
        for (int g = 0; g < 4; g++)
            R[g] = _mm_sub_epi32(R[g], _mm_cmpgt_epi32(kj, K[g]));
    }
    for (int g = 0; g < 4; g++)
        _mm_storeu_si128((__m128i *)(rank + 4 * g), R[g]);
}
#endif

#if ST_BC1_AVX2
/* rank16_sse eight texels at a time (the same keys, the same ranks). */
__attribute__((target("avx2"))) static void rank16_avx2(const float proj[16], int32_t rank[16])
{
    int32_t key[16];
    for (int g = 0; g < 4; g++)
        _mm_storeu_si128((__m128i *)(key + 4 * g),
                         rank_keys_sse(_mm_loadu_ps(proj + 4 * g),
                                       _mm_set_epi32(12 - 4 * g, 13 - 4 * g, 14 - 4 * g,
                                                     15 - 4 * g)));
    __m256i K0 = _mm256_loadu_si256((const __m256i *)key),
            K1 = _mm256_loadu_si256((const __m256i *)(key + 8));
    __m256i R0 = _mm256_setzero_si256(), R1 = _mm256_setzero_si256();
    for (int j = 0; j < 16; j++) {
        __m256i kj = _mm256_set1_epi32(key[j]);
        R0 = _mm256_sub_epi32(R0, _mm256_cmpgt_epi32(kj, K0));
        R1 = _mm256_sub_epi32(R1, _mm256_cmpgt_epi32(kj, K1));
    }
    _mm256_storeu_si256((__m256i *)rank, R0);
    _mm256_storeu_si256((__m256i *)(rank + 8), R1);
}
#endif

#ifdef __SSE2__
/* The split scan for blocks of 16 texels of weight 1: the determinant of every split comes
 * from the generated table (bc1_tables.h, 1/Dint, -1 for splits that do not count), so a score
 * is |P_i0 + P_i1 + P_i2|^2 * invd: no division. i2 runs in chunks of eight from
 * max(i1, lo[2]) (the last chunk ends at hi[2], overlapping the one before: a split seen again
 * has the same score and is not taken again). Each lane of each of two accumulators (even and
 * odd i1, two independent dependency chains) sees its splits in increasing index order and
 * keeps the first of the best scores; the merge takes the best score and on a tie the lowest
 * index, so the result does not depend on how the splits are spread over lanes. */
typedef struct split_acc {
    __m128 v[2];
    __m128i i[2];
} split_acc;

static inline void split_row_sse(const float *pr, const float *pg, const float *pb, int i0,
                                 int i1, const int hi[3], int first, int last, __m128 *bestv,
                                 __m128i *bidx)
{
    const __m128i lane = _mm_set_epi32(3, 2, 1, 0), four = _mm_set1_epi32(4);
    __m128 Ar = _mm_set1_ps(pr[i0]), Ag = _mm_set1_ps(pg[i0]), Ab = _mm_set1_ps(pb[i0]);
    __m128 Br = _mm_set1_ps(pr[i1]), Bg = _mm_set1_ps(pg[i1]), Bb = _mm_set1_ps(pb[i1]);
    const float *row = st_bc1_split_invd[i0][i1];
    for (int c = first;; c += 8) {
        int s = c < last ? c : last;
        __m128i idx = _mm_add_epi32(_mm_set1_epi32(i0 * 289 + i1 * 17 + s), lane);
        for (int h = 0; h < 8; h += 4) {
            /* X = (P_i0 + P_i2) + P_i1 */
            __m128 X = _mm_add_ps(_mm_add_ps(Ar, _mm_loadu_ps(pr + s + h)), Br);
            __m128 num = _mm_mul_ps(X, X);
            X = _mm_add_ps(_mm_add_ps(Ag, _mm_loadu_ps(pg + s + h)), Bg);
            num = _mm_add_ps(num, _mm_mul_ps(X, X));
            X = _mm_add_ps(_mm_add_ps(Ab, _mm_loadu_ps(pb + s + h)), Bb);
            num = _mm_add_ps(num, _mm_mul_ps(X, X));
            __m128 g = _mm_mul_ps(num, _mm_loadu_ps(row + s + h));
            __m128 m = _mm_cmpgt_ps(g, *bestv);
            *bestv = _mm_or_ps(_mm_and_ps(m, g), _mm_andnot_ps(m, *bestv));
            __m128i mi = _mm_castps_si128(m);
            *bidx = _mm_or_si128(_mm_and_si128(mi, idx), _mm_andnot_si128(mi, *bidx));
            idx = _mm_add_epi32(idx, four);
        }
        if (s + 7 >= hi[2])
            break;
    }
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

static void split_scan_tab_sse(const float *pr, const float *pg, const float *pb, const int lo[3],
                               const int hi[3], __m128 *best4, __m128i *idx4)
{
    __m128 v0 = _mm_setzero_ps(), v1 = v0;
    __m128i x0 = _mm_set1_epi32(-1), x1 = x0;
    int last = hi[2] - 7 < 0 ? 0 : hi[2] - 7;
    for (int i0 = lo[0]; i0 <= hi[0]; i0++) {
        int i1 = i0 > lo[1] ? i0 : lo[1], end = hi[1] < hi[2] ? hi[1] : hi[2];
        for (; i1 + 1 <= end; i1 += 2) {
            split_row_sse(pr, pg, pb, i0, i1, hi, i1 > lo[2] ? i1 : lo[2], last, &v0, &x0);
            split_row_sse(pr, pg, pb, i0, i1 + 1, hi, i1 + 1 > lo[2] ? i1 + 1 : lo[2], last,
                          &v1, &x1);
        }
        if (i1 <= end)
            split_row_sse(pr, pg, pb, i0, i1, hi, i1 > lo[2] ? i1 : lo[2], last, &v0, &x0);
    }
    split_pick_sse(&v0, &x0, v1, x1);
    *best4 = v0;
    *idx4 = x0;
}
#endif

#if ST_BC1_AVX2
/* split_row_sse eight i2 at a time (the same scores, the same rule per lane). */
__attribute__((target("avx2"), always_inline)) static inline void
split_row_avx2(const float *pr, const float *pg, const float *pb, int i0, int i1,
               const int hi[3], int first, int last, __m256 *bestv, __m256 *bidx)
{
    const __m256i lane = _mm256_set_epi32(7, 6, 5, 4, 3, 2, 1, 0);
    __m256 Ar = _mm256_set1_ps(pr[i0]), Ag = _mm256_set1_ps(pg[i0]), Ab = _mm256_set1_ps(pb[i0]);
    __m256 Br = _mm256_set1_ps(pr[i1]), Bg = _mm256_set1_ps(pg[i1]), Bb = _mm256_set1_ps(pb[i1]);
    const float *row = st_bc1_split_invd[i0][i1];
    for (int c = first;; c += 8) {
        int s = c < last ? c : last;
        __m256 X = _mm256_add_ps(_mm256_add_ps(Ar, _mm256_loadu_ps(pr + s)), Br);
        __m256 num = _mm256_mul_ps(X, X);
        X = _mm256_add_ps(_mm256_add_ps(Ag, _mm256_loadu_ps(pg + s)), Bg);
        num = _mm256_add_ps(num, _mm256_mul_ps(X, X));
        X = _mm256_add_ps(_mm256_add_ps(Ab, _mm256_loadu_ps(pb + s)), Bb);
        num = _mm256_add_ps(num, _mm256_mul_ps(X, X));
        __m256 g = _mm256_mul_ps(num, _mm256_loadu_ps(row + s));
        __m256 idx = _mm256_castsi256_ps(
            _mm256_add_epi32(_mm256_set1_epi32(i0 * 289 + i1 * 17 + s), lane));
        __m256 m = _mm256_cmp_ps(g, *bestv, _CMP_GT_OQ);
        *bestv = _mm256_blendv_ps(*bestv, g, m);
        *bidx = _mm256_blendv_ps(*bidx, idx, m);
        if (s + 7 >= hi[2])
            break;
    }
}

__attribute__((target("avx2"))) static void
split_scan_tab_avx2(const float *pr, const float *pg, const float *pb, const int lo[3],
                    const int hi[3], __m128 *best4, __m128i *idx4)
{
    __m256 v0 = _mm256_setzero_ps(), v1 = v0;
    __m256 x0 = _mm256_castsi256_ps(_mm256_set1_epi32(-1)), x1 = x0;
    int last = hi[2] - 7 < 0 ? 0 : hi[2] - 7;
    if (last == lo[2]) {
        /* one chunk of eight i2 at lo[2] for every (i0, i1) (the HQ window): the chunk's
         * prefix sums are loaded once; the same scores and order as the general loop */
        const int s = lo[2];
        const __m256 Pr = _mm256_loadu_ps(pr + s), Pg = _mm256_loadu_ps(pg + s),
                     Pb = _mm256_loadu_ps(pb + s);
        const __m256i lane = _mm256_set_epi32(7, 6, 5, 4, 3, 2, 1, 0),
                      step = _mm256_set1_epi32(17);
        for (int i0 = lo[0]; i0 <= hi[0]; i0++) {
            int i1 = i0 > lo[1] ? i0 : lo[1], end = hi[1] < hi[2] ? hi[1] : hi[2];
            __m256i idx = _mm256_add_epi32(_mm256_set1_epi32(i0 * 289 + i1 * 17 + s), lane);
            /* X = (P_i0 + P_i2) + P_i1: the chunk part of the sum once per i0 */
            const __m256 Qr = _mm256_add_ps(_mm256_set1_ps(pr[i0]), Pr),
                         Qg = _mm256_add_ps(_mm256_set1_ps(pg[i0]), Pg),
                         Qb = _mm256_add_ps(_mm256_set1_ps(pb[i0]), Pb);
            const float *row = st_bc1_split_invd[i0][0] + s;
            /* two rows per step, one per accumulator (any spread of the splits over the
             * accumulators gives the same result) */
#define ST_SPLIT_ROW(I1, V, XI, IDX)                                                       \
    do {                                                                                   \
        __m256 X_ = _mm256_add_ps(Qr, _mm256_broadcast_ss(pr + (I1)));                     \
        __m256 n_ = _mm256_mul_ps(X_, X_);                                                 \
        X_ = _mm256_add_ps(Qg, _mm256_broadcast_ss(pg + (I1)));                            \
        n_ = _mm256_add_ps(n_, _mm256_mul_ps(X_, X_));                                     \
        X_ = _mm256_add_ps(Qb, _mm256_broadcast_ss(pb + (I1)));                            \
        n_ = _mm256_add_ps(n_, _mm256_mul_ps(X_, X_));                                     \
        __m256 g_ = _mm256_mul_ps(n_, _mm256_loadu_ps(row + 17 * (I1)));                   \
        __m256 m_ = _mm256_cmp_ps(g_, V, _CMP_GT_OQ);                                      \
        V = _mm256_blendv_ps(V, g_, m_);                                                   \
        XI = _mm256_blendv_ps(XI, _mm256_castsi256_ps(IDX), m_);                           \
    } while (0)
            for (; i1 + 1 <= end; i1 += 2) {
                __m256i idx1 = _mm256_add_epi32(idx, step);
                ST_SPLIT_ROW(i1, v0, x0, idx);
                ST_SPLIT_ROW(i1 + 1, v1, x1, idx1);
                idx = _mm256_add_epi32(idx1, step);
            }
            if (i1 <= end)
                ST_SPLIT_ROW(i1, v0, x0, idx);
#undef ST_SPLIT_ROW
        }
        goto fold;
    }
    for (int i0 = lo[0]; i0 <= hi[0]; i0++) {
        int i1 = i0 > lo[1] ? i0 : lo[1], end = hi[1] < hi[2] ? hi[1] : hi[2];
        for (; i1 + 1 <= end; i1 += 2) {
            split_row_avx2(pr, pg, pb, i0, i1, hi, i1 > lo[2] ? i1 : lo[2], last, &v0, &x0);
            split_row_avx2(pr, pg, pb, i0, i1 + 1, hi, i1 + 1 > lo[2] ? i1 + 1 : lo[2], last,
                           &v1, &x1);
        }
        if (i1 <= end)
            split_row_avx2(pr, pg, pb, i0, i1, hi, i1 > lo[2] ? i1 : lo[2], last, &v0, &x0);
    }
fold:;
    /* the four 128-bit halves by the merge rule: the two accumulators, then upper into lower */
    __m128 a = _mm256_castps256_ps128(v0);
    __m128i ai = _mm_castps_si128(_mm256_castps256_ps128(x0));
    split_pick_sse(&a, &ai, _mm256_extractf128_ps(v0, 1),
                   _mm_castps_si128(_mm256_extractf128_ps(x0, 1)));
    split_pick_sse(&a, &ai, _mm256_castps256_ps128(v1),
                   _mm_castps_si128(_mm256_castps256_ps128(x1)));
    split_pick_sse(&a, &ai, _mm256_extractf128_ps(v1, 1),
                   _mm_castps_si128(_mm256_extractf128_ps(x1, 1)));
    *best4 = a;
    *idx4 = ai;
}
#endif

/* Cluster fit (4-colour): the texels sorted along the axis, every ordered split into four
 * runs (c0, 2/3 c0 + 1/3 c1, 1/3 c0 + 2/3 c1, c1), the least-squares endpoints of each split
 * from prefix sums, the split of least continuous error wins. */
/* The block's texels ranked along the axis (descending projection) and the prefix sums of
 * weight and weighted colour in that order, the colours taken relative to their mean (the fits
 * are translation invariant, the sums stay small and P_16 = 0); padded to 24: the vector
 * loops read up to 7 past 16. */
typedef struct sorted {
    float pw[24], pr[24], pg[24], pb[24];
} sorted;

static void sort_prefix(const blk *B, const axis *A, sorted *S)
{
    float proj[16];
    int ord[16];
#ifdef __SSE2__
    /* centred colours (the weighted ones for weighted blocks) and the projections, four
     * texels at a time; the same operations as the scalar loop below */
    float cr[16], cg[16], cb[16];
    {
        const __m128 mr = _mm_set1_ps(A->m[0]), mg = _mm_set1_ps(A->m[1]),
                     mb = _mm_set1_ps(A->m[2]), vr = _mm_set1_ps(A->v[0]),
                     vg = _mm_set1_ps(A->v[1]), vb = _mm_set1_ps(A->v[2]);
        for (int g = 0; g < 16; g += 4) {
            __m128 r = _mm_sub_ps(_mm_loadu_ps(B->r + g), mr),
                   gg = _mm_sub_ps(_mm_loadu_ps(B->g + g), mg),
                   b = _mm_sub_ps(_mm_loadu_ps(B->b + g), mb);
            _mm_storeu_ps(proj + g, _mm_add_ps(_mm_add_ps(_mm_mul_ps(r, vr), _mm_mul_ps(gg, vg)),
                                               _mm_mul_ps(b, vb)));
            if (!B->unit) {
                __m128 w = _mm_loadu_ps(B->w + g);
                r = _mm_mul_ps(r, w);
                gg = _mm_mul_ps(gg, w);
                b = _mm_mul_ps(b, w);
            }
            _mm_storeu_ps(cr + g, r);
            _mm_storeu_ps(cg + g, gg);
            _mm_storeu_ps(cb + g, b);
        }
    }
    {
        int32_t rank[16];
#if ST_BC1_AVX2
        if (__builtin_cpu_supports("avx2"))
            rank16_avx2(proj, rank);
        else
#endif
            rank16_sse(proj, rank);
        for (int i = 0; i < 16; i++)
            ord[rank[i]] = i;
    }
    float *pw = S->pw, *pr = S->pr, *pg = S->pg, *pb = S->pb;
    pw[0] = pr[0] = pg[0] = pb[0] = 0;
    for (int i = 0; i < 16; i++) {
        int k = ord[i];
        pw[i + 1] = pw[i] + B->w[k];
        pr[i + 1] = pr[i] + cr[k];
        pg[i + 1] = pg[i] + cg[k];
        pb[i + 1] = pb[i] + cb[k];
    }
#else
    for (int i = 0; i < 16; i++) {
        proj[i] = (B->r[i] - A->m[0]) * A->v[0] + (B->g[i] - A->m[1]) * A->v[1] +
                  (B->b[i] - A->m[2]) * A->v[2];
        ord[i] = i;
    }
    for (int i = 1; i < 16; i++) { /* insertion sort, descending */
        int k = ord[i];
        int j = i - 1;
        while (j >= 0 && proj[ord[j]] < proj[k]) {
            ord[j + 1] = ord[j];
            j--;
        }
        ord[j + 1] = k;
    }
    float *pw = S->pw, *pr = S->pr, *pg = S->pg, *pb = S->pb;
    pw[0] = pr[0] = pg[0] = pb[0] = 0;
    for (int i = 0; i < 16; i++) {
        int k = ord[i];
        float w = B->w[k];
        pw[i + 1] = pw[i] + w;
        pr[i + 1] = pr[i] + w * (B->r[k] - A->m[0]);
        pg[i + 1] = pg[i] + w * (B->g[k] - A->m[1]);
        pb[i + 1] = pb[i] + w * (B->b[k] - A->m[2]);
    }
#endif
    for (int i = 17; i < 24; i++) {
        pw[i] = pw[16];
        pr[i] = pr[16];
        pg[i] = pg[16];
        pb[i] = pb[16];
    }
}

#ifdef __SSE2__
static int split_merge(__m128 bv, __m128i bix);
#endif

static int cluster_fit(const blk *B, const axis *A, const sorted *S, const int lo[3],
                       const int hi[3], float e0[3], float e1[3])
{
    (void)B; /* the weights are in S; B says whether they are all 1 (SSE2 paths) */
    const float *pw = S->pw, *pr = S->pr, *pg = S->pg, *pb = S->pb;
    float best = -1e30f;
    int b0 = -1, b1 = -1, b2 = -1;
#ifdef __SSE2__
    if (B->unit) {
        __m128 bv;
        __m128i bix;
#if ST_BC1_AVX2
        if (__builtin_cpu_supports("avx2"))
            split_scan_tab_avx2(pr, pg, pb, lo, hi, &bv, &bix);
        else
#endif
            split_scan_tab_sse(pr, pg, pb, lo, hi, &bv, &bix);
        int bi = split_merge(bv, bix);
        if (bi >= 0) {
            b0 = bi / 289;
            b1 = bi / 17 % 17;
            b2 = bi % 17;
        }
        goto solve;
    }
#endif
#ifdef __SSE2__
    /* four consecutive i2 at once; each lane keeps its best score and split index, and the
     * lanes are merged so that the first best split in the scalar loop's order wins */
    const __m128 eps = _mm_set1_ps(1e-5f), ninf = _mm_set1_ps(-3e30f);
    __m128 bestv = ninf;
    __m128i bidx = _mm_setzero_si128(), lane = _mm_set_epi32(3, 2, 1, 0);
    /* With P_k the prefix sums of weighted (centred) colour and W_k of weight at the splits
     * (P_16 = 0, W = W_16): X = (P_i0 + P_i1 + P_i2)/3, Y = -X, AA = (5 W_i0 + 3 W_i1 +
     * W_i2)/9, BB = 2 (W_i2 - W_i0)/9, CC = W - AA - 2 BB, and the score
     * (CC|X|^2 - 2 BB X.Y + AA|Y|^2) / D = W |X|^2 / D: |X|^2 / D is compared. */
    float q3r[24], q3g[24], q3b[24], w9[24], w29[24];
    for (int i = 0; i < 24; i++) {
        q3r[i] = pr[i] * (1.0f / 3);
        q3g[i] = pg[i] * (1.0f / 3);
        q3b[i] = pb[i] * (1.0f / 3);
        w9[i] = pw[i] * (1.0f / 9);
        w29[i] = pw[i] * (2.0f / 9);
    }
    const __m128 Wv = _mm_set1_ps(pw[16]);
#if ST_BC1_AVX2
    if (__builtin_cpu_supports("avx2")) {
        cluster_scan_avx2(q3r, q3g, q3b, w9, w29, pw[16], lo, hi, &bestv, &bidx);
        goto merge;
    }
#endif
    for (int i0 = lo[0]; i0 <= hi[0]; i0++)
        for (int i1 = i0 > lo[1] ? i0 : lo[1]; i1 <= hi[1]; i1++) {
            __m128 Xr = _mm_set1_ps(q3r[i0] + q3r[i1]), Xg = _mm_set1_ps(q3g[i0] + q3g[i1]),
                   Xb = _mm_set1_ps(q3b[i0] + q3b[i1]);
            __m128 Ac = _mm_set1_ps(5 * w9[i0] + 3 * w9[i1]), Bc = _mm_set1_ps(-w29[i0]);
            int s0 = i1 > lo[2] ? i1 : lo[2];
            const __m128i lim = _mm_set1_epi32(i0 * 289 + i1 * 17 + hi[2] + 1);
            for (int i2 = s0; i2 <= hi[2]; i2 += 4) {
                __m128 AA = _mm_add_ps(Ac, _mm_loadu_ps(w9 + i2));
                __m128 BB = _mm_add_ps(Bc, _mm_loadu_ps(w29 + i2));
                __m128 CC = _mm_sub_ps(_mm_sub_ps(Wv, _mm_add_ps(AA, BB)), BB);
                __m128 D = _mm_sub_ps(_mm_mul_ps(AA, CC), _mm_mul_ps(BB, BB));
                __m128 X = _mm_add_ps(Xr, _mm_loadu_ps(q3r + i2));
                __m128 num = _mm_mul_ps(X, X);
                X = _mm_add_ps(Xg, _mm_loadu_ps(q3g + i2));
                num = _mm_add_ps(num, _mm_mul_ps(X, X));
                X = _mm_add_ps(Xb, _mm_loadu_ps(q3b + i2));
                num = _mm_add_ps(num, _mm_mul_ps(X, X));
                /* lanes past hi[2] or with a singular system do not count */
                __m128i idx = _mm_add_epi32(_mm_set1_epi32(i0 * 289 + i1 * 17 + i2), lane);
                /* relative test: a split with (nearly) one weight is singular */
                __m128 ok = _mm_and_ps(_mm_cmpgt_ps(D, _mm_mul_ps(eps, _mm_mul_ps(AA, CC))),
                                       _mm_castsi128_ps(_mm_cmplt_epi32(idx, lim)));
                __m128 gv = _mm_div_ps(num, _mm_or_ps(_mm_and_ps(ok, D),
                                                      _mm_andnot_ps(ok, _mm_set1_ps(1.0f))));
                gv = _mm_or_ps(_mm_and_ps(ok, gv), _mm_andnot_ps(ok, ninf));
                __m128 m = _mm_cmpgt_ps(gv, bestv);
                bestv = _mm_or_ps(_mm_and_ps(m, gv), _mm_andnot_ps(m, bestv));
                __m128i mi = _mm_castps_si128(m);
                bidx = _mm_or_si128(_mm_and_si128(mi, idx), _mm_andnot_si128(mi, bidx));
            }
        }
#if ST_BC1_AVX2
merge:
#endif
    /* the best lane; among equal scores the first in the scalar loop's order (lowest index) */
    {
        float gs[4];
        int32_t is[4];
        _mm_storeu_ps(gs, bestv);
        _mm_storeu_si128((__m128i *)is, bidx);
        int bi = -1;
        for (int l = 0; l < 4; l++)
            if (gs[l] > best || (gs[l] == best && bi >= 0 && is[l] < bi)) {
                if (gs[l] > -1e30f) {
                    best = gs[l];
                    bi = is[l];
                }
            }
        if (bi >= 0) {
            b0 = bi / 289;
            b1 = bi / 17 % 17;
            b2 = bi % 17;
        }
    }
#else
    for (int i0 = lo[0]; i0 <= hi[0]; i0++)
        for (int i1 = i0 > lo[1] ? i0 : lo[1]; i1 <= hi[1]; i1++) {
            float n0 = pw[i0], n1 = pw[i1] - pw[i0];
            float s1r = pr[i1] - pr[i0], s1g = pg[i1] - pg[i0], s1b = pb[i1] - pb[i0];
            float X0r = pr[i0] + s1r * (2.0f / 3), X0g = pg[i0] + s1g * (2.0f / 3),
                  X0b = pb[i0] + s1b * (2.0f / 3);
            float Y0r = s1r * (1.0f / 3), Y0g = s1g * (1.0f / 3), Y0b = s1b * (1.0f / 3);
            for (int i2 = i1 > lo[2] ? i1 : lo[2]; i2 <= hi[2]; i2++) {
                float n2 = pw[i2] - pw[i1], n3 = pw[16] - pw[i2];
                float AA = n0 + n1 * (4.0f / 9) + n2 * (1.0f / 9);
                float BB = (n1 + n2) * (2.0f / 9);
                float CC = n3 + n2 * (4.0f / 9) + n1 * (1.0f / 9);
                float D = AA * CC - BB * BB;
                if (!(D > 1e-5f * AA * CC))
                    continue;
                float s2r = pr[i2] - pr[i1], s2g = pg[i2] - pg[i1], s2b = pb[i2] - pb[i1];
                float s3r = pr[16] - pr[i2], s3g = pg[16] - pg[i2], s3b = pb[16] - pb[i2];
                float Xr = X0r + s2r * (1.0f / 3), Xg = X0g + s2g * (1.0f / 3),
                      Xb = X0b + s2b * (1.0f / 3);
                float Yr = Y0r + s3r + s2r * (2.0f / 3), Yg = Y0g + s3g + s2g * (2.0f / 3),
                      Yb = Y0b + s3b + s2b * (2.0f / 3);
                float xx = Xr * Xr + Xg * Xg + Xb * Xb, yy = Yr * Yr + Yg * Yg + Yb * Yb,
                      xy = Xr * Yr + Xg * Yg + Xb * Yb;
                /* maximise a.X + b.Y = (C|X|^2 - 2B X.Y + A|Y|^2) / D */
                float g = (CC * xx - 2 * BB * xy + AA * yy) / D;
                if (g > best) {
                    best = g;
                    b0 = i0;
                    b1 = i1;
                    b2 = i2;
                }
            }
        }
#endif
#ifdef __SSE2__
solve:;
#endif
    int found = b0 >= 0;
    if (found) {
        int i0 = b0, i1 = b1, i2 = b2;
        float n0 = pw[i0], n1 = pw[i1] - pw[i0], n2 = pw[i2] - pw[i1], n3 = pw[16] - pw[i2];
        float AA = n0 + n1 * (4.0f / 9) + n2 * (1.0f / 9), BB = (n1 + n2) * (2.0f / 9);
        float CC = n3 + n2 * (4.0f / 9) + n1 * (1.0f / 9), inv;
#ifdef __SSE2__
        if (B->unit) /* D = Dint / 81: the table has 1 / Dint (no division on this path) */
            inv = 81.0f * st_bc1_split_invd[i0][i1][i2];
        else
#endif
            inv = 1.0f / (AA * CC - BB * BB);
        const float *ps[3] = {pr, pg, pb};
        for (int k = 0; k < 3; k++) {
            const float *q = ps[k];
            float s1 = q[i1] - q[i0], s2 = q[i2] - q[i1], s3 = q[16] - q[i2];
            float X = q[i0] + s1 * (2.0f / 3) + s2 * (1.0f / 3);
            float Y = s3 + s2 * (2.0f / 3) + s1 * (1.0f / 3);
            e0[k] = (CC * X - BB * Y) * inv + A->m[k];
            e1[k] = (AA * Y - BB * X) * inv + A->m[k];
        }
    }
    for (int k = 0; k < 3 && found; k++) {
        e0[k] = e0[k] < 0 ? 0 : e0[k] > 255 ? 255 : e0[k];
        e1[k] = e1[k] < 0 ? 0 : e1[k] > 255 ? 255 : e1[k];
    }
    return found;
}

/* 3-colour cluster fit (blocks of 16 texels of weight 1): the ranked texels split at
 * i0 <= i1 into the runs c0, (c0 + c1) / 2 and c1. With X = (P_i0 + P_i1) / 2 (Y = -X) the
 * least-squares score is W |X|^2 / D, so |P_i0 + P_i1|^2 / Dint is compared, 1 / Dint from
 * the generated table (-1 where the split does not count: i1 < i0, singular). Every split is
 * tried with two fixed chunks of eight i1, 1..8 and 9..16 (the split (0, 0) is singular):
 * rows i0 = 0..8 take both, rows 9..16 the second; the chunks' prefix sums are loaded once.
 * Two accumulators; per lane the first of the best scores, merged by best score and lowest
 * index as in the 4-colour scan, so both paths pick the same split. */
#ifdef __SSE2__
static inline void split3_chunk_sse(__m128 Xr, __m128 Xg, __m128 Xb, const __m128 P[3][2],
                                    const float *row, int base, __m128 *bestv, __m128i *bidx)
{
    for (int h = 0; h < 2; h++) {
        __m128 X = _mm_add_ps(Xr, P[0][h]);
        __m128 num = _mm_mul_ps(X, X);
        X = _mm_add_ps(Xg, P[1][h]);
        num = _mm_add_ps(num, _mm_mul_ps(X, X));
        X = _mm_add_ps(Xb, P[2][h]);
        num = _mm_add_ps(num, _mm_mul_ps(X, X));
        __m128 g = _mm_mul_ps(num, _mm_loadu_ps(row + 4 * h));
        __m128i idx = _mm_add_epi32(_mm_set1_epi32(base + 4 * h), _mm_set_epi32(3, 2, 1, 0));
        __m128 m = _mm_cmpgt_ps(g, *bestv);
        *bestv = _mm_or_ps(_mm_and_ps(m, g), _mm_andnot_ps(m, *bestv));
        __m128i mi = _mm_castps_si128(m);
        *bidx = _mm_or_si128(_mm_and_si128(mi, idx), _mm_andnot_si128(mi, *bidx));
    }
}

static void split3_scan_sse(const float *pr, const float *pg, const float *pb, __m128 *best4,
                            __m128i *idx4)
{
    __m128 v0 = _mm_setzero_ps(), v1 = v0;
    __m128i x0 = _mm_set1_epi32(-1), x1 = x0;
    __m128 lo[3][2], hi[3][2]; /* P[1..8], P[9..16] */
    const float *ps[3] = {pr, pg, pb};
    for (int k = 0; k < 3; k++)
        for (int h = 0; h < 2; h++) {
            lo[k][h] = _mm_loadu_ps(ps[k] + 1 + 4 * h);
            hi[k][h] = _mm_loadu_ps(ps[k] + 9 + 4 * h);
        }
    for (int i0 = 0; i0 <= 16; i0++) {
        __m128 Xr = _mm_set1_ps(pr[i0]), Xg = _mm_set1_ps(pg[i0]), Xb = _mm_set1_ps(pb[i0]);
        const float *row = st_bc1_split3_invd[i0];
        if (i0 <= 8)
            split3_chunk_sse(Xr, Xg, Xb, lo, row + 1, i0 * 17 + 1, &v0, &x0);
        split3_chunk_sse(Xr, Xg, Xb, hi, row + 9, i0 * 17 + 9, &v1, &x1);
    }
    split_pick_sse(&v0, &x0, v1, x1);
    *best4 = v0;
    *idx4 = x0;
}
#endif

#if ST_BC1_AVX2
__attribute__((target("avx2"), always_inline)) static inline void
split3_chunk_avx2(__m256 Xr, __m256 Xg, __m256 Xb, __m256 Pr, __m256 Pg, __m256 Pb,
                  const float *row, int base, __m256 *bestv, __m256 *bidx)
{
    __m256 X = _mm256_add_ps(Xr, Pr);
    __m256 num = _mm256_mul_ps(X, X);
    X = _mm256_add_ps(Xg, Pg);
    num = _mm256_add_ps(num, _mm256_mul_ps(X, X));
    X = _mm256_add_ps(Xb, Pb);
    num = _mm256_add_ps(num, _mm256_mul_ps(X, X));
    __m256 g = _mm256_mul_ps(num, _mm256_loadu_ps(row));
    __m256 idx = _mm256_castsi256_ps(_mm256_add_epi32(_mm256_set1_epi32(base),
                                                      _mm256_set_epi32(7, 6, 5, 4, 3, 2, 1, 0)));
    __m256 m = _mm256_cmp_ps(g, *bestv, _CMP_GT_OQ);
    *bestv = _mm256_blendv_ps(*bestv, g, m);
    *bidx = _mm256_blendv_ps(*bidx, idx, m);
}

__attribute__((target("avx2"))) static void split3_scan_avx2(const float *pr, const float *pg,
                                                              const float *pb, __m128 *best4,
                                                              __m128i *idx4)
{
    __m256 v0 = _mm256_setzero_ps(), v1 = v0;
    __m256 x0 = _mm256_castsi256_ps(_mm256_set1_epi32(-1)), x1 = x0;
    const __m256 Lr = _mm256_loadu_ps(pr + 1), Lg = _mm256_loadu_ps(pg + 1),
                 Lb = _mm256_loadu_ps(pb + 1), Hr = _mm256_loadu_ps(pr + 9),
                 Hg = _mm256_loadu_ps(pg + 9), Hb = _mm256_loadu_ps(pb + 9);
    for (int i0 = 0; i0 <= 16; i0++) {
        __m256 Xr = _mm256_set1_ps(pr[i0]), Xg = _mm256_set1_ps(pg[i0]),
               Xb = _mm256_set1_ps(pb[i0]);
        const float *row = st_bc1_split3_invd[i0];
        if (i0 <= 8)
            split3_chunk_avx2(Xr, Xg, Xb, Lr, Lg, Lb, row + 1, i0 * 17 + 1, &v0, &x0);
        split3_chunk_avx2(Xr, Xg, Xb, Hr, Hg, Hb, row + 9, i0 * 17 + 9, &v1, &x1);
    }
    __m128 a = _mm256_castps256_ps128(v0);
    __m128i ai = _mm_castps_si128(_mm256_castps256_ps128(x0));
    split_pick_sse(&a, &ai, _mm256_extractf128_ps(v0, 1),
                   _mm_castps_si128(_mm256_extractf128_ps(x0, 1)));
    split_pick_sse(&a, &ai, _mm256_castps256_ps128(v1),
                   _mm_castps_si128(_mm256_castps256_ps128(x1)));
    split_pick_sse(&a, &ai, _mm256_extractf128_ps(v1, 1),
                   _mm_castps_si128(_mm256_extractf128_ps(x1, 1)));
    *best4 = a;
    *idx4 = ai;
}
#endif

#ifdef __SSE2__
/* The best lane of a scan's four (best score, lowest index on a tie); -1 when none. Without
 * branches: the maximum score (lanes that found nothing hold 0 and index -1, found ones a
 * score > 0), then the least index among the lanes that hold it. */
static int split_merge(__m128 bv, __m128i bix)
{
    __m128 m = _mm_max_ps(bv, _mm_shuffle_ps(bv, bv, _MM_SHUFFLE(2, 3, 0, 1)));
    m = _mm_max_ps(m, _mm_shuffle_ps(m, m, _MM_SHUFFLE(1, 0, 3, 2)));
    __m128i take = _mm_and_si128(_mm_castps_si128(_mm_cmpeq_ps(bv, m)),
                                 _mm_cmpgt_epi32(bix, _mm_set1_epi32(-1)));
    const __m128i big = _mm_set1_epi32(0x7fffffff);
    __m128i c = _mm_or_si128(_mm_and_si128(take, bix), _mm_andnot_si128(take, big));
    __m128i d = _mm_shuffle_epi32(c, _MM_SHUFFLE(2, 3, 0, 1));
    __m128i lt = _mm_cmplt_epi32(d, c);
    c = _mm_or_si128(_mm_and_si128(lt, d), _mm_andnot_si128(lt, c));
    d = _mm_shuffle_epi32(c, _MM_SHUFFLE(1, 0, 3, 2));
    lt = _mm_cmplt_epi32(d, c);
    c = _mm_or_si128(_mm_and_si128(lt, d), _mm_andnot_si128(lt, c));
    int bi = _mm_cvtsi128_si32(c);
    return bi == 0x7fffffff ? -1 : bi;
}

/* 3-colour endpoints (e0 for selector 0, e1 for selector 1) of the best split; 0 if none. */
static int cluster_fit3(const axis *A, const sorted *S, float e0[3], float e1[3], float *cont)
{
    __m128 bv;
    __m128i bix;
#if ST_BC1_AVX2
    if (__builtin_cpu_supports("avx2"))
        split3_scan_avx2(S->pr, S->pg, S->pb, &bv, &bix);
    else
#endif
        split3_scan_sse(S->pr, S->pg, S->pb, &bv, &bix);
    int bi = split_merge(bv, bix);
    if (bi < 0)
        return 0;
    int i0 = bi / 17, i1 = bi % 17;
    {
        /* the continuous least-squares error of the split: var - 64 |P_i0 + P_i1|^2 / Dint */
        float xr = S->pr[i0] + S->pr[i1], xg = S->pg[i0] + S->pg[i1], xb = S->pb[i0] + S->pb[i1];
        *cont = A->var - 64.0f * (xr * xr + xg * xg + xb * xb) * st_bc1_split3_invd[i0][i1];
    }
    float n0 = S->pw[i0], n1 = S->pw[i1] - S->pw[i0], n2 = S->pw[16] - S->pw[i1];
    float AA = n0 + 0.25f * n1, BB = 0.25f * n1, CC = n2 + 0.25f * n1;
    float inv = 16.0f * st_bc1_split3_invd[i0][i1]; /* D = Dint / 16 */
    const float *ps[3] = {S->pr, S->pg, S->pb};
    for (int k = 0; k < 3; k++) {
        const float *q = ps[k];
        float X = q[i0] + 0.5f * (q[i1] - q[i0]), Y = 0.5f * (q[i1] - q[i0]) + (q[16] - q[i1]);
        float a = (CC * X - BB * Y) * inv + A->m[k], b = (AA * Y - BB * X) * inv + A->m[k];
        e0[k] = a < 0 ? 0 : a > 255 ? 255 : a;
        e1[k] = b < 0 ? 0 : b > 255 ? 255 : b;
    }
    return 1;
}
#endif

/* Rounds of round -> select -> least squares from (e0, e1), 4-colour. */
static void rounds4(const blk *B, const profile *P, const axis *A, float e0[3], float e1[3],
                    cand *best)
{
    uint16_t pa = 0, pb = 0;
    for (int it = 0; it < P->rounds; it++) {
        uint16_t a = round565(e0[0], e0[1], e0[2]), b = round565(e1[0], e1[1], e1[2]);
        if (it > 0 && a == pa && b == pb)
            break; /* the least squares did not move the rounded endpoints */
        pa = a;
        pb = b;
        float before = best->err;
        try4(B, a, b, best);
        if (it > 0 && !(best->err < before))
            break;
        if (best->err == 0 || best->c0 == best->c1 || it + 1 == P->rounds)
            break;
        if (!ls_endpoints(B, best->sel, 1, A->tot, e0, e1))
            break;
        if (P->radius) {
            uint16_t a2, b2;
            refine_exact(B, best->sel, 1, e0, e1, P->radius, &a2, &b2);
            try4(B, a2, b2, best);
        }
    }
}

/* 4-colour weights of c1 for the 565 pair (c0, c1) by projection on the line through the
 * decoded endpoints: t = (x - p0).d / |d|^2 rounded to thirds (no palette distances). */
static void proj_weights(const blk *B, uint16_t c0, uint16_t c1, float tv[16])
{
    uint8_t p0[3], p1[3];
    st_bc1_565_to_rgb8(c0, p0);
    st_bc1_565_to_rgb8(c1, p1);
    float d[3] = {(float)p1[0] - p0[0], (float)p1[1] - p0[1], (float)p1[2] - p0[2]};
    float dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    float sc = dd > 0 ? 3.0f / dd : 0.0f;
    float o = -(p0[0] * d[0] + p0[1] * d[1] + p0[2] * d[2]) * sc + 0.5f;
#ifdef __SSE2__
    __m128 dr = _mm_set1_ps(d[0] * sc), dg = _mm_set1_ps(d[1] * sc), db = _mm_set1_ps(d[2] * sc);
    __m128 ov = _mm_set1_ps(o), zero = _mm_setzero_ps(), top = _mm_set1_ps(3.0f),
           third = _mm_set1_ps(1.0f / 3.0f);
    for (int g = 0; g < 16; g += 4) {
        __m128 t = _mm_add_ps(_mm_add_ps(_mm_mul_ps(_mm_loadu_ps(B->r + g), dr),
                                         _mm_mul_ps(_mm_loadu_ps(B->g + g), dg)),
                              _mm_add_ps(_mm_mul_ps(_mm_loadu_ps(B->b + g), db), ov));
        t = _mm_min_ps(_mm_max_ps(t, zero), top);
        t = _mm_cvtepi32_ps(_mm_cvttps_epi32(t));
        _mm_storeu_ps(tv + g, _mm_mul_ps(t, third));
    }
#else
    for (int i = 0; i < 16; i++) {
        float t = B->r[i] * d[0] * sc + B->g[i] * d[1] * sc + B->b[i] * d[2] * sc + o;
        t = t < 0 ? 0 : t > 3 ? 3 : t;
        tv[i] = (float)(int)t * (1.0f / 3.0f);
    }
#endif
}

/* 4-colour selectors for c0 > c1 by projection on the line p0 -> p1 of the decoded endpoints,
 * with the thresholds halfway between the projections of the four exact palette entries
 * (the truncated thirds are not exactly on the line: near-exact, no distances). */
static void proj_select(const blk *B, uint16_t c0, uint16_t c1, uint8_t sel[16])
{
    uint8_t a[3], b[3];
    st_bc1_565_to_rgb8(c0, a);
    st_bc1_565_to_rgb8(c1, b);
    /* projections (integers) of the palette entries in the order 0, 2, 3, 1 */
    int di[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    int pj[4] = {0, 0, 0, 0};
    for (int k = 0; k < 3; k++) {
        int e2 = (2 * a[k] + b[k]) / 3, e3 = (a[k] + 2 * b[k]) / 3;
        pj[0] += a[k] * di[k];
        pj[1] += e2 * di[k];
        pj[2] += e3 * di[k];
        pj[3] += b[k] * di[k];
    }
    float d[3] = {(float)di[0], (float)di[1], (float)di[2]};
    float t1 = 0.5f * (float)(pj[0] + pj[1]), t2 = 0.5f * (float)(pj[1] + pj[2]),
          t3 = 0.5f * (float)(pj[2] + pj[3]);
#ifdef __SSE2__
    __m128 dr = _mm_set1_ps(d[0]), dg = _mm_set1_ps(d[1]), db = _mm_set1_ps(d[2]);
    __m128 T1 = _mm_set1_ps(t1), T2 = _mm_set1_ps(t2), T3 = _mm_set1_ps(t3);
    /* rank 0..3 = number of thresholds passed; selector = rank 0 -> 0, 1 -> 2, 2 -> 3, 3 -> 1 */
    for (int g = 0; g < 16; g += 4) {
        __m128 x = _mm_add_ps(_mm_add_ps(_mm_mul_ps(_mm_loadu_ps(B->r + g), dr),
                                         _mm_mul_ps(_mm_loadu_ps(B->g + g), dg)),
                              _mm_mul_ps(_mm_loadu_ps(B->b + g), db));
        __m128i m1 = _mm_castps_si128(_mm_cmpgt_ps(x, T1));
        __m128i m2 = _mm_castps_si128(_mm_cmpgt_ps(x, T2));
        __m128i m3 = _mm_castps_si128(_mm_cmpgt_ps(x, T3));
        /* rank 1: 2, rank 2: 3, rank 3: 1 -> sel = (m1 & 2) | (m2 & 1) with rank 3 -> 1:
         * m1&2 | m2&1 gives 0,2,3,3; xor with (m3 & 2) turns 3 into 1 */
        __m128i sv = _mm_or_si128(_mm_and_si128(m1, _mm_set1_epi32(2)),
                                  _mm_and_si128(m2, _mm_set1_epi32(1)));
        sv = _mm_xor_si128(sv, _mm_and_si128(m3, _mm_set1_epi32(2)));
        __m128i s16 = _mm_packs_epi32(sv, sv);
        __m128i s8 = _mm_packus_epi16(s16, s16);
        uint32_t packed = (uint32_t)_mm_cvtsi128_si32(s8);
        memcpy(sel + g, &packed, 4);
    }
#else
    for (int i = 0; i < 16; i++) {
        float x = B->r[i] * d[0] + B->g[i] * d[1] + B->b[i] * d[2];
        int rank = (x > t1) + (x > t2) + (x > t3);
        sel[i] = (uint8_t)(rank == 0 ? 0 : rank == 1 ? 2 : rank == 2 ? 3 : 1);
    }
#endif
}

/* FAST: axis endpoints -> rounds of (round, projected selectors, least squares) -> one exact
 * selection of the result. */
/* Rounds of (round, projected selectors, least squares) from the inset axis endpoints. */
static void proj_rounds(const blk *B, const axis *A, float inset, int rounds, float e0[3],
                        float e1[3])
{
    axis_endpoints(A, inset, e0, e1);
    for (int it = 0; it < rounds; it++) {
        uint16_t a = round565(e0[0], e0[1], e0[2]), b = round565(e1[0], e1[1], e1[2]);
        if (a == b)
            break;
        float tv[16];
        proj_weights(B, a, b, tv);
        if (!ls_t(B, tv, A->tot, e0, e1))
            break;
    }
}

static void encode_fast4(const blk *B, const profile *P, const axis *A, cand *best)
{
    float e0[3], e1[3];
    axis_endpoints(A, P->inset, e0, e1);
    for (int it = 0; it < P->proj; it++) {
        uint16_t a = round565(e0[0], e0[1], e0[2]), b = round565(e1[0], e1[1], e1[2]);
        if (a == b)
            break;
        float tv[16];
        proj_weights(B, a, b, tv);
        if (!ls_t(B, tv, A->tot, e0, e1))
            break;
    }
    uint16_t a = round565(e0[0], e0[1], e0[2]), b = round565(e1[0], e1[1], e1[2]);
    if (P->proj_final && a != b) {
        best->c0 = a > b ? a : b;
        best->c1 = a > b ? b : a;
        proj_select(B, best->c0, best->c1, best->sel);
        best->err = 1.0f; /* not measured */
        return;
    }
    try4(B, a, b, best);
}

/* Encodes the block's opaque colours; four_ok = 0 forces 3-colour mode. */
static void encode_colours(const blk *B, const profile *P, int four_ok, cand *out)
{
    cand best;
    best.err = 3e30f;
    float e0[3], e1[3];
    axis A;
    sorted S;
    int have_sorted = 0; /* S is filled (the 3-colour fit reuses the 4-colour ranking) */
#ifndef __SSE2__
    (void)have_sorted;
#endif
    axis_compute(B, &A);
    if (four_ok && P->proj) {
        encode_fast4(B, P, &A, &best);
        *out = best;
        return;
    }
    if (four_ok) {
        if (P->seed)
            proj_rounds(B, &A, P->inset, P->seed, e0, e1);
        else
            axis_endpoints(&A, P->inset, e0, e1);
        rounds4(B, P, &A, e0, e1, &best);
        if (P->inset2 >= 0 && best.err > 0) {
            axis_endpoints(&A, P->inset2, e0, e1);
            rounds4(B, P, &A, e0, e1, &best);
        }
        if (P->cluster && best.err > 0) {
            /* splits within +-cluster of the ones the best selectors imply */
            int cnt[4] = {0, 0, 0, 0};
#ifdef __SSE2__
            if (B->unit) {
                /* bytes equal to j are 0xFF: their sum / 255 counts them (no chain of
                 * increments through memory) */
                __m128i sv = _mm_loadu_si128((const __m128i *)best.sel);
                for (int j = 0; j < 4; j++) {
                    __m128i sad = _mm_sad_epu8(_mm_cmpeq_epi8(sv, _mm_set1_epi8((char)j)),
                                               _mm_setzero_si128());
                    cnt[j] = (_mm_cvtsi128_si32(sad) + _mm_extract_epi16(sad, 4)) / 255;
                }
            } else
#endif
                for (int i = 0; i < 16; i++)
                    cnt[best.sel[i]] += B->w[i] > 0;
            int sp[3] = {cnt[0], cnt[0] + cnt[2], cnt[0] + cnt[2] + cnt[3]};
            if (best.c0 == best.c1) /* a flat result says nothing about the splits */
                sp[0] = 4, sp[1] = 8, sp[2] = 12;
            int lo[3], hi[3];
            for (int k = 0; k < 2; k++) {
                lo[k] = sp[k] - P->cluster < 0 ? 0 : sp[k] - P->cluster;
                hi[k] = sp[k] + P->cluster > 16 ? 16 : sp[k] + P->cluster;
            }
            /* i2: a window of 2 * cluster (at least 8, at most 17) from sp - cluster, slid
             * inside 0..16: one chunk of eight for the table scan at cluster 4 */
            int size = 2 * P->cluster < 8 ? 8 : 2 * P->cluster > 17 ? 17 : 2 * P->cluster;
            lo[2] = sp[2] - P->cluster < 0 ? 0 : sp[2] - P->cluster;
            hi[2] = lo[2] + size - 1;
            if (hi[2] > 16) {
                hi[2] = 16;
                lo[2] = 17 - size;
            }
            sort_prefix(B, &A, &S);
            have_sorted = 1;
            if (cluster_fit(B, &A, &S, lo, hi, e0, e1))
                rounds4(B, P, &A, e0, e1, &best);
        }
        if (P->neigh && best.c0 != best.c1)
            neighbourhood(B, &best, 1, P->neigh);
    }
    if (!four_ok || (P->rounds3 && best.err > 0)) {
        cand b3;
        b3.err = 3e30f;
        float f0[3], f1[3];
        int rounds = P->rounds3 ? P->rounds3 : 3;
#ifdef __SSE2__
        if (B->unit && P->fit3) {
            /* the 3-colour cluster fit along the same ranking, then as below */
            if (!have_sorted)
                sort_prefix(B, &A, &S);
            float cont = 0;
            rounds = P->fit3;
            if (!cluster_fit3(&A, &S, f0, f1, &cont))
                axis_endpoints(&A, 0.0f, f0, f1);
            else if (four_ok && !(cont < best.err))
                rounds = 0; /* even the unquantised 3-colour fit is not better */
        } else
#endif
            axis_endpoints(&A, 0.0f, f0, f1);
        for (int it = 0; it < rounds; it++) {
            uint16_t a = round565(f0[0], f0[1], f0[2]), b = round565(f1[0], f1[1], f1[2]);
            float before = b3.err;
            try3(B, a, b, &b3);
            if (it > 0 && !(b3.err < before))
                break;
            if (it == 0 && four_ok && b3.err > best.err * P->r3ratio)
                break; /* hopeless from the start */
            if (it + 1 == rounds || !ls_endpoints(B, b3.sel, 0, A.tot, f0, f1))
                break;
            if (P->radius) {
                uint16_t a2, b2;
                refine_exact(B, b3.sel, 0, f0, f1, P->radius, &a2, &b2);
                try3(B, a2, b2, &b3);
            }
        }
        /* the search moves the error by a few per cent: a trial far behind is not refined */
        if (P->neigh3 && b3.err < 1e30f && !(b3.err > best.err * P->n3ratio))
            neighbourhood(B, &b3, 0, P->neigh3);
        if (b3.err < best.err)
            best = b3;
    }
    *out = best;
}

static void write_block(uint16_t c0, uint16_t c1, uint32_t sel, uint8_t out[8])
{
    out[0] = (uint8_t)c0;
    out[1] = (uint8_t)(c0 >> 8);
    out[2] = (uint8_t)c1;
    out[3] = (uint8_t)(c1 >> 8);
    out[4] = (uint8_t)sel;
    out[5] = (uint8_t)(sel >> 8);
    out[6] = (uint8_t)(sel >> 16);
    out[7] = (uint8_t)(sel >> 24);
}

/* One colour for the whole block, 4-colour mode, from the optimal tables. */
static void encode_single(const uint8_t rgb[3], uint32_t transparent, uint8_t out[8])
{
    if (transparent) {
        /* 3-colour: c0 = c1 = nearest 565, selector 0, transparent ones 3 */
        uint16_t c = round565(rgb[0], rgb[1], rgb[2]);
        uint32_t sel = 0;
        for (int t = 0; t < 16; t++)
            if (transparent >> t & 1)
                sel |= 3u << (2 * t);
        write_block(c, c, sel, out);
        return;
    }
    const uint8_t *r = st_bc1_single5[rgb[0]], *g = st_bc1_single6[rgb[1]],
                  *b = st_bc1_single5[rgb[2]];
    uint16_t c0 = pack565(r[0], g[0], b[0]), c1 = pack565(r[1], g[1], b[1]);
    if (c0 > c1)
        write_block(c0, c1, 0xAAAAAAAAu, out); /* selector 2 = (2c0+c1)/3 */
    else if (c0 < c1)
        write_block(c1, c0, 0xFFFFFFFFu, out); /* swapped: selector 3 = (c0'+2c1')/3 */
    else
        write_block(c0, c1, 0, out); /* equal: 3-colour mode, selector 0 is the colour */
}

static void encode_block(const uint8_t rgba[64], const float weight[16], int level,
                         uint8_t out[8]);

void st_bc1_encode_block(const uint8_t rgba[64], int level, uint8_t out[8])
{
    encode_block(rgba, NULL, level, out);
}

void st_bc1_encode_block_w(const uint8_t rgba[64], const float weight[16], int level,
                           uint8_t out[8])
{
    encode_block(rgba, weight, level, out);
}

/* The block encoder behind both entry points (static: the image loop calls it directly). */
static void encode_block(const uint8_t rgba[64], const float weight[16], int level,
                         uint8_t out[8])
{
    uint32_t px[16];
    memcpy(px, rgba, 64);
    /* alpha is byte 3 of each little-endian word: alpha >= 128 <=> bit 31 set */
    uint32_t all = ~0u, diff = 0;
    for (int t = 0; t < 16; t++) {
        all &= px[t];
        diff |= (px[t] ^ px[0]) & 0x00FFFFFFu;
    }
    uint32_t transparent = 0;
    int same = 1, first = 0;
    blk B;
    if (all & 0x80000000u) { /* opaque: the common case */
        B.n = 16;
        same = diff == 0;
    } else {
        B.n = 0;
        first = -1;
        for (int t = 0; t < 16; t++) {
            const uint8_t *p = rgba + 4 * t;
            if (p[3] < 128) {
                transparent |= 1u << t;
                continue;
            }
            if (first < 0)
                first = t;
            else if (((px[t] ^ px[first]) & 0x00FFFFFFu) != 0)
                same = 0;
            B.n++;
        }
    }
    if (B.n == 0) {
        write_block(0, 0, 0xFFFFFFFFu, out); /* every texel transparent */
        return;
    }
    if (same) {
        encode_single(rgba + 4 * first, transparent, out);
        return;
    }
    if (!transparent && !weight) {
#ifdef __SSE2__
        const __m128i lo8 = _mm_set1_epi32(255);
        for (int t = 0; t < 16; t += 4) {
            __m128i v = _mm_loadu_si128((const __m128i *)(rgba + 4 * t));
            _mm_storeu_ps(B.r + t, _mm_cvtepi32_ps(_mm_and_si128(v, lo8)));
            _mm_storeu_ps(B.g + t, _mm_cvtepi32_ps(_mm_and_si128(_mm_srli_epi32(v, 8), lo8)));
            _mm_storeu_ps(B.b + t, _mm_cvtepi32_ps(_mm_and_si128(_mm_srli_epi32(v, 16), lo8)));
            _mm_storeu_ps(B.w + t, _mm_set1_ps(1.0f));
        }
        goto encode;
#endif
        for (int t = 0; t < 16; t++) {
            B.r[t] = (float)(px[t] & 255u);
            B.g[t] = (float)(px[t] >> 8 & 255u);
            B.b[t] = (float)(px[t] >> 16 & 255u);
            B.w[t] = 1.0f;
        }
        goto encode;
    }
    float wsum = 0;
    for (int t = 0; t < 16; t++)
        if (!(transparent >> t & 1))
            wsum += weight ? weight[t] : 1.0f;
    if (!(wsum > 0))
        weight = NULL; /* nothing counts: encode as if everything did */
    for (int t = 0; t < 16; t++) {
        const uint8_t *p = rgba + 4 * ((transparent >> t & 1) ? first : t);
        B.r[t] = p[0];
        B.g[t] = p[1];
        B.b[t] = p[2];
        float w = weight ? weight[t] : 1.0f;
        B.w[t] = (transparent >> t & 1) ? 0.0f : (w > 0 && w < 1e6f ? w : w >= 1e6f ? 1e6f : 0.0f);
    }
encode:;
    B.unit = !transparent && !weight;
    cand c;
    const profile *P = &PROFILES[level == ST_BC1_FAST ? 0 : level == ST_BC1_BEST ? 2 : 1];
    encode_colours(&B, P, transparent == 0, &c);
    uint32_t sel = 0;
    if (!transparent) {
        /* four selectors (bytes 0..3) of a word to one byte: the multiply puts selector k
         * at bits 24 + 2k, the cross terms stay below bit 24 or above bit 31 */
        for (int q = 0; q < 4; q++) {
            uint32_t v;
            memcpy(&v, c.sel + 4 * q, 4);
            sel |= (uint32_t)(((uint64_t)v * 0x1041040u >> 24) & 0xFFu) << (8 * q);
        }
    } else {
        for (int t = 0; t < 16; t++) {
            unsigned s = (transparent >> t & 1) ? 3u : c.sel[t];
            sel |= s << (2 * t);
        }
    }
    write_block(c.c0, c.c1, sel, out);
}

/* ---- images --------------------------------------------------------------------------- */

typedef struct img_job {
    const uint8_t *rgba;
    const float *weights; /* w*h, row-major, or NULL */
    uint32_t w, h;
    size_t stride;
    int level;
    uint8_t *blocks;
    uint32_t row0, row1; /* block rows */
} img_job;

static void load_block(const uint8_t *rgba, uint32_t w, uint32_t h, size_t stride, uint32_t bx,
                       uint32_t by, uint8_t tmp[64])
{
    for (uint32_t y = 0; y < 4; y++) {
        uint32_t sy = by * 4 + y < h ? by * 4 + y : h - 1;
        const uint8_t *row = rgba + (size_t)sy * stride;
        if (bx * 4 + 3 < w) {
            memcpy(tmp + 16 * y, row + (size_t)bx * 16, 16);
        } else {
            for (uint32_t x = 0; x < 4; x++) {
                uint32_t sx = bx * 4 + x < w ? bx * 4 + x : w - 1;
                memcpy(tmp + 16 * y + 4 * x, row + (size_t)sx * 4, 4);
            }
        }
    }
}

static void *img_worker(void *arg)
{
    img_job *j = arg;
    uint32_t bw = (j->w + 3) / 4;
    uint8_t tmp[64];
    float wt[16];
    for (uint32_t by = j->row0; by < j->row1; by++)
        for (uint32_t bx = 0; bx < bw; bx++) {
            load_block(j->rgba, j->w, j->h, j->stride, bx, by, tmp);
            if (j->weights) {
                for (uint32_t t = 0; t < 16; t++) {
                    uint32_t x = bx * 4 + (t & 3), y = by * 4 + (t >> 2);
                    /* padding repeats the edge texel: it does not count twice */
                    wt[t] = x < j->w && y < j->h ? j->weights[(size_t)y * j->w + x] : 0.0f;
                }
                encode_block(tmp, wt, j->level, j->blocks + ((size_t)by * bw + bx) * 8);
            } else {
                encode_block(tmp, NULL, j->level, j->blocks + ((size_t)by * bw + bx) * 8);
            }
        }
    return NULL;
}

int st_bc1_encode_image(const uint8_t *rgba, uint32_t w, uint32_t h, size_t stride, int level,
                        int threads, uint8_t *blocks, st_error *e)
{
    return st_bc1_encode_image_w(rgba, NULL, w, h, stride, level, threads, blocks, e);
}

int st_bc1_encode_image_w(const uint8_t *rgba, const float *weights, uint32_t w, uint32_t h,
                          size_t stride, int level, int threads, uint8_t *blocks, st_error *e)
{
    if (w < 1 || h < 1 || w > ST_MAX_DIM || h > ST_MAX_DIM)
        return st_fail(e, ST_EINVAL, "image size %ux%u not in 1..%u", w, h, ST_MAX_DIM);
    if (stride < (size_t)w * 4)
        return st_fail(e, ST_EINVAL, "row stride %zu is less than %u texels", stride, w);
    uint32_t bh = (h + 3) / 4;
    if (threads <= 0) {
        long n = sysconf(_SC_NPROCESSORS_ONLN);
        threads = n > 0 ? (int)n : 1;
    }
    if (threads > 64)
        threads = 64;
    /* below ~64K texels a thread costs more than it saves */
    if ((uint64_t)w * h < 65536 || (uint32_t)threads > bh)
        threads = 1;
    img_job jobs[64];
    pthread_t tid[64];
    int started = 0;
    for (int t = 0; t < threads; t++) {
        jobs[t] = (img_job){rgba, weights, w, h, stride, level, blocks,
                            (uint32_t)((uint64_t)bh * t / threads),
                            (uint32_t)((uint64_t)bh * (t + 1) / threads)};
    }
    for (int t = 1; t < threads; t++) {
        if (pthread_create(&tid[t], NULL, img_worker, &jobs[t]) != 0)
            break;
        started = t;
    }
    img_worker(&jobs[0]);
    for (int t = 1; t <= started; t++)
        pthread_join(tid[t], NULL);
    for (int t = started + 1; t < threads; t++)
        img_worker(&jobs[t]); /* a thread that did not start: do its share here */
    return ST_OK;
}

/* store/bc1/bc1_encode.c - the BC1 block encoder's entry points and levels, and the threaded
 * image encoder.
 *
 * Owns: the public block and image entry points (bc1.h), a block's colours and weights
 * (transparent, one-colour and weighted blocks), the three levels (profiles) and the order in
 * which a level runs the stages; splitting an image over threads. Does not own: the stages
 * themselves - bc1_fit.c (axis, least squares, FAST's projection), bc1_cluster.c (cluster
 * fits), bc1_select.c (exact selection, the +-1 search), bc1_encode_avx2.c (the AVX2 twins
 * and the CPU check); what they share is bc1_encode_internal.h. Nor sets, seams or files
 * (bc1_set.c, bc1_seam.c, seammask.c, dds.c).
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
 * SSE2 throughout (x86-64 baseline; plain C elsewhere); on CPUs with AVX2 (checked once per
 * block, st_bc1e_cpu_avx2) the hot loops run eight texels / splits at a time in
 * bc1_encode_avx2.c with the same arithmetic lane by lane (and the same order of every sum),
 * so the output is byte-identical either way (tests/unit/test_bc1_simd.c encodes with the
 * AVX2 twins off through st_bc1e_encode_block and compares).
 * Texels with alpha < 128 force 3-colour mode with selector 3 on them.
 */
#include "bc1.h"
#include "bc1_encode_internal.h"
#include "bc1_tables.h"

#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* What a level does (see the method above). */
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
    st_bc1e_axis_compute(B, &A);
    if (four_ok && P->proj) {
        st_bc1e_encode_fast4(B, P, &A, &best);
        *out = best;
        return;
    }
    if (four_ok) {
        if (P->seed)
            st_bc1e_proj_rounds(B, &A, P->inset, P->seed, e0, e1);
        else
            st_bc1e_axis_endpoints(&A, P->inset, e0, e1);
        st_bc1e_rounds4(B, P, &A, e0, e1, &best);
        if (P->inset2 >= 0 && best.err > 0) {
            st_bc1e_axis_endpoints(&A, P->inset2, e0, e1);
            st_bc1e_rounds4(B, P, &A, e0, e1, &best);
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
            st_bc1e_sort_prefix(B, &A, &S);
            have_sorted = 1;
            if (st_bc1e_cluster_fit(B, &A, &S, lo, hi, e0, e1))
                st_bc1e_rounds4(B, P, &A, e0, e1, &best);
        }
        if (P->neigh && best.c0 != best.c1)
            st_bc1e_neighbourhood(B, &best, 1, P->neigh);
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
                st_bc1e_sort_prefix(B, &A, &S);
            float cont = 0;
            rounds = P->fit3;
            if (!st_bc1e_cluster_fit3(B, &A, &S, f0, f1, &cont))
                st_bc1e_axis_endpoints(&A, 0.0f, f0, f1);
            else if (four_ok && !(cont < best.err))
                rounds = 0; /* even the unquantised 3-colour fit is not better */
        } else
#endif
            st_bc1e_axis_endpoints(&A, 0.0f, f0, f1);
        for (int it = 0; it < rounds; it++) {
            uint16_t a = round565(f0[0], f0[1], f0[2]), b = round565(f1[0], f1[1], f1[2]);
            float before = b3.err;
            st_bc1e_try3(B, a, b, &b3);
            if (it > 0 && !(b3.err < before))
                break;
            if (it == 0 && four_ok && b3.err > best.err * P->r3ratio)
                break; /* hopeless from the start */
            if (it + 1 == rounds || !st_bc1e_ls_endpoints(B, b3.sel, 0, A.tot, f0, f1))
                break;
            if (P->radius) {
                uint16_t a2, b2;
                st_bc1e_refine_exact(B, b3.sel, 0, f0, f1, P->radius, &a2, &b2);
                st_bc1e_try3(B, a2, b2, &b3);
            }
        }
        /* the search moves the error by a few per cent: a trial far behind is not refined */
        if (P->neigh3 && b3.err < 1e30f && !(b3.err > best.err * P->n3ratio))
            st_bc1e_neighbourhood(B, &b3, 0, P->neigh3);
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

void st_bc1_encode_block(const uint8_t rgba[64], int level, uint8_t out[8])
{
    st_bc1e_encode_block(rgba, NULL, level, st_bc1e_cpu_avx2(), out);
}

void st_bc1_encode_block_w(const uint8_t rgba[64], const float weight[16], int level,
                           uint8_t out[8])
{
    st_bc1e_encode_block(rgba, weight, level, st_bc1e_cpu_avx2(), out);
}

/* The block encoder behind the entry points and the image loop (bc1_encode_internal.h). */
void st_bc1e_encode_block(const uint8_t rgba[64], const float weight[16], int level, int avx2,
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
    B.avx2 = avx2;
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
    const int avx2 = st_bc1e_cpu_avx2();
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
                st_bc1e_encode_block(tmp, wt, j->level, avx2, j->blocks + ((size_t)by * bw + bx) * 8);
            } else {
                st_bc1e_encode_block(tmp, NULL, j->level, avx2, j->blocks + ((size_t)by * bw + bx) * 8);
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

/* store/bc1/bc1_cluster.c - the cluster fits of the BC1 block encoder.
 *
 * Owns: ranking a block's texels along the principal axis with prefix sums of the centred
 * colours (sorted), the 4-colour cluster fit over a window of ordered splits (HQ) or all 969
 * (BEST), and the 3-colour fit over all 153 splits of blocks of 16 texels of weight 1; the
 * split scores of such blocks come from the generated 1/determinant tables (bc1_tables.h, no
 * division). Does not own: rounding and measuring what the fits propose (bc1_fit.c,
 * bc1_select.c), the AVX2 scans (bc1_encode_avx2.c, chosen per block through BC1_AVX2).
 */
#include "bc1_encode_internal.h"
#include "bc1_tables.h"
#ifdef __SSE2__
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

#ifdef __SSE2__
/* The split scan for blocks of 16 texels of weight 1: the determinant of every split comes
 * from the generated table (bc1_tables.h, 1/Dint, -1 for splits that do not count), so a score
 * is |P_i0 + P_i1 + P_i2|^2 * invd: no division. i2 runs in chunks of eight from
 * max(i1, lo[2]) (the last chunk ends at hi[2], overlapping the one before: a split seen again
 * has the same score and is not taken again). Each lane of each of two accumulators (even and
 * odd i1, two independent dependency chains) sees its splits in increasing index order and
 * keeps the first of the best scores; the merge takes the best score and on a tie the lowest
 * index, so the result does not depend on how the splits are spread over lanes. */
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


/* Cluster fit (4-colour): the texels sorted along the axis, every ordered split into four
 * runs (c0, 2/3 c0 + 1/3 c1, 1/3 c0 + 2/3 c1, c1), the least-squares endpoints of each split
 * from prefix sums, the split of least continuous error wins. */

void st_bc1e_sort_prefix(const blk *B, const axis *A, sorted *S)
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
        if (BC1_AVX2(B))
            st_bc1e_rank16_avx2(proj, rank);
        else
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

int st_bc1e_cluster_fit(const blk *B, const axis *A, const sorted *S, const int lo[3],
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
        if (BC1_AVX2(B))
            st_bc1e_split_scan_tab_avx2(pr, pg, pb, lo, hi, &bv, &bix);
        else
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
    if (BC1_AVX2(B)) {
        st_bc1e_cluster_scan_avx2(q3r, q3g, q3b, w9, w29, pw[16], lo, hi, &bestv, &bidx);
        goto merge;
    }
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
merge:
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
int st_bc1e_cluster_fit3(const blk *B, const axis *A, const sorted *S, float e0[3],
                         float e1[3], float *cont)
{
    __m128 bv;
    __m128i bix;
    if (BC1_AVX2(B))
        st_bc1e_split3_scan_avx2(S->pr, S->pg, S->pb, &bv, &bix);
    else
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
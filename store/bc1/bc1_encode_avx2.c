/* store/bc1/bc1_encode_avx2.c - the AVX2 twins of the BC1 encoder's hot loops, and the CPU
 * check that lets them run. Platform code lives here so that the stage files hold no #if
 * around their logic: a call site reads `if (BC1_AVX2(B)) twin(...) else sse2(...)`, and
 * the block's avx2 flag comes from st_bc1e_cpu_avx2() once per block (bc1_encode.c).
 *
 * Owns: selection (select_avx2), the distance table and the move evaluation of the +-1
 * search, the ranking, the 4-colour split scans (weighted and table) and the 3-colour scan,
 * eight texels / splits at a time. Each is compiled for AVX2 by a per-function target
 * attribute (no -mavx2 for the file, so nothing else here can use AVX2 by accident) and runs
 * only on CPUs that have it. Every twin performs its SSE2 twin's operations lane by lane,
 * with the same order of every sum and the same tie rules, so the blocks are byte-identical
 * (tests/unit/test_bc1_simd.c compares the two paths block for block). Does not own: any
 * decision of the encoder. Without x86-64 and GCC-style attributes the file holds only the
 * check, which answers 0.
 */
#include "bc1_encode_internal.h"

#if ST_BC1_AVX2
#include "bc1_tables.h"

int st_bc1e_cpu_avx2(void)
{
    return __builtin_cpu_supports("avx2");
}

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
__attribute__((target("avx2"))) float
st_bc1e_select_avx2(const blk *B, uint16_t c0, uint16_t c1, uint8_t *sel, float limit)
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

/* nbase_fill eight texels at a time (the same values). */
__attribute__((target("avx2"))) void
st_bc1e_nbase_fill_avx2(const blk *B, uint16_t c0, uint16_t c1, nbase *N)
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

__attribute__((target("avx2"))) void
st_bc1e_moves_eval_avx2(const blk *B, const nbase *N, int k, const float p2[4][4], int three,
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

/* The cluster fit's split scan with eight i2 at once (the +-3 window of i2 in one step), for
 * CPUs with AVX2; the same operations lane by lane as the SSE2 loop, so the same scores and
 * the same split. Leaves its best four lanes (scores and split indices) folded into the
 * 128-bit form the SSE2 loop ends with. */
__attribute__((target("avx2"))) void
st_bc1e_cluster_scan_avx2(const float *q3r, const float *q3g, const float *q3b,
                          const float *w9, const float *w29, float wsum, const int lo[3],
                          const int hi[3], __m128 *best4, __m128i *idx4)
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

/* rank16_sse eight texels at a time (the same keys, the same ranks). */
__attribute__((target("avx2"))) void
st_bc1e_rank16_avx2(const float proj[16], int32_t rank[16])
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

/* The best of two accumulators of eight lanes (scores v, split indices x) as the four lanes
 * the SSE2 scans end with: the 128-bit halves by the merge rule (split_pick_sse), the two
 * accumulators, then upper into lower. */
__attribute__((target("avx2"), always_inline)) static inline void
fold_acc_avx2(__m256 v0, __m256 x0, __m256 v1, __m256 x1, __m128 *best4, __m128i *idx4)
{
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

__attribute__((target("avx2"))) void
st_bc1e_split_scan_tab_avx2(const float *pr, const float *pg, const float *pb, const int lo[3],
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
fold:
    fold_acc_avx2(v0, x0, v1, x1, best4, idx4);
}

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

__attribute__((target("avx2"))) void
st_bc1e_split3_scan_avx2(const float *pr, const float *pg, const float *pb, __m128 *best4,
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
    fold_acc_avx2(v0, x0, v1, x1, best4, idx4);
}
#else

int st_bc1e_cpu_avx2(void)
{
    return 0;
}

#endif

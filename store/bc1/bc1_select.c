/* store/bc1/bc1_select.c - exact selection and the +-1 search of the BC1 block encoder.
 *
 * Owns: choosing the selectors of an endpoint pair by the exact palette distance (truncating
 * decoder, bc1_texel.h) and its squared error; the 4- and 3-colour candidates (try4, try3:
 * a pair is kept only when it lowers the error); the steepest-descent search over the six
 * 565 components of a pair (twelve +-1 moves measured from one table of per-channel
 * distances). Does not own: where the pairs come from (bc1_fit.c, bc1_cluster.c), the order
 * of the stages (bc1_encode.c), the AVX2 twins (bc1_encode_avx2.c, chosen per block through
 * BC1_AVX2).
 */
#include "bc1_encode_internal.h"

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
#ifdef __SSE2__
static float select_eval(const blk *B, uint16_t c0, uint16_t c1, uint8_t *sel, float limit)
{
    if (BC1_AVX2(B))
        return st_bc1e_select_avx2(B, c0, c1, sel, limit);
    return select_sse(B, c0, c1, sel, limit);
}
#endif

/* Evaluates a 4-colour candidate given as a possibly unordered pair: orders it, handles
 * c0 == c1 (which would decode in 3-colour mode: all selectors 0 then). */
void st_bc1e_try4(const blk *B, uint16_t a, uint16_t b, cand *best)
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
void st_bc1e_try3(const blk *B, uint16_t a, uint16_t b, cand *best)
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
void st_bc1e_neighbourhood(const blk *B, cand *best, int four, int rounds)
{
    static const int sh[3] = {11, 5, 0}, mx[3] = {31, 63, 31};
    const int avx2 = BC1_AVX2(B);
    uint16_t c0 = best->c0, c1 = best->c1;
    float err = best->err;
    int moved = 0;
    for (int r = 0; r < rounds; r++) {
        nbase N;
        if (avx2)
            st_bc1e_nbase_fill_avx2(B, c0, c1, &N);
        else
            nbase_fill(B, c0, c1, &N);
        float lim = err;
        int win = -1;
        for (int k = 0; k < 3; k++) {
            int q0 = (c0 >> sh[k]) & mx[k], q1 = (c1 >> sh[k]) & mx[k];
            float p2[4][4], e[4];
            moves_palette(q0, q1, k == 1 ? 6 : 5, four, p2);
            if (avx2)
                st_bc1e_moves_eval_avx2(B, &N, k, p2, !four, e);
            else
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
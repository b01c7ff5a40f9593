/* store/bc1/bc1_fit.c - endpoint fitting of the BC1 block encoder.
 *
 * Owns: the principal axis of a block (weighted moments, C^5 by two squarings, the extreme
 * projections), the least-squares endpoints for given selector weights, the exact
 * per-channel refinement around them, the 4-colour rounds (round -> select -> least squares)
 * and FAST's path (selectors by projection on the decoded endpoint line, no palette
 * distances). Does not own: the cluster fits (bc1_cluster.c), selection and the search
 * (bc1_select.c), the order of the stages (bc1_encode.c).
 */
#include "bc1_encode_internal.h"

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
int st_bc1e_ls_endpoints(const blk *B, const uint8_t *sel, int four, const float tot[4],
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
void st_bc1e_refine_exact(const blk *B, const uint8_t *sel, int four, const float e0[3],
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

void st_bc1e_axis_compute(const blk *B, axis *A)
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

void st_bc1e_axis_endpoints(const axis *A, float inset, float e0[3], float e1[3])
{
    float d = (A->hi - A->lo) * inset, il = 1.0f / A->len2;
    float lo = (A->lo + d) * il, hi = (A->hi - d) * il;
    for (int k = 0; k < 3; k++) {
        float a = A->m[k] + A->v[k] * hi, b = A->m[k] + A->v[k] * lo;
        e0[k] = a < 0 ? 0 : a > 255 ? 255 : a;
        e1[k] = b < 0 ? 0 : b > 255 ? 255 : b;
    }
}


/* Rounds of round -> select -> least squares from (e0, e1), 4-colour. */
void st_bc1e_rounds4(const blk *B, const profile *P, const axis *A, float e0[3], float e1[3],
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
        st_bc1e_try4(B, a, b, best);
        if (it > 0 && !(best->err < before))
            break;
        if (best->err == 0 || best->c0 == best->c1 || it + 1 == P->rounds)
            break;
        if (!st_bc1e_ls_endpoints(B, best->sel, 1, A->tot, e0, e1))
            break;
        if (P->radius) {
            uint16_t a2, b2;
            st_bc1e_refine_exact(B, best->sel, 1, e0, e1, P->radius, &a2, &b2);
            st_bc1e_try4(B, a2, b2, best);
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
void st_bc1e_proj_rounds(const blk *B, const axis *A, float inset, int rounds, float e0[3],
                         float e1[3])
{
    st_bc1e_axis_endpoints(A, inset, e0, e1);
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

void st_bc1e_encode_fast4(const blk *B, const profile *P, const axis *A, cand *best)
{
    float e0[3], e1[3];
    st_bc1e_proj_rounds(B, A, P->inset, P->proj, e0, e1);
    uint16_t a = round565(e0[0], e0[1], e0[2]), b = round565(e1[0], e1[1], e1[2]);
    if (P->proj_final && a != b) {
        best->c0 = a > b ? a : b;
        best->c1 = a > b ? b : a;
        proj_select(B, best->c0, best->c1, best->sel);
        best->err = 1.0f; /* not measured */
        return;
    }
    st_bc1e_try4(B, a, b, best);
}
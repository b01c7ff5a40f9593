/* store/sample/sample.c - st_sample_batch: option and query validation, level selection (point,
 * bilinear, trilinear, anisotropic), the in-face fast path, and the result/coverage rules.
 *
 * Owns: the query loop, specialised by texel type (u8 x4, u8, u16, half, f32 x4, f32, BC1) so
 * that the inner loops see the dtype and channel count as constants; no allocation, no
 * per-tap function pointers. Does not own: taps outside the face (sample_tap.c, the slow
 * path), the Ptex filter family (ptexfilter.c), the set layout (set.h).
 *
 * A probe is one bilinear (or point) lookup at one level with a weight. A query adds its
 * probes into one st_acc (sum of w*T per channel, sum of w) and ends with sum(wT)/sum(w);
 * the coverage is sum(w). A probe whose taps all fall inside the face takes the fast path,
 * identical for every mode, so modes agree exactly in face interiors and Traverse costs what
 * Discard costs there. Discard and Traverse on an atlas with chart ids (set->ext.charts) run
 * in variants of their own (CH = 1): the query's chart is found once (query_chart), and a
 * probe takes the fast path only when its four taps are of that chart; otherwise
 * st_probe_bilinear_chart drops the others (Discard) or reads the texels linked to them across
 * a UV seam (Traverse; docs/sampler.md, "Chart Discard", "Chart Traverse"). Other sets never
 * pay for the check. A chart-mode batch pins the chart data first (set->ext.charts_pin: built
 * there when an atlas opened from its native file has none yet, and kept from the memory
 * budget's drop until the batch ends): once per batch, never per query.
 */
#include "sample_internal.h"

#include <math.h>
#include <string.h>

#define DT_BC1 4 /* pseudo dtype of the BC1 variant: decode on tap, 4 channels */

/* ---- texel reads specialised by dtype ------------------------------------------------- */

ST_AI void bc1_fetch(const st_view *v, int32_t i, int32_t j, float o[4])
{
    const uint8_t *blk = v->base + ((size_t)(j >> 2) * v->bw + (size_t)(i >> 2)) * 8;
    uint8_t rgba[4];
    st_bc1_texel(blk, (unsigned)i & 3u, (unsigned)j & 3u, rgba);
    for (int c = 0; c < 4; c++)
        o[c] = rgba[c] * (1.0f / 255.0f);
}

ST_AI float chan(int DT, const uint8_t *p, unsigned c)
{
    return st_channel_get(DT == DT_BC1 ? ST_DT_U8 : (unsigned)DT, p, c);
}

/* Four channels at once (u8 x4, f32 x4, decoded BC1) with SSE2, which every x86-64 has; the
 * scalar loop below is the same arithmetic, one channel at a time, for everything else. */
#if defined(__SSE2__)
#include <emmintrin.h>
#define ST_SIMD4 1
ST_AI __m128 load4(int DT, const uint8_t *p)
{
    if (DT == ST_DT_F32)
        return _mm_loadu_ps((const float *)p);
    int32_t x;
    memcpy(&x, p, 4);
    __m128i z = _mm_setzero_si128();
    __m128i v = _mm_unpacklo_epi16(_mm_unpacklo_epi8(_mm_cvtsi32_si128(x), z), z);
    return _mm_mul_ps(_mm_cvtepi32_ps(v), _mm_set1_ps(1.0f / 255.0f));
}
ST_AI void bilerp4(int DT, const uint8_t *p00, const uint8_t *p10, const uint8_t *p01,
                   const uint8_t *p11, float fx, float fy, float pw, st_acc *a)
{
    __m128 t00 = load4(DT, p00), t10 = load4(DT, p10), t01 = load4(DT, p01), t11 = load4(DT, p11);
    __m128 vx = _mm_set1_ps(fx), vy = _mm_set1_ps(fy);
    __m128 r0 = _mm_add_ps(t00, _mm_mul_ps(vx, _mm_sub_ps(t10, t00)));
    __m128 r1 = _mm_add_ps(t01, _mm_mul_ps(vx, _mm_sub_ps(t11, t01)));
    __m128 r = _mm_add_ps(r0, _mm_mul_ps(vy, _mm_sub_ps(r1, r0)));
    _mm_storeu_ps(a->c, _mm_add_ps(_mm_loadu_ps(a->c), _mm_mul_ps(_mm_set1_ps(pw), r)));
}
#else
#define ST_SIMD4 0
#endif

ST_AI void bc1_texel_at(const st_view *v, int32_t i, int32_t j, uint8_t rgba[4])
{
    const uint8_t *blk = v->base + ((size_t)(j >> 2) * v->bw + (size_t)(i >> 2)) * 8;
    st_bc1_texel(blk, (unsigned)i & 3u, (unsigned)j & 3u, rgba);
}

/* ---- probes ------------------------------------------------------------------------------ */

ST_AI void probe_bilinear(const st_set *s, unsigned mode, const st_fp *fp, uint32_t f,
                          unsigned level, float u, float v, float pw, st_acc *a, int DT,
                          unsigned nch, int CH)
{
    st_view V;
    st_view_init(&V, s, f, level);
    float x = u * (float)V.w - 0.5f, y = v * (float)V.h - 0.5f;
    int32_t i0 = st_ifloor(x), j0 = st_ifloor(y);
    float fx = x - (float)i0, fy = y - (float)j0;
    if (CH && fp->chart) { /* chart modes: the fast path when all four taps are the chart's */
        const uint16_t c = (uint16_t)fp->chart;
        const uint16_t *r = fp->ch->level[level];
        /* the ids' row pointer is formed only inside the level (i0 or j0 may be -1) */
        if (!((uint32_t)i0 < (uint32_t)(V.w - 1) && (uint32_t)j0 < (uint32_t)(V.h - 1) &&
              (r += (size_t)j0 * (size_t)V.w + (size_t)i0, r[0] == c) && r[1] == c &&
              r[V.w] == c && r[V.w + 1] == c)) {
            st_probe_bilinear_chart(s, mode, fp, level, &V, i0, j0, fx, fy, pw, a);
            return;
        }
    }
    if (!((uint32_t)i0 < (uint32_t)(V.w - 1) && (uint32_t)j0 < (uint32_t)(V.h - 1))) {
        st_probe_bilinear_edge(s, mode, fp, f, level, &V, i0, j0, fx, fy, pw, a);
        return;
    }
#if ST_SIMD4
    if (DT == DT_BC1 && V.bw) {
        uint8_t t[4][4];
        bc1_texel_at(&V, i0, j0, t[0]);
        bc1_texel_at(&V, i0 + 1, j0, t[1]);
        bc1_texel_at(&V, i0, j0 + 1, t[2]);
        bc1_texel_at(&V, i0 + 1, j0 + 1, t[3]);
        bilerp4(ST_DT_U8, t[0], t[1], t[2], t[3], fx, fy, pw, a);
        a->w += pw;
        return;
    }
    if (nch == 4 && (DT == ST_DT_U8 || DT == ST_DT_F32 || DT == DT_BC1)) {
        const uint8_t *p00 = V.base + (size_t)i0 * V.xs + (size_t)j0 * V.ys;
        bilerp4(DT == DT_BC1 ? ST_DT_U8 : DT, p00, p00 + V.xs, p00 + V.ys, p00 + V.ys + V.xs,
                fx, fy, pw, a);
        a->w += pw;
        return;
    }
#endif
    if (DT == DT_BC1 && V.bw) {
        float t00[4], t10[4], t01[4], t11[4];
        bc1_fetch(&V, i0, j0, t00);
        bc1_fetch(&V, i0 + 1, j0, t10);
        bc1_fetch(&V, i0, j0 + 1, t01);
        bc1_fetch(&V, i0 + 1, j0 + 1, t11);
        for (unsigned c = 0; c < 4; c++) {
            float r0 = t00[c] + fx * (t10[c] - t00[c]);
            float r1 = t01[c] + fx * (t11[c] - t01[c]);
            a->c[c] += pw * (r0 + fy * (r1 - r0));
        }
    } else {
        const uint8_t *p00 = V.base + (size_t)i0 * V.xs + (size_t)j0 * V.ys;
        const uint8_t *p10 = p00 + V.xs, *p01 = p00 + V.ys, *p11 = p01 + V.xs;
        for (unsigned c = 0; c < nch; c++) {
            float t00 = chan(DT, p00, c), t10 = chan(DT, p10, c);
            float t01 = chan(DT, p01, c), t11 = chan(DT, p11, c);
            float r0 = t00 + fx * (t10 - t00);
            float r1 = t01 + fx * (t11 - t01);
            a->c[c] += pw * (r0 + fy * (r1 - r0));
        }
    }
    a->w += pw;
}

ST_AI void probe_point(const st_set *s, unsigned mode, const st_fp *fp, uint32_t f,
                       unsigned level, float u, float v, float pw, st_acc *a, int DT,
                       unsigned nch, int CH)
{
    st_view V;
    st_view_init(&V, s, f, level);
    int32_t i = st_ifloor(u * (float)V.w), j = st_ifloor(v * (float)V.h);
    /* the face is the closed square: u == 1 (v == 1) reads the last column (row) */
    if (i == V.w && u <= 1.0f)
        i = V.w - 1;
    if (j == V.h && v <= 1.0f)
        j = V.h - 1;
    if (CH && fp->chart &&
        !((uint32_t)i < (uint32_t)V.w && (uint32_t)j < (uint32_t)V.h &&
          fp->ch->level[level][(size_t)j * (size_t)V.w + (size_t)i] == fp->chart)) {
        /* beyond the image or not the query's chart: dropped, or read across a seam */
        st_probe_point_chart(s, mode, fp, level, &V, i, j, pw, a);
        return;
    }
    if (!((uint32_t)i < (uint32_t)V.w && (uint32_t)j < (uint32_t)V.h)) {
        st_probe_point_edge(s, mode, fp, f, level, &V, i, j, pw, a);
        return;
    }
    if (DT == DT_BC1 && V.bw) {
        float t[4];
        bc1_fetch(&V, i, j, t);
        for (unsigned c = 0; c < 4; c++)
            a->c[c] += pw * t[c];
    } else {
        const uint8_t *p = V.base + (size_t)i * V.xs + (size_t)j * V.ys;
        for (unsigned c = 0; c < nch; c++)
            a->c[c] += pw * chan(DT, p, c);
    }
    a->w += pw;
}

/* ---- level selection (docs/sampler.md) --------------------------------------- */

ST_AI void probe_trilinear(const st_set *s, unsigned mode, const st_fp *fp, uint32_t f,
                           unsigned nl, float lod, float u, float v, float pw, st_acc *a, int DT,
                           unsigned nch, int CH)
{
    if (!(lod > 0.0f)) {
        probe_bilinear(s, mode, fp, f, 0, u, v, pw, a, DT, nch, CH);
    } else if (lod >= (float)(nl - 1)) {
        probe_bilinear(s, mode, fp, f, nl - 1, u, v, pw, a, DT, nch, CH);
    } else {
        unsigned L0 = (unsigned)lod;
        float t = lod - (float)L0;
        probe_bilinear(s, mode, fp, f, L0, u, v, pw * (1.0f - t), a, DT, nch, CH);
        if (t > 0.0f)
            probe_bilinear(s, mode, fp, f, L0 + 1, u, v, pw * t, a, DT, nch, CH);
    }
}

/* ---- chart Discard and Traverse (atlas sets) ------------------------------------------------ */

/* The lowest chart id of a listed triangle holding (x, y) (level-0 texel space, closed
 * triangles) among those of near texel k (listed by chart, lowest first), 0 when none does.
 * Out of line: 2-3 % of texels are near on the shared meshes, and the query loop stays small. */
__attribute__((noinline, cold)) static unsigned chart_at_point(const st_chart_ids *ch, size_t k,
                                                               double x, double y)
{
    size_t r = st_bit_rank(ch->near_bits, ch->near_rank, k);
    for (uint32_t n = ch->near_off[r]; n < ch->near_off[r + 1]; n++) {
        uint32_t t = ch->near_tri[n];
        const double *p = &ch->tri_xy[(size_t)t * 6];
        if ((p[2] - p[0]) * (y - p[1]) - (p[3] - p[1]) * (x - p[0]) >= 0 &&
            (p[4] - p[2]) * (y - p[3]) - (p[5] - p[3]) * (x - p[2]) >= 0 &&
            (p[0] - p[4]) * (y - p[5]) - (p[1] - p[5]) * (x - p[4]) >= 0)
            return ch->tri_id[t];
    }
    return 0;
}

/* The chart of a query at (u, v) (docs/sampler.md, "Chart Discard"): the lowest chart of a UV
 * triangle holding (u, v) where the level-0 texel holding it (the image the closed square, as
 * for point) is near (st_chart_ids: a triangle of another chart than its id reaches it);
 * otherwise, and where no triangle holds (u, v), the id of that texel; when that texel has
 * none, the id of the nearest texel centre (binary32 squared distance in texels, the first in
 * row order on a tie) among its 3 x 3 neighbours that have one; else 0 (no chart). */
static unsigned query_chart(const st_chart_ids *ch, const st_face *F, float u, float v)
{
    const int32_t W = (int32_t)F->w, H = (int32_t)F->h;
    const uint16_t *m = ch->level[0];
    float x = u * (float)W, y = v * (float)H;
    int32_t i = st_ifloor(x), j = st_ifloor(y);
    if (i == W && u <= 1.0f)
        i = W - 1;
    if (j == H && v <= 1.0f)
        j = H - 1;
    if ((uint32_t)i < (uint32_t)W && (uint32_t)j < (uint32_t)H) {
        size_t k = (size_t)j * (size_t)W + (size_t)i;
        if (ch->near_bits && st_bit_get(ch->near_bits, k)) {
            unsigned t = chart_at_point(ch, k, (double)u * W, (double)v * H);
            if (t)
                return t;
        }
        if (m[k])
            return m[k];
    }
    unsigned best = 0;
    float bd = INFINITY;
    for (int32_t jj = j - 1; jj <= j + 1; jj++)
        for (int32_t ii = i - 1; ii <= i + 1; ii++) {
            if (!((uint32_t)ii < (uint32_t)W && (uint32_t)jj < (uint32_t)H))
                continue;
            unsigned id = m[(size_t)jj * W + ii];
            float dx = x - ((float)ii + 0.5f), dy = y - ((float)jj + 0.5f);
            float d = dx * dx + dy * dy;
            if (id && d < bd) {
                bd = d;
                best = id;
            }
        }
    return best;
}

/* ---- one query ---------------------------------------------------------------------------- */

static void write_nan(float *out, unsigned nch)
{
    for (unsigned c = 0; c < nch; c++)
        out[c] = NAN;
}

ST_AI int sample_one(const st_set *s, const st_sample_opts *o, unsigned maxa, const st_query *q,
                     float *out, float *cov, int DT, unsigned NCH, int CH)
{
    unsigned nch = NCH ? NCH : s->info.nchan;
    int bad = st_check_query(s, q);
    if (bad) {
        write_nan(out, nch);
        *cov = 0.0f;
        return bad;
    }
    const uint32_t f = q->face;
    const st_face *F = &s->faces[f];
    const unsigned nl = F->nlevels, mode = o->mode;
    const float W0 = (float)F->w, H0 = (float)F->h;
    const float ax = q->dudx * W0, ay = q->dvdx * H0, bx = q->dudy * W0, by = q->dvdy * H0;
    const float rx2 = ax * ax + ay * ay, ry2 = bx * bx + by * by;
    const float rho2 = rx2 > ry2 ? rx2 : ry2;
    st_acc a = {{0.0f, 0.0f, 0.0f, 0.0f}, 0.0f, 0};
    /* lodadj NaN: Traverse's slow path derives min(lod, 0) from rho2 only when it needs it */
    st_fp fp = {q->dudx, q->dvdx, q->dudy, q->dvdy, rho2, NAN, NULL, 0};
    if (CH) { /* chart Discard or Traverse on an atlas: the query's chart */
        fp.ch = s->ext.charts;
        fp.chart = query_chart(fp.ch, F, q->u, q->v);
    }
    float lod = -INFINITY;
    unsigned level = 0;

    switch (o->filter) {
    case ST_FILTER_POINT:
    case ST_FILTER_BILINEAR:
        if (rho2 > 2.0f) /* lod > 0.5: a minified footprint, not level 0 */
            level = st_nearest_level(lod = st_lod_of_rho2(rho2), nl);
        if (o->filter == ST_FILTER_POINT)
            probe_point(s, mode, &fp, f, level, q->u, q->v, 1.0f, &a, DT, nch, CH);
        else
            probe_bilinear(s, mode, &fp, f, level, q->u, q->v, 1.0f, &a, DT, nch, CH);
        break;
    case ST_FILTER_TRILINEAR:
        lod = st_lod_of_rho2(rho2);
        fp.lodadj = lod < 0.0f ? lod : 0.0f;
        probe_trilinear(s, mode, &fp, f, nl, lod, q->u, q->v, 1.0f, &a, DT, nch, CH);
        break;
    default: { /* ST_FILTER_ANISO */
        float rx = sqrtf(rx2), ry = sqrtf(ry2);
        float pmax = rx, pmin = ry, mu = q->dudx, mv = q->dvdx;
        if (ry > rx) {
            pmax = ry;
            pmin = rx;
            mu = q->dudy;
            mv = q->dvdy;
        }
        unsigned N = 1;
        if (pmax > 0.0f) {
            if (pmin * (float)maxa <= pmax) {
                N = maxa;
            } else {
                float r = pmax / pmin; /* in [1, maxa) */
                N = (unsigned)r;
                N += ((float)N < r);
            }
            lod = log2f(pmax / (float)N);
        } else {
            lod = -INFINITY;
        }
        fp.lodadj = lod < 0.0f ? lod : 0.0f;
        if (N == 1) {
            probe_trilinear(s, mode, &fp, f, nl, lod, q->u, q->v, 1.0f, &a, DT, nch, CH);
        } else {
            float pw = 1.0f / (float)N;
            for (unsigned k = 0; k < N; k++) {
                float t = ((float)k + 0.5f) * pw - 0.5f;
                probe_trilinear(s, mode, &fp, f, nl, lod, q->u + t * mu, q->v + t * mv, pw, &a, DT,
                                nch, CH);
            }
        }
        break;
    }
    }

    if (a.w > 0.0f) {
        if (a.w == 1.0f) {
            for (unsigned c = 0; c < nch; c++)
                out[c] = a.c[c];
        } else {
            for (unsigned c = 0; c < nch; c++)
                out[c] = a.c[c] / a.w;
        }
        /* probe weights (1 - t, t; 1/N each) need not sum to exactly 1 in float: a coverage
         * within 2^-20 of 1 is 1 */
        *cov = mode == ST_MODE_CLAMP || a.w > 1.0f - 0x1p-20f ? 1.0f : a.w;
        return ST_Q_OK;
    }
    /* every tap was discarded (Discard, or Traverse with no face to go to) */
    *cov = 0.0f;
    if (o->zero_rule == ST_ZERO_CLAMP) {
        st_acc z = {{0.0f, 0.0f, 0.0f, 0.0f}, 0.0f, 0};
        float u = q->u < 0.0f ? 0.0f : q->u > 1.0f ? 1.0f : q->u;
        float v = q->v < 0.0f ? 0.0f : q->v > 1.0f ? 1.0f : q->v;
        st_lookup_clamped(s, f, st_nearest_level(lod, nl), u, v, 0, 1.0f, &z);
        for (unsigned c = 0; c < nch; c++)
            out[c] = z.c[c] / z.w;
        return ST_Q_OK;
    }
    write_nan(out, nch);
    return ST_Q_ZERO_COVERAGE;
}

ST_AI size_t run(const st_set *s, const st_sample_opts *o, const st_query *q, size_t n,
                 float *out, float *coverage, uint8_t *status, int DT, unsigned NCH, int CH)
{
    unsigned nch = NCH ? NCH : s->info.nchan;
    unsigned maxa = o->max_aniso ? o->max_aniso : 16;
    size_t bad = 0;
    for (size_t i = 0; i < n; i++) {
        float cv;
        int st = sample_one(s, o, maxa, &q[i], out + i * nch, &cv, DT, NCH, CH);
        if (coverage)
            coverage[i] = cv;
        if (status)
            status[i] = (uint8_t)st;
        bad += st != ST_Q_OK;
    }
    return bad;
}

#define ST_VARIANT(name, DT, NCH, CH)                                                        \
    static __attribute__((noinline)) size_t name(const st_set *s, const st_sample_opts *o,  \
                                                 const st_query *q, size_t n, float *out,   \
                                                 float *cov, uint8_t *st)                   \
    {                                                                                        \
        return run(s, o, q, n, out, cov, st, DT, NCH, CH);                                   \
    }
ST_VARIANT(run_u8x4, ST_DT_U8, 4, 0)
ST_VARIANT(run_u8, ST_DT_U8, 0, 0)
ST_VARIANT(run_u16, ST_DT_U16, 0, 0)
ST_VARIANT(run_half, ST_DT_HALF, 0, 0)
ST_VARIANT(run_f32x4, ST_DT_F32, 4, 0)
ST_VARIANT(run_f32, ST_DT_F32, 0, 0)
ST_VARIANT(run_bc1, DT_BC1, 4, 0)
/* chart Discard and Traverse on atlas sets (never BC1: a BC1 set keeps no mesh) */
ST_VARIANT(run_u8x4_ch, ST_DT_U8, 4, 1)
ST_VARIANT(run_u8_ch, ST_DT_U8, 0, 1)
ST_VARIANT(run_u16_ch, ST_DT_U16, 0, 1)
ST_VARIANT(run_half_ch, ST_DT_HALF, 0, 1)
ST_VARIANT(run_f32x4_ch, ST_DT_F32, 4, 1)
ST_VARIANT(run_f32_ch, ST_DT_F32, 0, 1)

typedef size_t (*run_fn)(const st_set *s, const st_sample_opts *o, const st_query *q, size_t n,
                         float *out, float *cov, uint8_t *st);
/* The variants by [chart mode][run_index]: u8 RGBA, u8, u16, half, f32 RGBA, f32. */
static const run_fn RUNS[2][6] = {
    {run_u8x4, run_u8, run_u16, run_half, run_f32x4, run_f32},
    {run_u8x4_ch, run_u8_ch, run_u16_ch, run_half_ch, run_f32x4_ch, run_f32_ch},
};

static unsigned run_index(const st_set_info *in)
{
    switch (in->dtype) {
    case ST_DT_U8: return in->nchan == 4 ? 0 : 1;
    case ST_DT_U16: return 2;
    case ST_DT_HALF: return 3;
    default: return in->nchan == 4 ? 4 : 5;
    }
}

int st_sample_batch(const st_set *s, const st_sample_opts *o, const st_query *q, size_t n,
                    float *out, float *coverage, uint8_t *status)
{
    if (!s || !o || (n && (!q || !out)))
        return ST_EINVAL;
    if (o->mode > ST_MODE_CLAMP || o->zero_rule > ST_ZERO_CLAMP || o->max_aniso > 16)
        return ST_EINVAL;
    if (o->filter >= ST_FILTER_PTEX_POINT && o->filter <= ST_FILTER_PTEX_MITCHELL) {
        if (s->info.kind != ST_KIND_PERFACE)
            return ST_EUNSUPPORTED;
        /* Ptex filter family: registered by ptex/ through the set's extension (the Ptex
         * resolution table it reads), so the sampler does not depend on ptex/ */
        if (!s->ext.filter)
            return ST_EUNSUPPORTED;
        return s->ext.filter(s, o, q, n, out, coverage, status);
    }
    if (o->filter > ST_FILTER_ANISO)
        return ST_EINVAL;
    /* levels >= 1 of a deferred Ptex import (set.h; the Ptex filters above make them in
     * their own entry): nothing below reads a level before this */
    int lrc = st_set_levels(s, NULL);
    if (lrc)
        return lrc;
    if (s->info.meshtype == ST_MESH_TRIANGLE) /* sample_tri.c: point only */
        return st_sample_tri_batch(s, o, q, n, out, coverage, status);
    if (s->info.nchan < 1 || s->info.nchan > ST_MAX_CHANNELS || !st_dtype_size(s->info.dtype))
        return ST_EINVAL;
    if (n > (size_t)INT32_MAX)
        return ST_ETOOBIG;
    const st_chart_ids *ch = s->ext.charts;
    /* chart Discard and chart Traverse (docs/sampler.md): taps off the query's chart are
     * dropped, or (Traverse) read from the texel linked to them across a seam */
    int chart = (o->mode == ST_MODE_DISCARD || o->mode == ST_MODE_TRAVERSE) &&
                s->info.kind == ST_KIND_ATLAS && ch;
    /* the chart data may be built lazily (an atlas opened from a native file) and dropped by
     * the memory budget: built if need be, and pinned while this batch reads it */
    int pinned = 0;
    if (chart && s->ext.charts_pin) {
        int prc = s->ext.charts_pin(s, NULL);
        if (prc)
            return prc;
        pinned = 1;
    }
    chart = chart && ch->nlevels == s->faces[0].nlevels && ch->nlevels;
    size_t bad = s->info.kind == ST_KIND_BC1 /* never a chart mode: a BC1 set keeps no mesh */
                     ? run_bc1(s, o, q, n, out, coverage, status)
                     : RUNS[chart][run_index(&s->info)](s, o, q, n, out, coverage, status);
    if (pinned)
        s->ext.charts_unpin(s);
    return (int)bad;
}

/* ---- names ---------------------------------------------------------------------------------- */

static const char *const mode_names[] = {"discard", "traverse", "clamp"};
static const struct {
    unsigned id;
    const char *name;
} filter_names[] = {
    {ST_FILTER_POINT, "point"},
    {ST_FILTER_BILINEAR, "bilinear"},
    {ST_FILTER_TRILINEAR, "trilinear"},
    {ST_FILTER_ANISO, "aniso"},
    {ST_FILTER_PTEX_POINT, "ptex-point"},
    {ST_FILTER_PTEX_BILINEAR, "ptex-bilinear"},
    {ST_FILTER_PTEX_BOX, "ptex-box"},
    {ST_FILTER_PTEX_GAUSSIAN, "ptex-gaussian"},
    {ST_FILTER_PTEX_BICUBIC, "ptex-bicubic"},
    {ST_FILTER_PTEX_BSPLINE, "ptex-bspline"},
    {ST_FILTER_PTEX_CATMULLROM, "ptex-catmullrom"},
    {ST_FILTER_PTEX_MITCHELL, "ptex-mitchell"},
};

const char *st_mode_name(unsigned mode)
{
    return mode < sizeof mode_names / sizeof *mode_names ? mode_names[mode] : NULL;
}

const char *st_filter_name(unsigned filter)
{
    for (size_t i = 0; i < sizeof filter_names / sizeof *filter_names; i++)
        if (filter_names[i].id == filter)
            return filter_names[i].name;
    return NULL;
}

int st_mode_parse(const char *name)
{
    for (unsigned i = 0; name && i < sizeof mode_names / sizeof *mode_names; i++)
        if (!strcmp(mode_names[i], name))
            return (int)i;
    return -1;
}

int st_filter_parse(const char *name)
{
    for (size_t i = 0; name && i < sizeof filter_names / sizeof *filter_names; i++)
        if (!strcmp(filter_names[i].name, name))
            return (int)filter_names[i].id;
    return -1;
}

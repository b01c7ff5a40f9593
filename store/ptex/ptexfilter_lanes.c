/* store/ptex/ptexfilter_lanes.c - Ptex's in-face bilinear on 8 queries at once (AVX2 + FMA +
 * F16C, chosen at run time) or 4 (SSE2), one query per lane (ptexfilter_lanes.h).
 *
 * The per-query bilinear (ptexfilter.c: the batch's checks, open_face, bilinear_kernel,
 * bilinear_fits, bilinear_write) spends most of its ~200 instructions on one query's
 * bookkeeping: loading and checking it, the kernel set-up of two axes in one SSE vector, the
 * table look-up through three dependent loads, the division. Here the same operations run
 * lane by lane on 8 (4) queries:
 *   1. the queries are transposed into one vector per field (face, u, v, derivatives);
 *   2. the checks: face in range, derivatives within ST_MAX_DERIV (NaN fails), u and v in
 *      [0, 1), the face's flags (gathered from the face table: ulog2, vlog2, flags in one
 *      32-bit word) and its lanef byte (ptexres.h: the neighbourhood-constant bit, and the
 *      mesh boundary edges that decide where a handed-over kernel may go);
 *   3. bilinear_kernel's arithmetic per axis (width and blur, clamps, the resolution from the
 *      exponent, pixel position, branchless floor, fraction) and bilinear_fits' test, in
 *      float (fl >= 0, fl + 1 < 2^r, fraction > 0: exact for these small integers);
 *   4. the table entry px[base[f] + ru * (vlog2 + 1) + rv] and the texel address (64-bit
 *      lanes), gathered only for the lanes served;
 *   5. the 2 x 2 texels: one channel in lanes (a 32-bit gather per row holds both texels of a
 *      u8, u16 or half row, a 64-bit gather both of a float row), several channels per lane
 *      (4 lanes of channels, as bilinear_write does);
 *   6. (t00 ku0 + t01 fu) kv0 + (t10 ku0 + t11 fu) fv times 1 / ((ku0 + fu)(kv0 + fv) one),
 *      multiplies and adds as written (no fused multiply-adds: C11 mode does not contract, and
 *      every product here is its own intrinsic), the division a true division;
 *   7. (8 lanes, since session 19) a lane on a constant face whose kernel lies inside it (a
 *      zero fraction's tap stripped): 0 + texel (ku0 + fu)(kv0 + fv) times the same scale,
 *      ptexfilter.c's const_write (const_lanes8).
 * Every step is an IEEE operation on the same operands as the scalar code's, so each lane's
 * result is bit for bit the per-query path's (test_ptexfilter_paths compares both lane
 * counts with the general path on every shared file). Lanes that fail a test are only masked:
 * their gathers are not made (masked gathers read nothing for them) and the caller serves
 * them afterwards.
 *
 * The box and width-4 filters (pf_kernel_lanes_select, AVX2 only): steps 1 and 2 on 8
 * queries, then kernel_qi's widths (|du/dx| + |du/dy|, times width, plus blur: a multiply and
 * an add, not fused) and its test for the fused path (width-4: widths under 1/4, NaN offered,
 * a face of at least 8 x 8 texels), and the face's row of the resolution table (base[f],
 * gathered for the plain lanes); the caller (kernel_run) gives these to the 8-query fused
 * path (ptexfilter_simd.c's pf_box8_select, pf_w4x8_select), calls the fused path per query
 * for the lanes it leaves, and serves the others one by one. Same operations, same
 * operands: the same bits.
 *
 * Owns: nothing but these loops.
 */
#include "ptexfilter_lanes.h"

#include <math.h>
#include <stddef.h>
#include <string.h>

#include "ptex_format.h"
#include "ptexfilter_kernel.h"

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>

/* The face's ulog2, vlog2, nlevels and flags are one aligned 32-bit word (one gather). */
_Static_assert(offsetof(st_face, ulog2) % 4 == 0 &&
                   offsetof(st_face, vlog2) == offsetof(st_face, ulog2) + 1 &&
                   offsetof(st_face, flags) == offsetof(st_face, ulog2) + 3 &&
                   sizeof(st_face) == 64,
               "st_face layout: ulog2, vlog2, nlevels, flags in one word, 64 bytes a face");
enum { PL_FACE_WORDS = sizeof(st_face) / 4 };

static float one_of(unsigned dt)
{
    return dt == ST_DT_U8 ? 255.0f : dt == ST_DT_U16 ? 65535.0f : 1.0f;
}

/* The edges a handed-over 2 x 2 kernel overhangs, as pf_lanes lanef's boundary bits (bit
 * 4 + e: past edge e): pf_lanes_kern's open and inside for one lane. */
static inline unsigned pl_overhang(int ru, int rv, int ui, int vi, float fu, float fv)
{
    return (vi < 0 ? 0x10u : 0u) | (fu != 0.0f && ui + 2 > 1 << ru ? 0x20u : 0u) |
           (fv != 0.0f && vi + 2 > 1 << rv ? 0x40u : 0u) | (ui < 0 ? 0x80u : 0u);
}

/* ---- 8 lanes (AVX2) --------------------------------------------------------------------- */

#define PL_TARGET __attribute__((target("avx2,fma,f16c"), always_inline)) static inline

/* One axis of bilinear_kernel, lane by lane, for W lanes (float vector V, int32 vector I of
 * the same size; ATTR the function's target): x the coordinate, w the width (|d/dx| +
 * |d/dy|), lg the face's log2 size; r the resolution, fl the first texel (a float), fr the
 * fraction; returns the lanes whose 2 x 2 texels lie inside the face (fl >= 0, fl + 1 < 2^r,
 * fr > 0, exact for these small integers). The same operations as the scalar code's (min and
 * max as its compare-and-select: minps and maxps pick the same operand, NaN included). One
 * text for both lane counts. */
#define PL_AXIS(NAME, ATTR, V, I)                                                           \
    ATTR I NAME(V x, V w, I lg, float width, float blur, I *r, V *fl, V *fr)                 \
    {                                                                                       \
        const V one = (V){0} + 1.0f, zero = (V){0};                                         \
        w = w * width + blur;                                                               \
        I lt = w < one;                                                                     \
        w = (V)((lt & (I)w) | (~lt & (I)one));                 /* bu < 1 ? bu : 1 */        \
        V lo = (V)((127 - lg) << 23);                                                       \
        I gt = w > lo;                                                                      \
        w = (V)((gt & (I)w) | (~gt & (I)lo));                  /* bu > lu ? bu : lu */      \
        *r = 127 - (((I)w >> 23) & 0xff);                                                   \
        V rf = (V)((*r + 127) << 23);                          /* 2^r */                    \
        V pix = x * rf - 0.5f;                                                              \
        V t = __builtin_convertvector(__builtin_convertvector(pix, I), V); /* pk_floor */     \
        *fl = t - (V)((I)(t > pix) & (I)one);                                               \
        *fr = pix - *fl;                                                                    \
        return (*fl >= zero) & (*fl + 1.0f < rf) & (*fr > zero);                            \
    }

typedef int32_t pl_v8i __attribute__((vector_size(32)));
typedef float pl_v8f __attribute__((vector_size(32)));
typedef int32_t pl_v4i __attribute__((vector_size(16)));
typedef float pl_v4f __attribute__((vector_size(16)));

PL_AXIS(axis8, PL_TARGET, pl_v8f, pl_v8i)

/* Rows [x[lo] .. x[lo + 3] | y[lo] .. y[lo + 3]] of 8 queries, transposed: 4 fields. */
PL_TARGET void fields8(const st_query *q, size_t off, __m256 f[4])
{
    /* written out (no array): the four rows stay in registers */
#define PL_ROW8(i)                                                                          \
    _mm256_insertf128_ps(                                                                   \
        _mm256_castps128_ps256(_mm_loadu_ps((const float *)(const void *)((const uint8_t *)&q[i] + off))), \
        _mm_loadu_ps((const float *)(const void *)((const uint8_t *)&q[(i) + 4] + off)), 1)
    __m256 r0 = PL_ROW8(0), r1 = PL_ROW8(1), r2 = PL_ROW8(2), r3 = PL_ROW8(3);
#undef PL_ROW8
    __m256 t0 = _mm256_unpacklo_ps(r0, r1), t1 = _mm256_unpackhi_ps(r0, r1);
    __m256 t2 = _mm256_unpacklo_ps(r2, r3), t3 = _mm256_unpackhi_ps(r2, r3);
    f[0] = _mm256_shuffle_ps(t0, t2, 0x44);
    f[1] = _mm256_shuffle_ps(t0, t2, 0xee);
    f[2] = _mm256_shuffle_ps(t1, t3, 0x44);
    f[3] = _mm256_shuffle_ps(t1, t3, 0xee);
}

/* The texels at a and b (type DT, 4 values each: as bilinear_write loads one) as the low and
 * the high 4 lanes. */
PL_TARGET __m256 texel2(const uint8_t *a, const uint8_t *b, unsigned DT)
{
    switch (DT) {
    case ST_DT_U8: {
        int x, y;
        memcpy(&x, a, 4);
        memcpy(&y, b, 4);
        return _mm256_cvtepi32_ps(
            _mm256_cvtepu8_epi32(_mm_unpacklo_epi32(_mm_cvtsi32_si128(x), _mm_cvtsi32_si128(y))));
    }
    case ST_DT_U16:
        return _mm256_cvtepi32_ps(_mm256_cvtepu16_epi32(
            _mm_unpacklo_epi64(_mm_loadl_epi64((const __m128i *)(const void *)a),
                               _mm_loadl_epi64((const __m128i *)(const void *)b))));
    case ST_DT_HALF:
        return _mm256_cvtph_ps(_mm_unpacklo_epi64(_mm_loadl_epi64((const __m128i *)(const void *)a),
                                                  _mm_loadl_epi64((const __m128i *)(const void *)b)));
    default:
        return _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps((const float *)(const void *)a)),
                                    _mm_loadu_ps((const float *)(const void *)b), 1);
    }
}

/* The first texel's address (p0) and the next row's (p1) of 4 lanes (64-bit) whose mask m32
 * is set (m64: the mask widened): the table entry px[base[f] + idx], plus off texels of ts
 * bytes; a row is ts << ru bytes. */
PL_TARGET void addr4(const pf_lanes *c, __m128i m32, __m128i f32, __m128i i32, __m128i o32,
                     __m128i r32, __m256i ts64, __m256i *m64, __m256i *p0, __m256i *p1)
{
    const __m256i zero = _mm256_setzero_si256();
    *m64 = _mm256_cvtepi32_epi64(m32);
    __m256i b = _mm256_mask_i32gather_epi64(zero, (const long long *)(const void *)c->base, f32,
                                            *m64, 8);
    __m256i e = _mm256_add_epi64(b, _mm256_cvtepu32_epi64(i32));
    __m256i d = _mm256_mask_i64gather_epi64(zero, (const long long *)(const void *)c->px, e,
                                            *m64, 8);
    *p0 = _mm256_add_epi64(d, _mm256_mul_epu32(_mm256_cvtepu32_epi64(o32), ts64));
    *p1 = _mm256_add_epi64(*p0, _mm256_sllv_epi64(ts64, _mm256_cvtepu32_epi64(r32)));
}

/* Steps 1 and 2 of 8 queries, for lanes8 and klanes8: the query checks (face < nfaces,
 * every derivative within ST_MAX_DERIV, 0 <= u, v < 1; a NaN fails), then the face's row and
 * lane byte gathered and the lanes of subfaces, constant faces and faces next to a constant
 * one dropped (o->m; o->mok the lanes before the drop, o->bad their flags that drop one:
 * lanes8 serves a constant face's, klanes8 does not). Returns 0, o left unset, when no query
 * passes the checks. */
typedef struct {
    __m256i face, fw, pxf, m;
    __m256i mok, bad; /* the lanes that passed the query checks; their flags that drop one */
    __m256 u, v, ax, bx, ay, by;
} pl_q8;

PL_TARGET int q8_checks(const pf_lanes *c, const st_query *q, pl_q8 *o)
{
    __m256 fa[4], fb[4];
    fields8(q, 0, fa);  /* face u v dudx */
    fields8(q, 12, fb); /* dudx dvdx dudy dvdy */
    const __m256 absm = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
    const __m256 lim = _mm256_set1_ps(ST_MAX_DERIV), one = _mm256_set1_ps(1.0f);
    __m256i face = _mm256_castps_si256(fa[0]);
    __m256 u = fa[1], v = fa[2];
    __m256 ax = _mm256_and_ps(fb[0], absm), bx = _mm256_and_ps(fb[1], absm);
    __m256 ay = _mm256_and_ps(fb[2], absm), by = _mm256_and_ps(fb[3], absm);
    /* face < nfaces, unsigned */
    const __m256i sgn = _mm256_set1_epi32((int)0x80000000u);
    __m256i fok = _mm256_cmpgt_epi32(_mm256_set1_epi32((int)(c->nfaces ^ 0x80000000u)),
                                     _mm256_xor_si256(face, sgn));
    __m256 ok = _mm256_and_ps(_mm256_and_ps(_mm256_cmp_ps(ax, lim, _CMP_LE_OQ),
                                            _mm256_cmp_ps(bx, lim, _CMP_LE_OQ)),
                              _mm256_and_ps(_mm256_cmp_ps(ay, lim, _CMP_LE_OQ),
                                            _mm256_cmp_ps(by, lim, _CMP_LE_OQ)));
    ok = _mm256_and_ps(ok, _mm256_and_ps(_mm256_cmp_ps(u, _mm256_setzero_ps(), _CMP_GE_OQ),
                                         _mm256_cmp_ps(u, one, _CMP_LT_OQ)));
    ok = _mm256_and_ps(ok, _mm256_and_ps(_mm256_cmp_ps(v, _mm256_setzero_ps(), _CMP_GE_OQ),
                                         _mm256_cmp_ps(v, one, _CMP_LT_OQ)));
    ok = _mm256_and_ps(ok, _mm256_castsi256_ps(fok));
    if (_mm256_testz_ps(ok, ok))
        return 0;
    __m256i m = _mm256_castps_si256(ok);
    const int *fw0 = (const int *)(const void *)((const uint8_t *)c->faces +
                                                 offsetof(st_face, ulog2));
    __m256i fw = _mm256_mask_i32gather_epi32(_mm256_setzero_si256(), fw0,
                                             _mm256_slli_epi32(face, 4), m, 4);
    __m256i pxf = _mm256_mask_i32gather_epi32(_mm256_setzero_si256(),
                                              (const int *)(const void *)c->lanef, face, m, 1);
    const __m256i zero = _mm256_setzero_si256();
    __m256i bad = _mm256_or_si256(
        _mm256_and_si256(pxf, _mm256_set1_epi32(PTX_FLAG_NBCONSTANT)),
        _mm256_and_si256(_mm256_srli_epi32(fw, 24),
                         _mm256_set1_epi32(ST_FACE_SUBFACE | ST_FACE_CONSTANT)));
    o->mok = m;
    o->bad = bad;
    m = _mm256_andnot_si256(_mm256_cmpgt_epi32(bad, zero), m);
    o->face = face;
    o->fw = fw;
    o->pxf = pxf;
    o->m = m;
    o->u = u;
    o->v = v;
    o->ax = ax;
    o->bx = bx;
    o->ay = ay;
    o->by = by;
    return 1;
}

static inline __m128 texel4(const uint8_t *p, unsigned DT);

/* The lanes of cmask, whose kernel lies inside a constant face (ptexfilter.c's bilinear_q
 * and const_write): the face's texel (table entry 0) times the kernel's weight
 * (ku0 + fu)(kv0 + fv) (with a zero fraction the stripped axis' 0 + 1: the same 1), added to
 * zero, times 1 / (weight one), a lane at a time; after the plain lanes' stores (which may
 * write whole vectors). */
PL_TARGET unsigned const_lanes8(const pf_lanes *c, unsigned cmask, __m256i face, __m256 fu,
                                __m256 fv, float *out, unsigned DT, unsigned NC)
{
    const __m256 one = _mm256_set1_ps(1.0f);
    __m256 w = _mm256_mul_ps(_mm256_add_ps(_mm256_sub_ps(one, fu), fu),
                             _mm256_add_ps(_mm256_sub_ps(one, fv), fv));
    __m256 sc = _mm256_div_ps(one, _mm256_mul_ps(w, _mm256_set1_ps(one_of(DT))));
    float wl[8], sl[8];
    uint32_t fl[8];
    _mm256_storeu_ps(wl, w);
    _mm256_storeu_ps(sl, sc);
    _mm256_storeu_si256((__m256i *)(void *)fl, face);
    for (unsigned rest = cmask; rest; rest &= rest - 1) {
        int j = __builtin_ctz(rest);
        __m128 acc = _mm_add_ps(_mm_setzero_ps(), _mm_mul_ps(texel4(c->px[c->base[fl[j]]], DT),
                                                             _mm_set1_ps(wl[j])));
        float res[4];
        _mm_storeu_ps(res, _mm_mul_ps(acc, _mm_set1_ps(sl[j])));
        memcpy(out + (size_t)j * NC, res, NC * sizeof(float));
    }
    return cmask;
}

/* 8 queries of texels of type DT with NC channels; the lanes on a constant face whose 2 x 2
 * texels lie inside it served too. */
PL_TARGET unsigned lanes8(const pf_lanes *c, const st_query *q, float *out, pf_lanes_kern *k,
                          unsigned *edge, unsigned DT, unsigned NC)
{
    _Static_assert(offsetof(st_query, u) == 4 && offsetof(st_query, dudx) == 12 &&
                       offsetof(st_query, dvdy) == 24,
                   "st_query: face u v dudx dvdx dudy dvdy");
    pl_q8 q8;
    *edge = 0;
    if (!q8_checks(c, q, &q8))
        return 0;
    const __m256 one = _mm256_set1_ps(1.0f);
    const __m256i zero = _mm256_setzero_si256(), ff = _mm256_set1_epi32(0xff);
    __m256i face = q8.face, fw = q8.fw, pxf = q8.pxf, m = q8.m;
    __m256 u = q8.u, v = q8.v, ax = q8.ax, bx = q8.bx, ay = q8.ay, by = q8.by;
    /* the lanes on a constant face (not a subface, no constant neighbourhood: the flags
     * that drop it are CONSTANT alone), looked for only when a lane was dropped */
    unsigned pm = (unsigned)_mm256_movemask_ps(_mm256_castsi256_ps(m));
    __m256i cm = zero;
    if (pm != 0xffu)
        cm = _mm256_and_si256(_mm256_cmpeq_epi32(q8.bad, _mm256_set1_epi32(ST_FACE_CONSTANT)),
                              q8.mok);
    if (!pm && _mm256_testz_si256(cm, cm))
        return 0; /* subfaces, faces with a constant neighbourhood: nothing for the lanes */
    __m256i lu = _mm256_and_si256(fw, ff), lv = _mm256_and_si256(_mm256_srli_epi32(fw, 8), ff);
    pl_v8i ru8, rv8;
    pl_v8f flu8, flv8, fu8, fv8;
    pl_v8i in = axis8((pl_v8f)u, (pl_v8f)_mm256_add_ps(ax, ay), (pl_v8i)lu, c->width, c->blur,
                      &ru8, &flu8, &fu8) &
                axis8((pl_v8f)v, (pl_v8f)_mm256_add_ps(bx, by), (pl_v8i)lv, c->width, c->blur,
                      &rv8, &flv8, &fv8);
    __m256i plain = m;
    m = _mm256_and_si256(m, (__m256i)in);
    __m256i ru = (__m256i)ru8, rv = (__m256i)rv8;
    __m256 flu = (__m256)flu8, flv = (__m256)flv8, fu = (__m256)fu8, fv = (__m256)fv8;
    __m256i ui = _mm256_cvttps_epi32(flu), vi = _mm256_cvttps_epi32(flv);
    /* the lanes on a constant face whose kernel lies inside it (const_lanes8), a zero
     * fraction's tap stripped (bilinear_q's test: fl >= 0, fl + 2 or 1 <= 2^r) */
    unsigned cmask = 0;
    if (pm != 0xffu && !_mm256_testz_si256(cm, cm)) {
        const __m256 two = _mm256_set1_ps(2.0f), zf = _mm256_setzero_ps();
        const __m256i e127 = _mm256_set1_epi32(127);
        __m256 rfu = _mm256_castsi256_ps(_mm256_slli_epi32(_mm256_add_epi32(ru, e127), 23));
        __m256 rfv = _mm256_castsi256_ps(_mm256_slli_epi32(_mm256_add_epi32(rv, e127), 23));
        __m256 nu = _mm256_blendv_ps(one, two, _mm256_cmp_ps(fu, zf, _CMP_NEQ_UQ));
        __m256 nv = _mm256_blendv_ps(one, two, _mm256_cmp_ps(fv, zf, _CMP_NEQ_UQ));
        __m256 cin = _mm256_and_ps(
            _mm256_and_ps(_mm256_cmp_ps(flu, zf, _CMP_GE_OQ),
                          _mm256_cmp_ps(_mm256_add_ps(flu, nu), rfu, _CMP_LE_OQ)),
            _mm256_and_ps(_mm256_cmp_ps(flv, zf, _CMP_GE_OQ),
                          _mm256_cmp_ps(_mm256_add_ps(flv, nv), rfv, _CMP_LE_OQ)));
        cmask = (unsigned)_mm256_movemask_ps(_mm256_and_ps(_mm256_castsi256_ps(cm), cin));
    }
    unsigned mask = (unsigned)_mm256_movemask_ps(_mm256_castsi256_ps(m));
    *edge = (unsigned)_mm256_movemask_ps(_mm256_castsi256_ps(plain)) & ~mask;
    if (*edge) { /* the kernel set-up of the lanes handed over */
        _mm256_storeu_si256((__m256i *)(void *)k->ru, ru);
        _mm256_storeu_si256((__m256i *)(void *)k->rv, rv);
        _mm256_storeu_si256((__m256i *)(void *)k->ui, ui);
        _mm256_storeu_si256((__m256i *)(void *)k->vi, vi);
        _mm256_storeu_ps(k->fu, fu);
        _mm256_storeu_ps(k->fv, fv);
        /* the edges each kernel overhangs (pl_overhang's), each against its boundary bit of
         * lanef (gathered above) shifted to the sign: a sign set is a blocked lane */
        const __m256i one32 = _mm256_set1_epi32(1), two32 = _mm256_set1_epi32(2);
        __m256i fun = _mm256_castps_si256(_mm256_cmp_ps(fu, _mm256_setzero_ps(), _CMP_NEQ_UQ));
        __m256i fvn = _mm256_castps_si256(_mm256_cmp_ps(fv, _mm256_setzero_ps(), _CMP_NEQ_UQ));
        __m256i ovb = _mm256_cmpgt_epi32(zero, vi), ovl = _mm256_cmpgt_epi32(zero, ui);
        __m256i ovr = _mm256_and_si256(fun, _mm256_cmpgt_epi32(_mm256_add_epi32(ui, two32),
                                                               _mm256_sllv_epi32(one32, ru)));
        __m256i ovt = _mm256_and_si256(fvn, _mm256_cmpgt_epi32(_mm256_add_epi32(vi, two32),
                                                               _mm256_sllv_epi32(one32, rv)));
        __m256i blocked = _mm256_or_si256(
            _mm256_or_si256(_mm256_and_si256(ovb, _mm256_slli_epi32(pxf, 27)),
                            _mm256_and_si256(ovr, _mm256_slli_epi32(pxf, 26))),
            _mm256_or_si256(_mm256_and_si256(ovt, _mm256_slli_epi32(pxf, 25)),
                            _mm256_and_si256(ovl, _mm256_slli_epi32(pxf, 24))));
        __m256i over = _mm256_or_si256(_mm256_or_si256(ovb, ovr), _mm256_or_si256(ovt, ovl));
        k->inside = ~(unsigned)_mm256_movemask_ps(_mm256_castsi256_ps(over)) & *edge;
        k->open = ~(unsigned)_mm256_movemask_ps(_mm256_castsi256_ps(blocked)) & *edge;
    }
    if (!mask)
        return cmask ? const_lanes8(c, cmask, face, fu, fv, out, DT, NC) : 0u;
    /* the table entry of (ru, rv) and the first texel's address, 64-bit lanes 0-3 / 4-7 */
    __m256i idx = _mm256_add_epi32(_mm256_mullo_epi32(ru, _mm256_add_epi32(lv, _mm256_set1_epi32(1))), rv);
    __m256i off = _mm256_add_epi32(_mm256_sllv_epi32(vi, ru), ui); /* < 2^30 */
    const size_t ts = st_dtype_size(DT) * NC;
    const __m256i ts64 = _mm256_set1_epi64x((long long)ts);
    __m256i p0[2], p1[2], m64[2];
    __m128i m32[2] = {_mm256_castsi256_si128(m), _mm256_extracti128_si256(m, 1)};
    /* each half written out (no loop over arrays: the halves stay in registers) */
    addr4(c, m32[0], _mm256_castsi256_si128(face), _mm256_castsi256_si128(idx),
          _mm256_castsi256_si128(off), _mm256_castsi256_si128(ru), ts64, &m64[0], &p0[0], &p1[0]);
    addr4(c, m32[1], _mm256_extracti128_si256(face, 1), _mm256_extracti128_si256(idx, 1),
          _mm256_extracti128_si256(off, 1), _mm256_extracti128_si256(ru, 1), ts64, &m64[1],
          &p0[1], &p1[1]);
    __m256 ku0 = _mm256_sub_ps(one, fu), kv0 = _mm256_sub_ps(one, fv);
    __m256 scale = _mm256_div_ps(
        one, _mm256_mul_ps(_mm256_mul_ps(_mm256_add_ps(ku0, fu), _mm256_add_ps(kv0, fv)),
                           _mm256_set1_ps(one_of(DT))));
    if (NC == 1) {
        __m256 t00, t01, t10, t11;
        if (DT == ST_DT_F32) {
            /* a 64-bit gather per row: both texels */
            __m256 g[2][2];
            for (int h = 0; h < 2; h++) {
                g[0][h] = _mm256_castsi256_ps(_mm256_mask_i64gather_epi64(zero, (const long long *)0, p0[h], m64[h], 1));
                g[1][h] = _mm256_castsi256_ps(_mm256_mask_i64gather_epi64(zero, (const long long *)0, p1[h], m64[h], 1));
            }
            /* [lane 0 1 4 5 | 2 3 6 7] in 64-bit pairs -> lanes in order */
            t00 = _mm256_castpd_ps(_mm256_permute4x64_pd(_mm256_castps_pd(_mm256_shuffle_ps(g[0][0], g[0][1], 0x88)), 0xd8));
            t01 = _mm256_castpd_ps(_mm256_permute4x64_pd(_mm256_castps_pd(_mm256_shuffle_ps(g[0][0], g[0][1], 0xdd)), 0xd8));
            t10 = _mm256_castpd_ps(_mm256_permute4x64_pd(_mm256_castps_pd(_mm256_shuffle_ps(g[1][0], g[1][1], 0x88)), 0xd8));
            t11 = _mm256_castpd_ps(_mm256_permute4x64_pd(_mm256_castps_pd(_mm256_shuffle_ps(g[1][0], g[1][1], 0xdd)), 0xd8));
        } else {
            /* a 32-bit gather per row: both texels (u8 and u16 / half) */
            __m256i g[2];
            for (int row = 0; row < 2; row++) {
                const __m256i *p = row ? p1 : p0;
                __m128i lo = _mm256_mask_i64gather_epi32(_mm_setzero_si128(), (const int *)0, p[0], m32[0], 1);
                __m128i hi = _mm256_mask_i64gather_epi32(_mm_setzero_si128(), (const int *)0, p[1], m32[1], 1);
                g[row] = _mm256_inserti128_si256(_mm256_castsi128_si256(lo), hi, 1);
            }
            if (DT == ST_DT_U8) {
                t00 = _mm256_cvtepi32_ps(_mm256_and_si256(g[0], ff));
                t01 = _mm256_cvtepi32_ps(_mm256_and_si256(_mm256_srli_epi32(g[0], 8), ff));
                t10 = _mm256_cvtepi32_ps(_mm256_and_si256(g[1], ff));
                t11 = _mm256_cvtepi32_ps(_mm256_and_si256(_mm256_srli_epi32(g[1], 8), ff));
            } else if (DT == ST_DT_U16) {
                const __m256i fff = _mm256_set1_epi32(0xffff);
                t00 = _mm256_cvtepi32_ps(_mm256_and_si256(g[0], fff));
                t01 = _mm256_cvtepi32_ps(_mm256_srli_epi32(g[0], 16));
                t10 = _mm256_cvtepi32_ps(_mm256_and_si256(g[1], fff));
                t11 = _mm256_cvtepi32_ps(_mm256_srli_epi32(g[1], 16));
            } else {
                /* half: [lo halves 0-3, hi 0-3 | lo 4-7, hi 4-7] -> lo 0-7, hi 0-7 */
                const __m256i fff = _mm256_set1_epi32(0xffff);
                __m256i a = _mm256_permute4x64_epi64(
                    _mm256_packus_epi32(_mm256_and_si256(g[0], fff), _mm256_srli_epi32(g[0], 16)), 0xd8);
                __m256i b = _mm256_permute4x64_epi64(
                    _mm256_packus_epi32(_mm256_and_si256(g[1], fff), _mm256_srli_epi32(g[1], 16)), 0xd8);
                t00 = _mm256_cvtph_ps(_mm256_castsi256_si128(a));
                t01 = _mm256_cvtph_ps(_mm256_extracti128_si256(a, 1));
                t10 = _mm256_cvtph_ps(_mm256_castsi256_si128(b));
                t11 = _mm256_cvtph_ps(_mm256_extracti128_si256(b, 1));
            }
        }
        __m256 r0 = _mm256_add_ps(_mm256_mul_ps(t00, ku0), _mm256_mul_ps(t01, fu));
        __m256 r1 = _mm256_add_ps(_mm256_mul_ps(t10, ku0), _mm256_mul_ps(t11, fu));
        __m256 acc = _mm256_add_ps(_mm256_mul_ps(r0, kv0), _mm256_mul_ps(r1, fv));
        _mm256_storeu_ps(out, _mm256_mul_ps(acc, scale));
        return mask | (cmask ? const_lanes8(c, cmask, face, fu, fv, out, DT, NC) : 0u);
    }
    if (NC >= 3) {
        /* two lanes a vector: lane 2k's texel in the low 4 lanes, lane 2k + 1's in the high 4
         * (bilinear_write's operations on each); a lane not served reads zeros */
        static const uint8_t zeros[64];
        const __m256i safe = _mm256_set1_epi64x((long long)(uintptr_t)zeros);
        uint64_t b0[8], b1[8];
        for (int h = 0; h < 2; h++) {
            _mm256_storeu_si256((__m256i *)(void *)(b0 + 4 * h), _mm256_blendv_epi8(safe, p0[h], m64[h]));
            _mm256_storeu_si256((__m256i *)(void *)(b1 + 4 * h), _mm256_blendv_epi8(safe, p1[h], m64[h]));
        }
        const __m256i sel = _mm256_setr_epi32(0, 0, 0, 0, 1, 1, 1, 1);
        for (int k = 0; k < 4; k++) {
            if (!(mask >> (2 * k) & 3))
                continue;
            __m256i ix = _mm256_add_epi32(sel, _mm256_set1_epi32(2 * k));
            const uint8_t *pa = (const uint8_t *)(uintptr_t)b0[2 * k];
            const uint8_t *pb = (const uint8_t *)(uintptr_t)b0[2 * k + 1];
            const uint8_t *qa = (const uint8_t *)(uintptr_t)b1[2 * k];
            const uint8_t *qb = (const uint8_t *)(uintptr_t)b1[2 * k + 1];
            __m256 a = _mm256_permutevar8x32_ps(ku0, ix), b = _mm256_permutevar8x32_ps(fu, ix);
            __m256 r0 = _mm256_add_ps(_mm256_mul_ps(texel2(pa, pb, DT), a),
                                      _mm256_mul_ps(texel2(pa + ts, pb + ts, DT), b));
            __m256 r1 = _mm256_add_ps(_mm256_mul_ps(texel2(qa, qb, DT), a),
                                      _mm256_mul_ps(texel2(qa + ts, qb + ts, DT), b));
            __m256 acc = _mm256_add_ps(_mm256_mul_ps(r0, _mm256_permutevar8x32_ps(kv0, ix)),
                                       _mm256_mul_ps(r1, _mm256_permutevar8x32_ps(fv, ix)));
            __m256 res = _mm256_mul_ps(acc, _mm256_permutevar8x32_ps(scale, ix));
            float *o = out + (size_t)(2 * k) * NC;
            if (NC == 4) {
                _mm256_storeu_ps(o, res);
            } else {
                __m128 lo = _mm256_castps256_ps128(res), hi = _mm256_extractf128_ps(res, 1);
                _mm_storel_pi((__m64 *)(void *)o, lo);
                _mm_store_ss(o + 2, _mm_movehl_ps(lo, lo));
                _mm_storel_pi((__m64 *)(void *)(o + 3), hi);
                _mm_store_ss(o + 5, _mm_movehl_ps(hi, hi));
            }
        }
        return mask | (cmask ? const_lanes8(c, cmask, face, fu, fv, out, DT, NC) : 0u);
    }
    /* two channels: one lane's texels in 4 lanes, as bilinear_write */
    uint64_t a0[8], a1[8];
    float k0[8], k1[8], w0[8], w1[8], sc[8];
    for (int h = 0; h < 2; h++) {
        _mm256_storeu_si256((__m256i *)(void *)(a0 + 4 * h), p0[h]);
        _mm256_storeu_si256((__m256i *)(void *)(a1 + 4 * h), p1[h]);
    }
    _mm256_storeu_ps(k0, ku0);
    _mm256_storeu_ps(k1, fu);
    _mm256_storeu_ps(w0, kv0);
    _mm256_storeu_ps(w1, fv);
    _mm256_storeu_ps(sc, scale);
    for (unsigned rest = mask; rest; rest &= rest - 1) {
        int j = __builtin_ctz(rest);
        const uint8_t *p = (const uint8_t *)(uintptr_t)a0[j], *p1r = (const uint8_t *)(uintptr_t)a1[j];
        __m128 x00, x01, x10, x11;
        switch (DT) {
        case ST_DT_U8: {
            int b00, b01, b10, b11;
            memcpy(&b00, p, 4);
            memcpy(&b01, p + ts, 4);
            memcpy(&b10, p1r, 4);
            memcpy(&b11, p1r + ts, 4);
            x00 = _mm_cvtepi32_ps(_mm_cvtepu8_epi32(_mm_cvtsi32_si128(b00)));
            x01 = _mm_cvtepi32_ps(_mm_cvtepu8_epi32(_mm_cvtsi32_si128(b01)));
            x10 = _mm_cvtepi32_ps(_mm_cvtepu8_epi32(_mm_cvtsi32_si128(b10)));
            x11 = _mm_cvtepi32_ps(_mm_cvtepu8_epi32(_mm_cvtsi32_si128(b11)));
            break;
        }
        case ST_DT_U16:
            x00 = _mm_cvtepi32_ps(_mm_cvtepu16_epi32(_mm_loadl_epi64((const __m128i *)(const void *)p)));
            x01 = _mm_cvtepi32_ps(_mm_cvtepu16_epi32(_mm_loadl_epi64((const __m128i *)(const void *)(p + ts))));
            x10 = _mm_cvtepi32_ps(_mm_cvtepu16_epi32(_mm_loadl_epi64((const __m128i *)(const void *)p1r)));
            x11 = _mm_cvtepi32_ps(_mm_cvtepu16_epi32(_mm_loadl_epi64((const __m128i *)(const void *)(p1r + ts))));
            break;
        case ST_DT_HALF:
            x00 = _mm_cvtph_ps(_mm_loadl_epi64((const __m128i *)(const void *)p));
            x01 = _mm_cvtph_ps(_mm_loadl_epi64((const __m128i *)(const void *)(p + ts)));
            x10 = _mm_cvtph_ps(_mm_loadl_epi64((const __m128i *)(const void *)p1r));
            x11 = _mm_cvtph_ps(_mm_loadl_epi64((const __m128i *)(const void *)(p1r + ts)));
            break;
        default:
            x00 = _mm_loadu_ps((const float *)(const void *)p);
            x01 = _mm_loadu_ps((const float *)(const void *)(p + ts));
            x10 = _mm_loadu_ps((const float *)(const void *)p1r);
            x11 = _mm_loadu_ps((const float *)(const void *)(p1r + ts));
            break;
        }
        __m128 a = _mm_set1_ps(k0[j]), b = _mm_set1_ps(k1[j]);
        __m128 r0 = _mm_add_ps(_mm_mul_ps(x00, a), _mm_mul_ps(x01, b));
        __m128 r1 = _mm_add_ps(_mm_mul_ps(x10, a), _mm_mul_ps(x11, b));
        __m128 acc = _mm_add_ps(_mm_mul_ps(r0, _mm_set1_ps(w0[j])), _mm_mul_ps(r1, _mm_set1_ps(w1[j])));
        __m128 res = _mm_mul_ps(acc, _mm_set1_ps(sc[j]));
        float *o = out + (size_t)j * NC;
        if (NC == 4) {
            _mm_storeu_ps(o, res);
        } else {
            _mm_storel_pi((__m64 *)(void *)o, res);
            if (NC == 3)
                _mm_store_ss(o + 2, _mm_movehl_ps(res, res));
        }
    }
    return mask | (cmask ? const_lanes8(c, cmask, face, fu, fv, out, DT, NC) : 0u);
}

/* Blocks of W lanes (FN the one-block body) until one is not served whole or nblk are: the
 * loop in the lane function, so that a run of in-face blocks pays for one call and one set-up
 * of the constants (pf_bilinear_lanes_fn). */
#define PL_BLOCKS(FN, W, DT, NC)                                                            \
    {                                                                                       \
        size_t b = 0;                                                                       \
        for (;;) {                                                                          \
            unsigned m = FN(c, q + W * b, out + (size_t)W * NC * b, k, edge, DT, NC);       \
            if (m != (1u << W) - 1 || ++b == nblk) {                                        \
                *whole = b;                                                                 \
                return m;                                                                   \
            }                                                                               \
        }                                                                                   \
    }
#define PL_FN8(DT, NC)                                                                      \
    __attribute__((target("avx2,fma,f16c"))) static unsigned pl8_##DT##_##NC(               \
        const pf_lanes *c, const st_query *q, size_t nblk, float *out, pf_lanes_kern *k,    \
        unsigned *edge, size_t *whole)                                                      \
    PL_BLOCKS(lanes8, 8, DT, NC)
#define PL_FN8_NC(DT) PL_FN8(DT, 1) PL_FN8(DT, 2) PL_FN8(DT, 3) PL_FN8(DT, 4)
PL_FN8_NC(0)
PL_FN8_NC(1)
PL_FN8_NC(2)
PL_FN8_NC(3)

/* ---- 4 lanes (SSE2) --------------------------------------------------------------------- */

PL_AXIS(axis4, static inline, pl_v4f, pl_v4i)

/* One texel of type DT as 4 float lanes (ptexfilter.c's loads: u8 4 bytes, u16 and half 8,
 * float 16, whatever the channel count; the lanes past it are never stored). */
static inline __m128 texel4(const uint8_t *p, unsigned DT)
{
    switch (DT) {
    case ST_DT_U8: {
        int x;
        memcpy(&x, p, 4);
        __m128i z = _mm_setzero_si128();
        return _mm_cvtepi32_ps(_mm_unpacklo_epi16(_mm_unpacklo_epi8(_mm_cvtsi32_si128(x), z), z));
    }
    case ST_DT_U16:
        return _mm_cvtepi32_ps(_mm_unpacklo_epi16(_mm_loadl_epi64((const __m128i *)(const void *)p),
                                                  _mm_setzero_si128()));
    case ST_DT_HALF: {
        uint16_t h[4];
        memcpy(h, p, sizeof h);
        return _mm_setr_ps(st_half_to_float(h[0]), st_half_to_float(h[1]),
                           st_half_to_float(h[2]), st_half_to_float(h[3]));
    }
    default:
        return _mm_loadu_ps((const float *)(const void *)p);
    }
}

/* One value of type DT (the one-channel lanes). */
static inline float value1(const uint8_t *p, unsigned DT)
{
    switch (DT) {
    case ST_DT_U8: return (float)p[0];
    case ST_DT_U16: { uint16_t x; memcpy(&x, p, 2); return (float)x; }
    case ST_DT_HALF: { uint16_t x; memcpy(&x, p, 2); return st_half_to_float(x); }
    default: { float x; memcpy(&x, p, 4); return x; }
    }
}

__attribute__((always_inline)) static inline unsigned lanes4(const pf_lanes *c,
                                                             const st_query *q, float *out,
                                                             pf_lanes_kern *k, unsigned *edge,
                                                             unsigned DT, unsigned NC)
{
    /* the queries' fields by lane: checks, then the face words (scalar loads) */
    float u_[4], v_[4], uw_[4], vw_[4];
    int lu_[4], lv_[4], ok_[4];
    for (int j = 0; j < 4; j++) {
        const st_query *x = &q[j];
        float ax = fabsf(x->dudx), bx = fabsf(x->dvdx), ay = fabsf(x->dudy), by = fabsf(x->dvdy);
        int ok = x->face < c->nfaces && ax <= ST_MAX_DERIV && bx <= ST_MAX_DERIV &&
                 ay <= ST_MAX_DERIV && by <= ST_MAX_DERIV && x->u >= 0.0f && x->u < 1.0f &&
                 x->v >= 0.0f && x->v < 1.0f;
        const st_face *F = ok ? &c->faces[x->face] : c->faces;
        ok = ok && !(c->lanef[x->face] & PTX_FLAG_NBCONSTANT) &&
             !(F->flags & (ST_FACE_SUBFACE | ST_FACE_CONSTANT));
        ok_[j] = ok;
        u_[j] = x->u, v_[j] = x->v;
        uw_[j] = ax + ay, vw_[j] = bx + by;
        lu_[j] = F->ulog2, lv_[j] = F->vlog2;
    }
    pl_v4i ru4, rv4;
    pl_v4f flu4, flv4, fu4, fv4;
    pl_v4i in = axis4((pl_v4f)_mm_loadu_ps(u_), (pl_v4f)_mm_loadu_ps(uw_),
                      (pl_v4i)_mm_loadu_si128((const __m128i *)(const void *)lu_), c->width,
                      c->blur, &ru4, &flu4, &fu4) &
                axis4((pl_v4f)_mm_loadu_ps(v_), (pl_v4f)_mm_loadu_ps(vw_),
                      (pl_v4i)_mm_loadu_si128((const __m128i *)(const void *)lv_), c->width,
                      c->blur, &rv4, &flv4, &fv4);
    __m128i ru = (__m128i)ru4, rv = (__m128i)rv4;
    __m128 flu = (__m128)flu4, flv = (__m128)flv4, fu = (__m128)fu4, fv = (__m128)fv4;
    unsigned plain = (unsigned)(ok_[0] | ok_[1] << 1 | ok_[2] << 2 | ok_[3] << 3);
    unsigned mask = (unsigned)_mm_movemask_ps((__m128)in) & plain;
    *edge = plain & ~mask;
    if (*edge) { /* the kernel set-up of the lanes handed over */
        _mm_storeu_si128((__m128i *)(void *)k->ru, ru);
        _mm_storeu_si128((__m128i *)(void *)k->rv, rv);
        _mm_storeu_si128((__m128i *)(void *)k->ui, _mm_cvttps_epi32(flu));
        _mm_storeu_si128((__m128i *)(void *)k->vi, _mm_cvttps_epi32(flv));
        _mm_storeu_ps(k->fu, fu);
        _mm_storeu_ps(k->fv, fv);
        k->open = k->inside = 0;
        for (unsigned rest = *edge; rest; rest &= rest - 1) {
            int j = __builtin_ctz(rest);
            unsigned bits = pl_overhang(k->ru[j], k->rv[j], k->ui[j], k->vi[j], k->fu[j], k->fv[j]);
            k->inside |= (bits == 0) << j;
            k->open |= ((bits & c->lanef[q[j].face]) == 0) << j;
        }
    }
    if (!mask)
        return 0;
    const __m128 one = _mm_set1_ps(1.0f);
    __m128 ku0 = _mm_sub_ps(one, fu), kv0 = _mm_sub_ps(one, fv);
    __m128 scale = _mm_div_ps(one, _mm_mul_ps(_mm_mul_ps(_mm_add_ps(ku0, fu), _mm_add_ps(kv0, fv)),
                                              _mm_set1_ps(one_of(DT))));
    int ru_[4], rv_[4], ui_[4], vi_[4];
    _mm_storeu_si128((__m128i *)(void *)ru_, ru);
    _mm_storeu_si128((__m128i *)(void *)rv_, rv);
    _mm_storeu_si128((__m128i *)(void *)ui_, _mm_cvttps_epi32(flu));
    _mm_storeu_si128((__m128i *)(void *)vi_, _mm_cvttps_epi32(flv));
    const size_t ts = st_dtype_size(DT) * NC;
    const uint8_t *p0[4], *p1[4];
    for (int j = 0; j < 4; j++) {
        p0[j] = p1[j] = NULL;
        if (!(mask >> j & 1))
            continue;
        const uint8_t *d = c->px[c->base[q[j].face] + (size_t)ru_[j] * ((unsigned)lv_[j] + 1u) +
                                 (size_t)rv_[j]];
        size_t rowb = ts << ru_[j];
        p0[j] = d + (size_t)vi_[j] * rowb + (size_t)ui_[j] * ts;
        p1[j] = p0[j] + rowb;
    }
    if (NC == 1) {
        float t[4][4] = {{0}};
        for (int j = 0; j < 4; j++) {
            if (!p0[j])
                continue;
            t[0][j] = value1(p0[j], DT);
            t[1][j] = value1(p0[j] + ts, DT);
            t[2][j] = value1(p1[j], DT);
            t[3][j] = value1(p1[j] + ts, DT);
        }
        __m128 r0 = _mm_add_ps(_mm_mul_ps(_mm_loadu_ps(t[0]), ku0), _mm_mul_ps(_mm_loadu_ps(t[1]), fu));
        __m128 r1 = _mm_add_ps(_mm_mul_ps(_mm_loadu_ps(t[2]), ku0), _mm_mul_ps(_mm_loadu_ps(t[3]), fu));
        __m128 acc = _mm_add_ps(_mm_mul_ps(r0, kv0), _mm_mul_ps(r1, fv));
        _mm_storeu_ps(out, _mm_mul_ps(acc, scale));
        return mask;
    }
    float k0[4], k1[4], w0[4], w1[4], sc[4];
    _mm_storeu_ps(k0, ku0);
    _mm_storeu_ps(k1, fu);
    _mm_storeu_ps(w0, kv0);
    _mm_storeu_ps(w1, fv);
    _mm_storeu_ps(sc, scale);
    for (int j = 0; j < 4; j++) {
        if (!p0[j])
            continue;
        __m128 a = _mm_set1_ps(k0[j]), b = _mm_set1_ps(k1[j]);
        __m128 r0 = _mm_add_ps(_mm_mul_ps(texel4(p0[j], DT), a), _mm_mul_ps(texel4(p0[j] + ts, DT), b));
        __m128 r1 = _mm_add_ps(_mm_mul_ps(texel4(p1[j], DT), a), _mm_mul_ps(texel4(p1[j] + ts, DT), b));
        __m128 acc = _mm_add_ps(_mm_mul_ps(r0, _mm_set1_ps(w0[j])), _mm_mul_ps(r1, _mm_set1_ps(w1[j])));
        float res[4];
        _mm_storeu_ps(res, _mm_mul_ps(acc, _mm_set1_ps(sc[j])));
        memcpy(out + (size_t)j * NC, res, NC * sizeof(float));
    }
    return mask;
}

#define PL_FN4(DT, NC)                                                                      \
    static unsigned pl4_##DT##_##NC(const pf_lanes *c, const st_query *q, size_t nblk,      \
                                    float *out, pf_lanes_kern *k, unsigned *edge,           \
                                    size_t *whole)                                          \
    PL_BLOCKS(lanes4, 4, DT, NC)
#define PL_FN4_NC(DT) PL_FN4(DT, 1) PL_FN4(DT, 2) PL_FN4(DT, 3) PL_FN4(DT, 4)
PL_FN4_NC(0)
PL_FN4_NC(1)
PL_FN4_NC(2)
PL_FN4_NC(3)

/* ---- the box and width-4 filters' checks and set-up (pf_kernel_lanes_select) ----------- */

/* lanes8's steps 1 and 2 (the same checks), then kernel_qi's widths and its test for the
 * fused path, and the face's row of the table (base[f] gathered for the plain lanes). */
__attribute__((target("avx2,fma,f16c"))) static inline void klanes8(const pf_lanes *c,
                                                                    const st_query *q,
                                                                    pf_klanes *k, int w4)
{
    pl_q8 q8;
    k->plain = k->fast = k->nonb = k->cst = 0;
    if (!q8_checks(c, q, &q8))
        return;
    const __m256i zero = _mm256_setzero_si256(), ff = _mm256_set1_epi32(0xff);
    __m256i face = q8.face, fw = q8.fw, m = q8.m;
    __m256 u = q8.u, v = q8.v, ax = q8.ax, bx = q8.bx, ay = q8.ay, by = q8.by;
    unsigned plain = (unsigned)_mm256_movemask_ps(_mm256_castsi256_ps(m));
    /* constant faces that open_face opens: the flag byte's subface and constant bits are
     * the constant one, not next to a constant face */
    __m256i cm = _mm256_and_si256(
        q8.mok, _mm256_and_si256(
                    _mm256_cmpeq_epi32(_mm256_and_si256(q8.pxf, _mm256_set1_epi32(PTX_FLAG_NBCONSTANT)), zero),
                    _mm256_cmpeq_epi32(_mm256_and_si256(_mm256_srli_epi32(fw, 24),
                                                        _mm256_set1_epi32(ST_FACE_SUBFACE | ST_FACE_CONSTANT)),
                                       _mm256_set1_epi32(ST_FACE_CONSTANT))));
    unsigned cst = (unsigned)_mm256_movemask_ps(_mm256_castsi256_ps(cm));
    if (!(plain | cst))
        return;
    m = _mm256_or_si256(m, cm); /* the rows gathered below */
    __m256i lu = _mm256_and_si256(fw, ff), lv = _mm256_and_si256(_mm256_srli_epi32(fw, 8), ff);
    /* kernel_qi's widths: |du/dx| + |du/dy|, times width, plus blur (two operations) */
    __m256 bu = _mm256_add_ps(_mm256_mul_ps(_mm256_add_ps(ax, ay), _mm256_set1_ps(c->width)),
                              _mm256_set1_ps(c->blur));
    __m256 bv = _mm256_add_ps(_mm256_mul_ps(_mm256_add_ps(bx, by), _mm256_set1_ps(c->width)),
                              _mm256_set1_ps(c->blur));
    unsigned fast = plain;
    if (w4) { /* not (bu >= 1/4 or bv >= 1/4 or ulog2 < 3 or vlog2 < 3); NaN widths offered */
        const __m256 q4 = _mm256_set1_ps(.25f);
        const __m256i three = _mm256_set1_epi32(3);
        __m256i decl = _mm256_or_si256(
            _mm256_castps_si256(_mm256_or_ps(_mm256_cmp_ps(bu, q4, _CMP_GE_OQ),
                                             _mm256_cmp_ps(bv, q4, _CMP_GE_OQ))),
            _mm256_or_si256(_mm256_cmpgt_epi32(three, lu), _mm256_cmpgt_epi32(three, lv)));
        fast &= ~(unsigned)_mm256_movemask_ps(_mm256_castsi256_ps(decl));
    }
    /* no neighbour (the four boundary bits of the lane byte); width-4: both widths >= 1/2,
     * or both in [1/4, 1/2) once clamped to a texel of the face (pf_q8's band; NaN clamped
     * too, as pk_width4_axis clamps it) */
    const __m256i bnd = _mm256_set1_epi32(0xf0);
    __m256 nb = _mm256_castsi256_ps(_mm256_cmpeq_epi32(_mm256_and_si256(q8.pxf, bnd), bnd));
    if (w4) {
        const __m256 h = _mm256_set1_ps(.5f), q4 = _mm256_set1_ps(.25f);
        __m256 cu = pf_w4_clamp8(bu, lu), cv = pf_w4_clamp8(bv, lv);
        __m256 band = _mm256_and_ps(
            _mm256_and_ps(_mm256_cmp_ps(cu, q4, _CMP_GE_OQ), _mm256_cmp_ps(cu, h, _CMP_LT_OQ)),
            _mm256_and_ps(_mm256_cmp_ps(cv, q4, _CMP_GE_OQ), _mm256_cmp_ps(cv, h, _CMP_LT_OQ)));
        nb = _mm256_and_ps(nb, _mm256_or_ps(_mm256_and_ps(_mm256_cmp_ps(bu, h, _CMP_GE_OQ),
                                                          _mm256_cmp_ps(bv, h, _CMP_GE_OQ)),
                                            band));
    }
    k->nonb = plain & (unsigned)_mm256_movemask_ps(nb);
    k->plain = plain;
    k->fast = fast;
    k->cst = cst;
    _mm256_storeu_si256((__m256i *)(void *)k->ulog2, lu);
    _mm256_storeu_si256((__m256i *)(void *)k->vlog2, lv);
    _mm256_storeu_ps(k->u, u);
    _mm256_storeu_ps(k->v, v);
    _mm256_storeu_ps(k->bu, bu);
    _mm256_storeu_ps(k->bv, bv);
    /* px + base[f] for the plain and constant lanes (8 bytes an entry) */
    const __m256i pxb = _mm256_set1_epi64x((long long)(uintptr_t)c->px);
    __m128i f0 = _mm256_castsi256_si128(face), f1 = _mm256_extracti128_si256(face, 1);
    __m128i m0 = _mm256_castsi256_si128(m), m1 = _mm256_extracti128_si256(m, 1);
    __m256i b0 = _mm256_mask_i32gather_epi64(zero, (const long long *)(const void *)c->base, f0,
                                             _mm256_cvtepi32_epi64(m0), 8);
    __m256i b1 = _mm256_mask_i32gather_epi64(zero, (const long long *)(const void *)c->base, f1,
                                             _mm256_cvtepi32_epi64(m1), 8);
    _mm256_storeu_si256((__m256i *)(void *)&k->px[0],
                        _mm256_add_epi64(pxb, _mm256_slli_epi64(b0, 3)));
    _mm256_storeu_si256((__m256i *)(void *)&k->px[4],
                        _mm256_add_epi64(pxb, _mm256_slli_epi64(b1, 3)));
}

__attribute__((target("avx2,fma,f16c"))) static void klanes8_box(const pf_lanes *c,
                                                                 const st_query *q,
                                                                 pf_klanes *k)
{
    klanes8(c, q, k, 0);
}
__attribute__((target("avx2,fma,f16c"))) static void klanes8_w4(const pf_lanes *c,
                                                                const st_query *q,
                                                                pf_klanes *k)
{
    klanes8(c, q, k, 1);
}

pf_kernel_lanes_fn pf_kernel_lanes_select(unsigned ftype)
{
    if (!pf_have_avx2())
        return NULL;
    return ftype == ST_FILTER_PTEX_BOX ? klanes8_box : klanes8_w4;
}

pf_bilinear_lanes_fn pf_bilinear_lanes_select(unsigned dt, unsigned nc, unsigned maxlanes,
                                              unsigned *lanes)
{
#define PL_ROW(W, DT) {pl##W##_##DT##_1, pl##W##_##DT##_2, pl##W##_##DT##_3, pl##W##_##DT##_4}
    static const pf_bilinear_lanes_fn f8[4][4] = {PL_ROW(8, 0), PL_ROW(8, 1), PL_ROW(8, 2),
                                                  PL_ROW(8, 3)};
    static const pf_bilinear_lanes_fn f4[4][4] = {PL_ROW(4, 0), PL_ROW(4, 1), PL_ROW(4, 2),
                                                  PL_ROW(4, 3)};
#undef PL_ROW
    if (dt > 3 || nc < 1 || nc > 4 || maxlanes < 4)
        return NULL;
    if (maxlanes >= 8 && pf_have_avx2()) {
        *lanes = 8;
        return f8[dt][nc - 1];
    }
    *lanes = 4;
    return f4[dt][nc - 1];
}

#else

pf_bilinear_lanes_fn pf_bilinear_lanes_select(unsigned dt, unsigned nc, unsigned maxlanes,
                                              unsigned *lanes)
{
    (void)dt; (void)nc; (void)maxlanes; (void)lanes;
    return NULL;
}

pf_kernel_lanes_fn pf_kernel_lanes_select(unsigned ftype)
{
    (void)ftype;
    return NULL;
}

#endif

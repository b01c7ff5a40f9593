/* store/ptex/ptexfilter_kernel.h - separable kernels of Ptex's filter family (private to
 * ptexfilter*.c).
 *
 * A kernel is a window [u, u+uw) x [v, v+vw) of texels at resolution 2^ulog2 x 2^vlog2 with
 * one weight per column (ku) and per row (kv); the filter is sum ku[i] kv[j] texel(u+i, v+j).
 * The operations mirror Ptex's PtexSeparableKernel (v2.4): splitting off the part that hangs
 * over an edge, folding it back (merge), rotating it into a neighbour's frame, changing its
 * resolution by 2 (down/up) and making it symmetric for corners of valence > 4.
 *
 * Owns: the kernel value type and its operations; building a kernel for each filter type.
 * Does not own: where kernels are applied (ptexfilter.c).
 */
#ifndef ST_PTEXFILTER_KERNEL_H
#define ST_PTEXFILTER_KERNEL_H

#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "sample.h"

#ifdef __SSE2__
#include <emmintrin.h>
#endif

#define PK_MAX 24   /* weights per axis; Ptex needs at most 10, doubled once by upres */

typedef struct pk {
    int ulog2, vlog2;            /* resolution the kernel is built for */
    int u, v;                    /* first texel */
    int uw, vw;                  /* window size */
    int ku0, kv0;                /* first weight in kub / kvb */
    int rot;                     /* quarter turns applied so far */
    float kub[PK_MAX], kvb[PK_MAX];
} pk;

static inline float *pk_ku(pk *k) { return k->kub + k->ku0; }
static inline float *pk_kv(pk *k) { return k->kvb + k->kv0; }

/* floor and ceil without a libm call and without a branch (random coordinates made the
 * branch of a compare-and-adjust mispredict half the time); |x| < 2^31 here: coordinates are
 * clamped before. */
static inline float pk_floor(float x)
{
    float t = (float)(int)x;
    return t - (float)(t > x);
}
static inline float pk_ceil(float x)
{
    float t = (float)(int)x;
    return t + (float)(t < x);
}
/* (int)pk_floor(x) and (int)pk_ceil(x) in integers (the same values: t + 1 is exact where
 * t < x, as x is not integral there, |x| < 2^23), without the conversion back and forth. */
static inline int pk_ifloor(float x)
{
    int i = (int)x;
    return i - ((float)i > x);
}
static inline int pk_iceil(float x)
{
    int i = (int)x;
    return i + ((float)i < x);
}

/* 1 / 2^power, and Ptex's resolution for a width: ceil(log2(1/w)) read from the exponent. */
static inline float pk_recip_pow2(int power)
{
    uint32_t i = (uint32_t)(127 - power) << 23;
    float f;
    memcpy(&f, &i, 4);
    return f;
}
static inline int pk_res_from_width(float w)
{
    uint32_t i;
    memcpy(&i, &w, 4);
    return 127 - (int)((i >> 23) & 0xff);
}

/* Whether mask m has at least n bits set (n a constant: unrolled), without
 * __builtin_popcount, which without -mpopcnt is a call into libgcc (about 2.5 instructions
 * a query of the width-4 batches in callgrind, session 31). */
static inline int pf_bits_atleast(unsigned m, int n)
{
    for (int i = 1; i < n; i++)
        m &= m - 1;
    return m != 0;
}

typedef float pk_v4f __attribute__((vector_size(16)));
typedef int32_t pk_v4i __attribute__((vector_size(16)));

/* 2^y in each lane, for y below 1/2 (the Gaussian weights: y = -x^2 * 2 log2(e) for the
 * quad filters' kernel_eval, y = -Q * 3.5^2 / 2 * log2(e) for the triangle filter's read
 * sweeps): y clamped to -126 from below, y = n + f with n = (int)(y - 1/2) (y - 1/2 rounded
 * towards 0: the nearest integer for y <= 0 and for 0 <= y < 1/2, |f| <= 1/2), 2^f by a
 * degree-6 polynomial (relative error about 2e-7), times 2^n made in the exponent bits. One
 * implementation for both: kernel_eval's weights are these bits (ptexfilter_simd.c's AVX2
 * copy repeats them 8 lanes at a time, bit for bit). */
__attribute__((always_inline)) static inline pk_v4f pk_exp2_4(pk_v4f y)
{
    /* the constants in memory, whole vectors (operands of the vector instructions, not
     * scalars broadcast at each use) */
#define PK_C4(c) {c, c, c, c}
    static const pk_v4f k[9] = {PK_C4(-126.0f), PK_C4(0.5f), PK_C4(1.0f),
                                PK_C4(0.693147181f), PK_C4(0.240226507f),
                                PK_C4(0.0555041087f), PK_C4(0.00961812911f),
                                PK_C4(0.00133335581f), PK_C4(0.000154035304f)};
#undef PK_C4
#ifdef __SSE2__
    /* maxps gives its second operand unless the first is greater: y, or -126 where y is
     * below it (a NaN y: y), the select below in one instruction */
    y = (pk_v4f)_mm_max_ps((__m128)k[0], (__m128)y);
#else
    pk_v4i lo = y < k[0];
    pk_v4i yb, mb;
    memcpy(&yb, &y, 16);
    memcpy(&mb, &k[0], 16);
    yb = (yb & ~lo) | (mb & lo);
    memcpy(&y, &yb, 16);
#endif
    pk_v4i ii = __builtin_convertvector(y - k[1], pk_v4i); /* y <= 0: nearest */
    pk_v4f f = y - __builtin_convertvector(ii, pk_v4f);
    pk_v4f q = k[2] + f * (k[3] + f * (k[4] + f * (k[5] + f * (k[6] + f * (k[7] + f * k[8])))));
    pk_v4i bits = (ii + 127) << 23;
    pk_v4f sc;
    memcpy(&sc, &bits, 16);
    return q * sc;
}

static inline float pk_hermite_blur(float x)
{
    x = __builtin_fabsf(x);
    return x < 1.0f ? (2.0f * x - 3.0f) * x * x + 1.0f : 0.0f;
}

/* Ptex's width-4 filters (gaussian, bicubic family), one axis, lerp off (pk_build's): resolution *kres, first texel *ku and taps *kw of a
 * width uw at u on a face of resolution 2^fres. Returns 1 when the weights are
 * pk_kernel_eval(p, *x1o, *stepo, w, *kw), left to the caller (so that both axes can be
 * evaluated at once); 0 when they are written to w already (room for 4), their
 * pk_accumulate in *sumo (the 4 or 2 taps' sum from 0 in order, without a loop). */
__attribute__((always_inline)) static inline int
pk_width4_axis_s(int *kres, int *ku, int *kw, float *w, float u, float uw, int fres,
                 float *x1o, float *stepo, float *sumo)
{
    float lo = pk_recip_pow2(fres);
    if (!(uw >= lo))
        uw = lo;
    *kres = pk_res_from_width(uw);
    if (uw >= .25f) {
        if (uw < .5f) {
            *kres = 2;
            float upix = u * 4.0f - 0.5f;
            int u1 = pk_iceil(upix - 2), u2 = pk_iceil(upix + 2);
            u1 = u1 & ~1;
            u2 = (u2 + 1) & ~1;
            *ku = u1;
            *kw = u2 - u1;
            if (*kw > PK_MAX / 2)
                *kw = PK_MAX / 2;
            *x1o = (float)u1 - upix;
            *stepo = 1.0f;
            return 1;
        } else if (uw < 1) {
            *kres = 1;
            float upix = u * 2.0f - 0.5f;
            *ku = pk_ifloor(u - .5f) * 2;
            *kw = 4;
            float x1 = (float)*ku - upix;
            float s = 1.0f / (uw * 1.5f + .5f);
            /* hermite_blur of (x1 + i) * s, i = 0, 2, and of ((x1 + i) + 1) * s, 4 lanes, the
             * same operations in the same order */
            pk_v4f xa = x1 + (pk_v4f){0.0f, 0.0f, 2.0f, 2.0f};
            pk_v4f x = (xa + (pk_v4f){0.0f, 1.0f, 0.0f, 1.0f}) * s;
            pk_v4i xb;
            __builtin_memcpy(&xb, &x, sizeof x);
            xb &= 0x7fffffff;
            __builtin_memcpy(&x, &xb, sizeof x);
            pk_v4f h = (2.0f * x - 3.0f) * x * x + 1.0f;
            pk_v4i hb, lt = x < 1.0f;
            __builtin_memcpy(&hb, &h, sizeof h);
            hb &= lt;
            __builtin_memcpy(w, &hb, sizeof hb);
            __builtin_memcpy(&h, &hb, sizeof hb);
            *sumo = (((0.0f + h[0]) + h[1]) + h[2]) + h[3];
            return 0;
        } else {
            *kres = 0;
            float upix = u - .5f;
            *kw = 2;
            float ui = pk_floor(upix);
            *ku = (int)ui;
            w[0] = pk_hermite_blur(upix - ui);
            w[1] = 1 - w[0];
            *sumo = (0.0f + w[0]) + w[1];
            return 0;
        }
    }
    int resu = 1 << (*kres < 0 ? 0 : *kres > 30 ? 30 : *kres); /* widths under 1/4 only */
    float upix = u * (float)resu - 0.5f;
    float uwpix = uw * (float)resu;
    float dupix = 2.0f * uwpix;
    int u1 = pk_iceil(upix - dupix), u2 = pk_iceil(upix + dupix);
    *ku = u1;
    *kw = u2 - u1;
    if (*kw > PK_MAX / 2)
        *kw = PK_MAX / 2; /* cannot happen: uwpix < 2 gives at most 9 */
    *x1o = ((float)u1 - upix) / uwpix;
    *stepo = 1.0f / uwpix;
    return 1;
}

/* pk_width4_axis_s without the sum. */
__attribute__((always_inline)) static inline int
pk_width4_axis(int *kres, int *ku, int *kw, float *w, float u, float uw, int fres, float *x1o,
               float *stepo)
{
    float sum;
    return pk_width4_axis_s(kres, ku, kw, w, u, uw, fres, x1o, stepo, &sum);
}

/* The first nc (1..4) of 4 half values at p as floats, lanes nc..3 zero: st_half_to_float's
 * bits lane by lane (both are exact: a normal or infinite / NaN half moves its exponent and
 * mantissa, a zero or subnormal one is its mantissa times 2^-24, which a float holds
 * exactly), without its per-channel branches. Reads 8 bytes at p (the arenas end with
 * slack). */
__attribute__((always_inline)) static inline pk_v4f pk_half4(const uint8_t *p, unsigned nc)
{
#ifdef __SSE2__
    pk_v4i h = (pk_v4i)_mm_unpacklo_epi16(_mm_loadl_epi64((const __m128i *)(const void *)p),
                                          _mm_setzero_si128());
#else
    uint16_t h16[4];
    memcpy(h16, p, sizeof h16);
    pk_v4i h = {h16[0], h16[1], h16[2], h16[3]};
#endif
    pk_v4i sign = (h & 0x8000) << 16, em = h & 0x7fff;
    pk_v4i norm = (em << 13) + (112 << 23);
    norm += (em > 0x7bff) & (112 << 23);                  /* exponent 31: infinity, NaN */
    pk_v4f sub = __builtin_convertvector(em, pk_v4f) * 0x1p-24f; /* exponent 0 */
    pk_v4i sb, lt = em < 0x400;
    __builtin_memcpy(&sb, &sub, sizeof sb);
    pk_v4i bits = ((norm & ~lt) | (sb & lt)) | sign;
    static const pk_v4i keep[4] = {{-1, 0, 0, 0}, {-1, -1, 0, 0}, {-1, -1, -1, 0},
                                   {-1, -1, -1, -1}};
    bits &= keep[(nc - 1) & 3];
    pk_v4f r;
    __builtin_memcpy(&r, &bits, sizeof r);
    return r;
}

/* Filter-specific kernel construction (Ptex's buildKernel); ftype is st_filter. */
typedef struct pk_params {
    unsigned ftype;
    int avx2;                    /* pf_have_avx2(): kernels evaluated by ptexfilter_simd.c */
    float coeffs[7];             /* bicubic coefficients for the sharpness */
    int lerp;                    /* Ptex's lerp option for the width-4 filters (gaussian,
                                    bicubic family): their kernels blended toward the next
                                    lower resolution (pk_build; 0 from pk_params_init) */
} pk_params;

/* avx2: pf_have_avx2(), asked once by the caller (per batch). lerp is left 0: the caller
 * sets it (only the width-4 filters read it). */
void pk_params_init(pk_params *p, unsigned ftype, float sharpness, int avx2);
void pk_build(const pk_params *p, pk *k, float u, float v, float uw, float vw, int fulog2,
              int fvlog2);
/* One axis of a width-4 kernel with Ptex's lerp on (PtexWidth4Filter::buildKernelAxis with
 * lerp): the width's place between the resolution it picks (width 1/2^r) and the next lower
 * one (2/2^r), lerp2 = (uw - 1/2^r) * 2^r in [0, 1), blends each pair of taps (an even
 * pair: the window widened to even ends) toward the kernel at the pair's middle: widths under
 * 1/4, the kernel at the middle point; 1/4 to 1/2, Ptex's Hermite blur of the middle at the
 * next lower resolution's spread; 1/2 to 1, the Hermite taps blended likewise. At lerp2 = 0
 * (a width on a level) and for widths of a face or more the kernel without lerp, bit for
 * bit. Writes the taps to w (room for PK_MAX / 2) and the window to *kres, *ku, *kw. */
void pk_width4_axis_lerp(const pk_params *p, int *kres, int *ku, int *kw, float *w, float u,
                         float uw, int fres);
/* The kernel function of a width-4 filter (gaussian, bicubic family) at x1 + i * step,
 * i < n, into w (room for n rounded up to 4): the portable evaluation. */
void pk_kernel_eval(const pk_params *p, float x1, float step, float *w, int n);

/* Kernel operations (Ptex semantics). */
void  pk_set(pk *dst, const pk *src);           /* copy with weights packed at index 0 */
static inline float pk_accumulate(const float *p, int n)
{
    float r = 0;
    for (int i = 0; i < n; i++)
        r += p[i];
    return r;
}
/* pk_accumulate(p, n) for 1 <= n <= 4 where p[0 .. 4) may be read (defined or not): the
 * same additions in the same order, without the loop's exit test (it mispredicts when the
 * tap counts vary from query to query): the lanes at n and past cleared to +0, and every
 * lane added, from 0 in order. A +0 added leaves the sum as it is: the sum is never -0 (0
 * plus -0 is +0, and a sum of two values is -0 only when both are), NaN stays NaN, an
 * infinity stays. */
__attribute__((always_inline)) static inline float pk_accumulate4(const float *p, int n)
{
#ifdef __SSE2__
    __m128 a = _mm_and_ps(_mm_loadu_ps(p), _mm_castsi128_ps(_mm_cmpgt_epi32(
                                               _mm_set1_epi32(n), _mm_setr_epi32(0, 1, 2, 3))));
    __m128 r = _mm_add_ss(_mm_setzero_ps(), a);
    r = _mm_add_ss(r, _mm_shuffle_ps(a, a, 1));
    r = _mm_add_ss(r, _mm_shuffle_ps(a, a, 2));
    r = _mm_add_ss(r, _mm_shuffle_ps(a, a, 3));
    return _mm_cvtss_f32(r);
#else
    return pk_accumulate(p, n);
#endif
}

static inline float pk_weight(const pk *k)
{
    return pk_accumulate(k->kub + k->ku0, k->uw) * pk_accumulate(k->kvb + k->kv0, k->vw);
}
/* The taps of w[0 .. n) (1 <= n <= 12) that are not zero, as a bit mask (NaN counts as not
 * zero, -0 as zero, as pk_strip_zeros' == 0 tests). Reads w[0 .. 4) and, for longer axes,
 * up to w[12), defined or not: the lanes at n and past are cleared before the compare. */
__attribute__((always_inline)) static inline unsigned pk_nonzero_mask12(const float *w, int n)
{
#ifdef __SSE2__
    const __m128i idx = _mm_setr_epi32(0, 1, 2, 3);
    const __m128 z = _mm_setzero_ps();
    __m128i nn = _mm_set1_epi32(n);
    __m128 x = _mm_and_ps(_mm_loadu_ps(w), _mm_castsi128_ps(_mm_cmpgt_epi32(nn, idx)));
    unsigned m = (unsigned)_mm_movemask_ps(_mm_cmpneq_ps(x, z));
    if (__builtin_expect(n > 4, 0)) {
        for (int b = 1; b < 3; b++) {
            nn = _mm_sub_epi32(nn, _mm_set1_epi32(4));
            x = _mm_and_ps(_mm_loadu_ps(w + 4 * b), _mm_castsi128_ps(_mm_cmpgt_epi32(nn, idx)));
            m |= (unsigned)_mm_movemask_ps(_mm_cmpneq_ps(x, z)) << (4 * b);
        }
    }
    return m;
#else
    unsigned m = 0;
    for (int i = 0; i < n; i++)
        m |= (unsigned)(w[i] != 0) << i;
    return m;
#endif
}

/* pk_nonzero_mask12 for w in a buffer of which w[0 .. 8) may be read (a pk's kub, kvb):
 * the first 8 taps without a branch (4 and 6 taps, the commonest, alternate at random: the
 * test of n > 4 mispredicted about once a query); w[8 .. 12) for more than 8 taps. */
__attribute__((always_inline)) static inline unsigned pk_nonzero_mask24(const float *w, int n)
{
#ifdef __SSE2__
    const __m128i idx = _mm_setr_epi32(0, 1, 2, 3), idx4 = _mm_setr_epi32(4, 5, 6, 7);
    const __m128 z = _mm_setzero_ps();
    __m128i nn = _mm_set1_epi32(n);
    __m128 x = _mm_and_ps(_mm_loadu_ps(w), _mm_castsi128_ps(_mm_cmpgt_epi32(nn, idx)));
    __m128 y = _mm_and_ps(_mm_loadu_ps(w + 4), _mm_castsi128_ps(_mm_cmpgt_epi32(nn, idx4)));
    unsigned m = (unsigned)_mm_movemask_ps(_mm_cmpneq_ps(x, z)) |
                 (unsigned)_mm_movemask_ps(_mm_cmpneq_ps(y, z)) << 4;
    if (__builtin_expect(n > 8, 0)) {
        nn = _mm_sub_epi32(nn, _mm_set1_epi32(8));
        x = _mm_and_ps(_mm_loadu_ps(w + 8), _mm_castsi128_ps(_mm_cmpgt_epi32(nn, idx)));
        m |= (unsigned)_mm_movemask_ps(_mm_cmpneq_ps(x, z)) << 8;
    }
    return m;
#else
    return pk_nonzero_mask12(w, n);
#endif
}

/* pk_strip_zeros of one axis whose weights start at index 0 (1 <= n <= 12): the first and
 * last tap that is not zero from the mask m of its nonzero taps instead of the loops (the
 * same window; an axis of zeros only ends empty past its last tap, as the loops leave it). */
__attribute__((always_inline)) static inline void pk_strip_axis_m(int *k0, int *x, int *n,
                                                                  unsigned m)
{
    if (__builtin_expect(!m, 0)) { /* the first loop strips every tap */
        *k0 += *n;
        *x += *n;
        *n = 0;
        return;
    }
    int a = __builtin_ctz(m), b = 31 - __builtin_clz(m);
    *k0 += a;
    *x += a;
    *n = b - a + 1;
}
/* pk_strip_axis_m with pk_nonzero_mask12's mask of w[0 .. *n). */
__attribute__((always_inline)) static inline void pk_strip_axis12(int *k0, int *x, int *n,
                                                                  const float *w)
{
    pk_strip_axis_m(k0, x, n, pk_nonzero_mask12(w, *n));
}

/* The zero weights at both ends of each axis removed (Ptex's stripZeros). */
static inline void pk_strip_zeros_loops(pk *k)
{
    while (k->uw > 0 && k->kub[k->ku0] == 0) { k->ku0++; k->u++; k->uw--; }
    while (k->uw > 0 && k->kub[k->ku0 + k->uw - 1] == 0) k->uw--;
    while (k->vw > 0 && k->kvb[k->kv0] == 0) { k->kv0++; k->v++; k->vw--; }
    while (k->vw > 0 && k->kvb[k->kv0 + k->vw - 1] == 0) k->vw--;
}
__attribute__((always_inline)) static inline void pk_strip_zeros(pk *k)
{
    if (__builtin_expect(k->ku0 == 0 && k->kv0 == 0 && k->uw >= 1 && k->uw <= 12 &&
                             k->vw >= 1 && k->vw <= 12, 1)) {
        /* a kernel as pk_build makes it (the common case) */
        pk_strip_axis_m(&k->ku0, &k->u, &k->uw, pk_nonzero_mask24(k->kub, k->uw));
        pk_strip_axis_m(&k->kv0, &k->v, &k->vw, pk_nonzero_mask24(k->kvb, k->vw));
        return;
    }
    pk_strip_zeros_loops(k);
}
void  pk_merge_l(pk *k, int black);
void  pk_merge_r(pk *k, int black);
void  pk_merge_b(pk *k, int black);
void  pk_merge_t(pk *k, int black);
void  pk_split_l(pk *k, pk *out);
void  pk_split_r(pk *k, pk *out);
void  pk_split_b(pk *k, pk *out);
void  pk_split_t(pk *k, pk *out);
void  pk_rotate(pk *k, int rot);
int   pk_main_to_subface(pk *k, int eid);       /* returns 1 when the primary subface */
void  pk_subface_to_main(pk *k, int eid);
/* Halves the resolution of the w weights at kw of a window starting at *u (Ptex's
 * downres: pairs summed, an odd first or last weight kept); pk_downres_u / _v on one axis. */
static inline void pk_downres_run(float *kw, int *u, int *uw)
{
    float *src = kw, *dst = kw;
    int w = *uw;
    if (*u & 1) {
        dst++;
        src++;
        w--;
    }
    for (int i = w / 2; i > 0; i--) {
        *dst++ = src[0] + src[1];
        src += 2;
    }
    if (w & 1)
        *dst++ = *src++;
    *u /= 2;
    *uw = (int)(dst - kw);
}
void  pk_downres_u(pk *k);
void  pk_downres_v(pk *k);
void  pk_upres_u(pk *k);
void  pk_upres_v(pk *k);
float pk_make_symmetric(pk *k, float initial_weight);

/* ptexfilter_simd.c: AVX2 + FMA + F16C (pf_have_avx2() says whether the CPU has them):
 * returns acc + sum_j kv[j] sum_i ku[i] texel(i, j) (lanes 0..nc-1; the others unspecified)
 * over k's window whose first texel is at base, rows rowb bytes apart, texels of type dt
 * (st_dtype) with nc (1..4) channels. Reads up to 31 bytes past the window's last row (the
 * arenas' 64 bytes of slack cover it). */
typedef float pf_v4 __attribute__((vector_size(16)));
int   pf_have_avx2(void);
/* out[ch] = acc[ch] * scale for the nc (1..4) channels: the same products, in one vector
 * multiply and a store of nc lanes (nothing past out[nc - 1] written). */
static inline void pf_put_scaled(float *out, pf_v4 acc, float scale, unsigned nc)
{
#ifdef __SSE2__
    __m128 r = _mm_mul_ps((__m128)acc, _mm_set1_ps(scale));
    switch (nc) {
    case 4: _mm_storeu_ps(out, r); break;
    case 3:
        _mm_storel_pi((__m64 *)(void *)out, r);
        _mm_store_ss(out + 2, _mm_movehl_ps(r, r));
        break;
    case 2: _mm_storel_pi((__m64 *)(void *)out, r); break;
    default: _mm_store_ss(out, r); break;
    }
#else
    for (unsigned ch = 0; ch < nc; ch++)
        out[ch] = acc[ch] * scale;
#endif
}
/* Both axes of a width-4 kernel at once, bit for bit pk_kernel_eval(p, x1u, su, wu, nu) and
 * pk_kernel_eval(p, x1v, sv, wv, nv) (nu, nv <= PK_MAX / 2; writes 8 or 16 weights each). */
void  pf_kernel_eval2_avx2(const pk_params *p, float x1u, float su, float *wu, int nu,
                           float x1v, float sv, float *wv, int nv);
/* One axis: bit for bit pk_kernel_eval(p, x1, s, w, n) (n <= PK_MAX / 2; writes 8 or 16
 * weights). */
void  pf_kernel_eval1_avx2(const pk_params *p, float x1, float s, float *w, int n);
/* pf_kernel_eval2_avx2 that also sums each axis' weights as pk_accumulate(wu, nu) and
 * pk_accumulate(wv, nv) do (lanes 0 and 1; in registers, without a loop: the loop's exit
 * mispredicts when the tap counts vary from query to query), and pf_kernel_eval1_avx2 with
 * pk_accumulate(w, n). */
pf_v4 pf_kernel_eval2s_avx2(const pk_params *p, float x1u, float su, float *wu, int nu,
                            float x1v, float sv, float *wv, int nv);
float pf_kernel_eval1s_avx2(const pk_params *p, float x1, float s, float *w, int n);

/* The width-4 filters' pk_build (gaussian, bicubic family; lerp off) into k, with the same
 * pk_width4_axis and the same evaluations, inline (no call, no filter-type tests), returning
 * the pk_weight that k has after pk_strip_zeros: each axis' taps as built summed in order
 * from 0 (pk_width4_axis_s' sums, pf_kernel_eval2s_avx2's), which is the stripped taps' sum
 * bit for bit: the zeros the strip removes lie before the first tap that is not zero, where
 * the sum is +0 and stays +0, or after the last, where adding a zero changes no sum (a sum
 * from +0 is never -0). */
__attribute__((always_inline)) static inline float pk_build_w4s(const pk_params *p, pk *k,
                                                                float u, float v, float uw,
                                                                float vw, int fulog2,
                                                                int fvlog2)
{
    k->ku0 = k->kv0 = k->rot = 0;
    float x1u = 0, su = 0, x1v = 0, sv = 0, wu = 0, wv = 0;
    int eu = pk_width4_axis_s(&k->ulog2, &k->u, &k->uw, k->kub, u, uw, fulog2, &x1u, &su, &wu);
    int ev = pk_width4_axis_s(&k->vlog2, &k->v, &k->vw, k->kvb, v, vw, fvlog2, &x1v, &sv, &wv);
    if (!p->avx2) {
        if (eu) {
            pk_kernel_eval(p, x1u, su, k->kub, k->uw);
            wu = pk_accumulate(k->kub, k->uw);
        }
        if (ev) {
            pk_kernel_eval(p, x1v, sv, k->kvb, k->vw);
            wv = pk_accumulate(k->kvb, k->vw);
        }
    } else if (eu && ev) {
        pf_v4 s = pf_kernel_eval2s_avx2(p, x1u, su, k->kub, k->uw, x1v, sv, k->kvb, k->vw);
        wu = s[0];
        wv = s[1];
    } else if (eu)
        wu = pf_kernel_eval1s_avx2(p, x1u, su, k->kub, k->uw);
    else if (ev)
        wv = pf_kernel_eval1s_avx2(p, x1v, sv, k->kvb, k->vw);
    return wu * wv;
}
pf_v4 pf_apply_avx2(const uint8_t *base, size_t rowb, const pk *k, unsigned dt, unsigned nc,
                    pf_v4 acc);
/* The same window loop with the weights given directly (uw, vw >= 1), for texels of one type
 * and channel count: chosen once per batch by pf_window_select(dt, nc) (NULL without AVX2). */
typedef pf_v4 (*pf_window_fn)(const uint8_t *base, size_t rowb, const float *ku, int uw,
                              const float *kv, int vw, pf_v4 acc);
pf_window_fn pf_window_select(unsigned dt, unsigned nc);

/* The fused path of a query whose kernel lies inside one face (ptexfilter_simd.c, AVX2):
 * the box and width-4 (gaussian, bicubic family) filters, kernel built, zeros stripped,
 * weighed and applied without a pk, bit for bit what pk_build + pk_strip_zeros + pk_weight
 * + pf_apply_avx2 + the division by weight * one value give. px is the face's row of the
 * resolution table (st_ptexres px + base[f]: (ru, rv) at px[ru * (fvlog2 + 1) + rv]) of a
 * face that is neither constant nor a subface; u, v wrapped or clamped into the face and
 * uw, vw the widths with width and blur applied, as pk_build takes them. Writes nc values
 * to out and returns 1. Returns 2 when the kernel overhangs the face and kout is not NULL:
 * *kout is then the kernel pk_build + pk_strip_zeros make (weights at index 0, not empty),
 * for the general path to split. Returns 0 (nothing written) when the kernel overhangs the
 * face (kout NULL), is empty, has a weight <= 0, or is one the fused path does not take
 * (width-4 widths of 1/4 or more, more than 8 taps): the caller then runs the general path. */
typedef int (*pf_fast_fn)(const pk_params *p, const uint8_t *const *px, int fulog2, int fvlog2,
                          float u, float v, float uw, float vw, float *out, pk *kout);
/* The fused path for texels of type dt with nc channels and filter ftype, or NULL (no AVX2,
 * or a filter without one). */
pf_fast_fn pf_fast_select(unsigned dt, unsigned nc, unsigned ftype);

/* The fused width-4 path of 8 queries at once (ptexfilter_simd.c, AVX2), after klanes8
 * (ptexfilter_lanes.h: k the block's checks and set-up): for the lanes of k->fast whose
 * kernel is the fused path's common case (4 x 4 taps, none zero - or, but for 1-channel half
 * and float texels, only the first of an axis: a query on a texel centre, whose axis
 * pf_fast_fn strips to 3 taps - the window after any strip inside the face, total weight
 * > 0) writes the nc values of lane j at out + j * nc, bit for bit what pf_fast_fn writes,
 * and returns their mask; sets *over to the lanes with no zero tap but for a window that
 * overhangs the face, kout[lane] (kout: 8 of them) the kernel pf_fast_fn
 * hands over for them (its return 2) and wout[lane] its pk_weight; the other lanes are left
 * to the per-query path (their outputs untouched). NULL but for the width-4 filters (any
 * texel type, 1..4 channels) with AVX2. */
struct pf_klanes;
typedef unsigned (*pf_w4x8_fn)(const pk_params *p, const struct pf_klanes *k, float *out,
                               pk *kout, float *wout, unsigned *over);
pf_w4x8_fn pf_w4x8_select(unsigned dt, unsigned nc, unsigned ftype);

/* A window of uw x vw texels with uw, vw in 1..2 (ptexfilter_simd.c, AVX2): bit for bit what
 * pf_apply_avx2 gives for a kernel with that window and weights ku, kv, without its
 * dispatch (the pieces of a bilinear kernel split at face edges). pf_small_select gives the
 * function (the window loop's type) for texels of type dt with nc channels, or NULL without
 * AVX2. */
pf_window_fn pf_small_select(unsigned dt, unsigned nc);

/* Four windows of one texel each summed into acc in order (texel p[i], weights ku[i][0] and
 * kv[i][0], rows rowb apart as the small window takes them): bit for bit four calls of
 * pf_small_select's function with uw = vw = 1, in one call (the four pieces of a width-4
 * kernel at resolution 1 x 1 split at a regular corner: ptexfilter_walk.c's
 * pf_walk_kernel_r0).
 * pf_small4_select gives it for texels of type dt with nc channels, or NULL without AVX2. */
typedef struct pf_tex4 {
    const uint8_t *p[4];
    const float *ku[4], *kv[4];
} pf_tex4;
typedef pf_v4 (*pf_small4_fn)(const pf_tex4 *t, size_t rowb, pf_v4 acc);
pf_small4_fn pf_small4_select(unsigned dt, unsigned nc);
/* The same with the first two windows of t only (a fold's two pieces: lean_r0's). */
pf_small4_fn pf_small2_select(unsigned dt, unsigned nc);

/* The bilinear of 2 x 2 texels of 4 half values each (p the first, ts bytes per texel, rows
 * rowb apart; reads 8 bytes per texel, so up to 2 past a 3-channel one): lanes 0..3 of
 * (t00 ku0 + t01 fu) kv0 + (t10 ku0 + t11 fu) fv, with ptexfilter.c's operations in its
 * order (F16C loads). NULL without AVX2 + F16C. */
typedef pf_v4 (*pf_bilinear_half_fn)(const uint8_t *p, size_t ts, size_t rowb, float ku0,
                                     float fu, float kv0, float fv);
pf_bilinear_half_fn pf_bilinear_half_select(void);

/* ptexfilter.c, for tests: st_ptexfilter_batch along one path, to check that the shortcuts
 * give the general path's results bit for bit. PF_PATH_BEST: what st_ptexfilter_batch does;
 * PF_PATH_GENERAL: every query through eval (no per-type query function, no fused,
 * small-window or lane path); PF_PATH_QUERY: the per-query shortcuts without the bilinear
 * lanes and without the box / width-4 batch loop (kernel_run); PF_PATH_LANES4: the 4-lane
 * (SSE2) bilinear lanes whatever the CPU. */
enum { PF_PATH_BEST, PF_PATH_GENERAL, PF_PATH_QUERY, PF_PATH_LANES4 };
int pf_batch_path(const st_set *s, const st_sample_opts *o, const st_query *q, size_t n,
                  float *out, float *coverage, uint8_t *status, int path);

#endif

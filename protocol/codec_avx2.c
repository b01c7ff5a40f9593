/* protocol/codec_avx2.c - the AVX2 + F16C forms of the per-value codecs on the sampling hot
 * path (codec_simd.h), chosen at run time by their callers (stp_codec_have_avx2); elsewhere,
 * and for the layouts not done here, the portable loops of compact.c and bodies.c run.
 * Platform code lives here so that those stay portable. Results are bit for bit the portable
 * loops' for every input (test_codec_simd compares them).
 *
 * binary32 -> binary16 (stp_f16_encode_avx2): VCVTPS2PH with the rounding in the immediate
 * (nearest, ties to even, whatever MXCSR says) rounds as PROTOCOL.md 4.4.1 does, overflows
 * to infinity from 65520 up, and flushes to signed zero up to 2^-25; MXCSR.FTZ is ignored and
 * DAZ can only turn a binary32 subnormal (far below 2^-25) into the zero it becomes anyway.
 * Only NaN differs: the instruction keeps the top 10 payload bits (quieted), the spec says
 * 0x7E00 with the sign kept, so NaN lanes (exponent 31, mantissa not 0: no other input makes
 * one) get their 9 low payload bits cleared.
 *
 * binary16 -> binary32 (stp_f16_decode_avx2, and the derivatives of the compact queries):
 * VCVTPH2PS is exact for every finite and infinite half (subnormals too; DAZ is ignored) but
 * quiets a signalling NaN, where the spec (and the portable loop) keeps the payload as it
 * is: a batch of 8 holding a NaN, rare, takes the lanes of exponent 31 from the integer form
 * sign | 0x7F800000 | mantissa << 13.
 *
 * unorm (stp_unorm8/16_encode_avx2): bodies.c's rule in binary64, four values at a time:
 * v x max is exact and so is + 0.5, so the sum is the same with or without fusing; max(x, 0)
 * and min(x, max) are the portable selects operand for operand (MAXPD returns its second
 * operand for NaN, as `x > 0.0 ? x : 0.0` does); truncation, then unsigned saturating packs
 * of values already in range.
 *
 * Compact queries (stp_sample_queries_f32_avx2, layouts UV16 and UV16 + FACE16): one query
 * is 7 or 8 u16 lanes in one 16-byte load (the 14-byte layout's last query is copied out
 * first, so nothing past the request is read), widened to 8 dword lanes: the face as it is,
 * u and v converted and scaled by 2^-16 (exact), the derivatives through VCVTPH2PS; one
 * 32-byte store per query, its 4 bytes past the query overwritten by the next one (the last
 * query goes through a buffer). The f32-float layouts (FACE16 alone, none) are copies, left to
 * the portable loop.
 *
 * The other way, a client's compact queries (stp_put_queries_uv16_avx2, the same two layouts):
 * one stp_query in one 32-byte load (the last one copied out first), u and v rounded to
 * u16 fixed point (narrow_uv16 says how that equals stp_f32_to_unit16), the derivatives
 * through f16_of, blended with the face's low half into one 16-byte store per query (14 bytes
 * apart with FACE16, the next store overwriting the 2 extra; the last through a buffer).
 *
 * Owns: nothing but these loops and the CPU check.
 */
#include "codec_simd.h"

#include <string.h>

#if defined(__x86_64__) && defined(__GNUC__)
#include <cpuid.h>
#include <immintrin.h>

int stp_codec_have_avx2(void)
{
#ifdef __clang__
    /* clang's __builtin_cpu_supports has no "f16c": CPUID leaf 1, ECX bit 29, asked once
     * (CPUID traps in a VM) */
    static _Atomic int have = -1;
    int h = have;
    if (h < 0) {
        unsigned a, b, c, d;
        __builtin_cpu_init();
        h = __builtin_cpu_supports("avx2") && __get_cpuid(1, &a, &b, &c, &d) && (c >> 29 & 1);
        have = h;
    }
    return h;
#else
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("f16c");
#endif
}

#define CX_TARGET __attribute__((target("avx2,f16c")))
#define CX_INLINE __attribute__((target("avx2,f16c"), always_inline)) static inline

/* 8 halves from 8 floats, NaN lanes made 0x7E00 | sign. */
CX_INLINE __m128i f16_of(__m256 f)
{
    __m128i h = _mm256_cvtps_ph(f, _MM_FROUND_TO_NEAREST_INT);
    __m128i nan = _mm_cmpgt_epi16(_mm_and_si128(h, _mm_set1_epi16(0x7FFF)),
                                  _mm_set1_epi16(0x7C00));
    return _mm_andnot_si128(_mm_and_si128(nan, _mm_set1_epi16(0x01FF)), h);
}

/* The lanes of exponent 31 of the 8 halves x (as dwords x32) in f, from the integer form
 * (the NaN payload as it is); mask: those lanes. */
CX_INLINE __m256 f32_exp31(__m256 f, __m256i x32)
{
    __m256i mask = _mm256_cmpgt_epi32(_mm256_and_si256(x32, _mm256_set1_epi32(0x7FFF)),
                                      _mm256_set1_epi32(0x7BFF));
    __m256i alt = _mm256_or_si256(
        _mm256_or_si256(_mm256_slli_epi32(_mm256_and_si256(x32, _mm256_set1_epi32(0x8000)), 16),
                        _mm256_set1_epi32(0x7F800000)),
        _mm256_slli_epi32(_mm256_and_si256(x32, _mm256_set1_epi32(0x3FF)), 13));
    return _mm256_blendv_ps(f, _mm256_castsi256_ps(alt), _mm256_castsi256_ps(mask));
}

/* byte mask (of _mm_movemask_epi8) of the u16 lanes of x with exponent 31 */
CX_INLINE int exp31_bytes(__m128i x)
{
    return _mm_movemask_epi8(_mm_cmpgt_epi16(_mm_and_si128(x, _mm_set1_epi16(0x7FFF)),
                                             _mm_set1_epi16(0x7BFF)));
}

/* 8 halves to 8 floats, exactly (NaN payload kept). */
CX_INLINE __m256 f32_of(__m128i x)
{
    __m256 f = _mm256_cvtph_ps(x);
    if (__builtin_expect(exp31_bytes(x) != 0, 0))
        f = f32_exp31(f, _mm256_cvtepu16_epi32(x));
    return f;
}

CX_TARGET void stp_f16_encode_avx2(const float *v, size_t n, uint8_t *out)
{
    size_t i = 0;
    for (; i + 16 <= n; i += 16) {
        __m128i a = f16_of(_mm256_loadu_ps(v + i)), b = f16_of(_mm256_loadu_ps(v + i + 8));
        _mm_storeu_si128((__m128i *)(void *)(out + 2 * i), a);
        _mm_storeu_si128((__m128i *)(void *)(out + 2 * i + 16), b);
    }
    for (; i + 8 <= n; i += 8)
        _mm_storeu_si128((__m128i *)(void *)(out + 2 * i), f16_of(_mm256_loadu_ps(v + i)));
    if (i < n) {
        float t[8] = {0};
        uint8_t h[16];
        memcpy(t, v + i, (n - i) * sizeof *t);
        _mm_storeu_si128((__m128i *)(void *)h, f16_of(_mm256_loadu_ps(t)));
        memcpy(out + 2 * i, h, (n - i) * 2);
    }
}

CX_TARGET void stp_f16_decode_avx2(const uint8_t *p, size_t n, float *out)
{
    size_t i = 0;
    for (; i + 8 <= n; i += 8)
        _mm256_storeu_ps(out + i, f32_of(_mm_loadu_si128((const __m128i *)(const void *)(p + 2 * i))));
    if (i < n) {
        uint8_t h[16] = {0};
        float t[8];
        memcpy(h, p + 2 * i, (n - i) * 2);
        _mm256_storeu_ps(t, f32_of(_mm_loadu_si128((const __m128i *)(const void *)h)));
        memcpy(out + i, t, (n - i) * sizeof *t);
    }
}

/* 8 floats to unorm (max 255 or 65535) as 8 u16 lanes. */
CX_INLINE __m128i unorm_of(__m256 f, double max)
{
    const __m256d mx = _mm256_set1_pd(max), half = _mm256_set1_pd(0.5), zero = _mm256_setzero_pd();
    __m256d lo = _mm256_cvtps_pd(_mm256_castps256_ps128(f));
    __m256d hi = _mm256_cvtps_pd(_mm256_extractf128_ps(f, 1));
    lo = _mm256_min_pd(_mm256_max_pd(_mm256_add_pd(_mm256_mul_pd(lo, mx), half), zero), mx);
    hi = _mm256_min_pd(_mm256_max_pd(_mm256_add_pd(_mm256_mul_pd(hi, mx), half), zero), mx);
    return _mm_packus_epi32(_mm256_cvttpd_epi32(lo), _mm256_cvttpd_epi32(hi));
}

CX_TARGET void stp_unorm8_encode_avx2(const float *v, size_t n, uint8_t *out)
{
    size_t i = 0;
    for (; i + 16 <= n; i += 16) {
        __m128i a = unorm_of(_mm256_loadu_ps(v + i), 255.0);
        __m128i b = unorm_of(_mm256_loadu_ps(v + i + 8), 255.0);
        _mm_storeu_si128((__m128i *)(void *)(out + i), _mm_packus_epi16(a, b));
    }
    if (i < n) {
        float t[16] = {0};
        uint8_t b[16];
        memcpy(t, v + i, (n - i) * sizeof *t);
        _mm_storeu_si128((__m128i *)(void *)b, _mm_packus_epi16(unorm_of(_mm256_loadu_ps(t), 255.0),
                                                                unorm_of(_mm256_loadu_ps(t + 8), 255.0)));
        memcpy(out + i, b, n - i);
    }
}

CX_TARGET void stp_unorm16_encode_avx2(const float *v, size_t n, uint8_t *out)
{
    size_t i = 0;
    for (; i + 8 <= n; i += 8)
        _mm_storeu_si128((__m128i *)(void *)(out + 2 * i), unorm_of(_mm256_loadu_ps(v + i), 65535.0));
    if (i < n) {
        float t[8] = {0};
        uint8_t b[16];
        memcpy(t, v + i, (n - i) * sizeof *t);
        _mm_storeu_si128((__m128i *)(void *)b, unorm_of(_mm256_loadu_ps(t), 65535.0));
        memcpy(out + 2 * i, b, (n - i) * 2);
    }
}

/* One UV16 query: x holds u16 lanes [face (or anything), u, v, dudx, dvdx, dudy, dvdy, any];
 * the 8 dwords [face, u, v, dudx, ..., dvdy, any] with face = lane 0 zero-extended. */
CX_INLINE __m256i widen_uv16(__m128i x)
{
    __m256i x32 = _mm256_cvtepu16_epi32(x);
    __m256 uv = _mm256_mul_ps(_mm256_cvtepi32_ps(x32), _mm256_set1_ps(1.0f / 65536.0f));
    __m256 d = _mm256_cvtph_ps(x);
    if (__builtin_expect((exp31_bytes(x) & 0x3FC0) != 0, 0))  /* lanes 3..6 */
        d = f32_exp31(d, x32);
    __m256i r = _mm256_blend_epi32(x32, _mm256_castps_si256(uv), 0x06);
    return _mm256_blend_epi32(r, _mm256_castps_si256(d), 0x78);
}

CX_INLINE __m128i load16(const uint8_t *p)
{
    return _mm_loadu_si128((const __m128i *)(const void *)p);
}

CX_TARGET void stp_sample_queries_f32_avx2(const stp_sample_req *r, uint32_t first, uint32_t n,
                                           uint8_t *out)
{
    unsigned fl = r->p.flags & STP_SF_COMPACT_MASK;
    if (!(fl & STP_SF_UV16) || n == 0) {
        stp_sample_queries_f32_scalar(r, first, n, out);
        return;
    }
    size_t qs = stp_query_size(fl);
    const uint8_t *p = r->raw + (size_t)first * qs;
    uint8_t last[32];
    uint32_t i = 0;
    if (fl & STP_SF_FACE16) {
        for (; i + 1 < n; i++, p += 14, out += STP_QUERY_SIZE)
            _mm256_storeu_si256((__m256i *)(void *)out, widen_uv16(load16(p)));
        uint8_t q[16] = {0};
        memcpy(q, p, 14);
        _mm256_storeu_si256((__m256i *)(void *)last, widen_uv16(load16(q)));
    } else {
        /* [face lo, face hi, u, v, h x 4]: shifted by one lane for widen_uv16, the face's
         * dword put back */
        for (; i + 1 < n; i++, p += 16, out += STP_QUERY_SIZE) {
            __m128i x = load16(p);
            __m256i w = widen_uv16(_mm_bsrli_si128(x, 2));
            _mm256_storeu_si256((__m256i *)(void *)out,
                                _mm256_blend_epi32(w, _mm256_castsi128_si256(x), 0x01));
        }
        __m128i x = load16(p);
        __m256i w = widen_uv16(_mm_bsrli_si128(x, 2));
        _mm256_storeu_si256((__m256i *)(void *)last,
                            _mm256_blend_epi32(w, _mm256_castsi128_si256(x), 0x01));
    }
    memcpy(out, last, STP_QUERY_SIZE);
}

/* One query narrowed to the UV16 + FACE16 layout: x holds its 7 dwords (and one more, not
 * used); u16 lanes [face & 0xFFFF, u16(u), u16(v), f16(dudx), ..., f16(dvdy), any]. u16 is
 * compact.c's stp_f32_to_unit16: u x 2^16 is exact, VROUNDPS with the rounding in the
 * immediate rounds it to nearest, ties to even (whatever MXCSR says); MAXPS(r, 0) returns its
 * second operand for NaN, as `!(u > 0)` gives 0; MINPS clamps at 65535 (u >= 65535 / 65536,
 * infinity: the scalar's 65535; below that the rounded value is at most 65535 anyway); the
 * packs see values 0..65535 only. */
CX_INLINE __m128i narrow_uv16(__m256 x)
{
    __m128 lo = _mm256_castps256_ps128(x);
    __m128 r = _mm_round_ps(_mm_mul_ps(lo, _mm_set1_ps(65536.0f)),
                            _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC);
    r = _mm_min_ps(_mm_max_ps(r, _mm_setzero_ps()), _mm_set1_ps(65535.0f));
    __m128i uv = _mm_cvttps_epi32(r);
    uv = _mm_packus_epi32(uv, uv);                /* u16 lanes 1, 2: u, v */
    __m128i h = f16_of(x);                        /* u16 lanes 3..6: the derivatives */
    __m128i q = _mm_blend_epi16(_mm_castps_si128(lo), uv, 0x06);   /* lane 0: face low */
    return _mm_blend_epi16(q, h, 0x78);
}

CX_INLINE __m256 load32(const stp_query *q)
{
    return _mm256_loadu_ps((const float *)(const void *)q);
}

CX_TARGET void stp_put_queries_uv16_avx2(const stp_query *q, size_t n, int face16, uint8_t *out)
{
    if (n == 0)
        return;
    float last[8] = {0};
    memcpy(last, &q[n - 1], sizeof *q);           /* nothing past the queries is read */
    if (face16) {
        /* 16-byte stores 14 bytes apart: each one's last 2 bytes are the next query's */
        for (size_t i = 0; i + 1 < n; i++, out += 14)
            _mm_storeu_si128((__m128i *)(void *)out, narrow_uv16(load32(&q[i])));
        uint8_t t[16];
        _mm_storeu_si128((__m128i *)(void *)t, narrow_uv16(_mm256_loadu_ps(last)));
        memcpy(out, t, 14);
        return;
    }
    /* [face lo, face hi, u, v, h x 4]: the 14-byte form shifted up a lane, the face's high
     * half put back */
    for (size_t i = 0; i + 1 < n; i++, out += 16) {
        __m256 x = load32(&q[i]);
        __m128i w = _mm_bslli_si128(narrow_uv16(x), 2);
        _mm_storeu_si128((__m128i *)(void *)out,
                         _mm_blend_epi16(w, _mm_castps_si128(_mm256_castps256_ps128(x)), 0x03));
    }
    __m256 x = _mm256_loadu_ps(last);
    __m128i w = _mm_bslli_si128(narrow_uv16(x), 2);
    _mm_storeu_si128((__m128i *)(void *)out,
                     _mm_blend_epi16(w, _mm_castps_si128(_mm256_castps256_ps128(x)), 0x03));
}

#else /* no x86-64 intrinsics: the portable loops */

int stp_codec_have_avx2(void)
{
    return 0;
}

void stp_f16_encode_avx2(const float *v, size_t n, uint8_t *out)
{
    stp_f16_encode_scalar(v, n, out);
}

void stp_f16_decode_avx2(const uint8_t *p, size_t n, float *out)
{
    stp_f16_decode_scalar(p, n, out);
}

void stp_sample_queries_f32_avx2(const stp_sample_req *r, uint32_t first, uint32_t n,
                                 uint8_t *out)
{
    stp_sample_queries_f32_scalar(r, first, n, out);
}

void stp_put_queries_uv16_avx2(const stp_query *q, size_t n, int face16, uint8_t *out)
{
    stp_put_queries_uv16_scalar(q, n, face16, out);
}

void stp_unorm8_encode_avx2(const float *v, size_t n, uint8_t *out)
{
    stp_unorm8_encode_scalar(v, n, out);
}

void stp_unorm16_encode_avx2(const float *v, size_t n, uint8_t *out)
{
    stp_unorm16_encode_scalar(v, n, out);
}

#endif

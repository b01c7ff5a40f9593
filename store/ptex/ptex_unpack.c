/* store/ptex/ptex_unpack.c - difference decoding and planar -> interleaved (see
 * ptex_unpack.h).
 *
 * Difference decoding is a prefix sum: 32 bytes (AVX2, chosen at run time) or 16 bytes (SSE2)
 * at a time with log2 shifted adds, then the total of everything before added to every lane
 * (kept in a register with one add per step, so the steps do not wait for each other).
 * Interleaving takes 16 (8, 4) channels of each plane and zips them with unpack
 * instructions; shapes without a vector path (3 channels of u8/u16) and row tails go through
 * the plain loop.
 */
#include "ptex_unpack.h"
#include "loadpath.h"

#include <string.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define UNDIFF_AVX2 1

/* 32 bytes per step: a prefix sum inside each 16-byte lane (log2 shifted adds), the low
 * lane's total added to the high lane, then the running total of everything before (carry)
 * added. The carry is the only loop-carried value and takes one add per step (the totals are
 * computed off that chain). Returns the bytes done (a multiple of 32). */
__attribute__((target("avx2"))) static size_t undiff8_avx2(uint8_t *p, size_t bytes)
{
    const __m256i b15 = _mm256_set1_epi8(15);
    __m256i carry = _mm256_setzero_si256();
    size_t i = 0;
    for (; i + 32 <= bytes; i += 32) {
        __m256i x = _mm256_loadu_si256((const __m256i *)(const void *)(p + i));
        x = _mm256_add_epi8(x, _mm256_slli_si256(x, 1));
        x = _mm256_add_epi8(x, _mm256_slli_si256(x, 2));
        x = _mm256_add_epi8(x, _mm256_slli_si256(x, 4));
        x = _mm256_add_epi8(x, _mm256_slli_si256(x, 8));
        __m256i t = _mm256_shuffle_epi8(x, b15);                  /* lane totals */
        x = _mm256_add_epi8(x, _mm256_permute2x128_si256(t, t, 0x08));
        __m256i tot = _mm256_permute4x64_epi64(_mm256_shuffle_epi8(x, b15), 0xff);
        _mm256_storeu_si256((__m256i *)(void *)(p + i), _mm256_add_epi8(x, carry));
        carry = _mm256_add_epi8(carry, tot);
    }
    return i;
}

/* The same for u16: 16 values per step. Returns the values done. */
__attribute__((target("avx2"))) static size_t undiff16_avx2(uint16_t *q, size_t n)
{
    const __m256i w7 = _mm256_set1_epi16(0x0f0e); /* bytes 14, 15: word 7 of the lane */
    __m256i carry = _mm256_setzero_si256();
    size_t i = 0;
    for (; i + 16 <= n; i += 16) {
        __m256i x = _mm256_loadu_si256((const __m256i *)(const void *)(q + i));
        x = _mm256_add_epi16(x, _mm256_slli_si256(x, 2));
        x = _mm256_add_epi16(x, _mm256_slli_si256(x, 4));
        x = _mm256_add_epi16(x, _mm256_slli_si256(x, 8));
        __m256i t = _mm256_shuffle_epi8(x, w7);
        x = _mm256_add_epi16(x, _mm256_permute2x128_si256(t, t, 0x08));
        __m256i tot = _mm256_permute4x64_epi64(_mm256_shuffle_epi8(x, w7), 0xff);
        _mm256_storeu_si256((__m256i *)(void *)(q + i), _mm256_add_epi16(x, carry));
        carry = _mm256_add_epi16(carry, tot);
    }
    return i;
}
#endif

STU_LOADPATH
void st_ptx_undiff(size_t csize, uint8_t *p, size_t bytes)
{
    size_t i = 0;
#ifdef UNDIFF_AVX2
    int avx2 = __builtin_cpu_supports("avx2"); /* what libgcc found at start-up */
#endif
    if (csize == 1) {
        uint8_t prev = 0;
#ifdef UNDIFF_AVX2
        if (avx2)
            i = undiff8_avx2(p, bytes);
#endif
#ifdef __SSE2__
        __m128i carry = _mm_set1_epi8((char)(i ? p[i - 1] : 0));
        for (; i + 16 <= bytes; i += 16) {
            __m128i x = _mm_loadu_si128((const __m128i *)(const void *)(p + i));
            x = _mm_add_epi8(x, _mm_slli_si128(x, 1));
            x = _mm_add_epi8(x, _mm_slli_si128(x, 2));
            x = _mm_add_epi8(x, _mm_slli_si128(x, 4));
            x = _mm_add_epi8(x, _mm_slli_si128(x, 8));
            __m128i t = _mm_unpackhi_epi8(x, x);  /* byte 15 to every lane */
            t = _mm_unpackhi_epi16(t, t);
            t = _mm_shuffle_epi32(t, 0xff);
            _mm_storeu_si128((__m128i *)(void *)(p + i), _mm_add_epi8(x, carry));
            carry = _mm_add_epi8(carry, t);    /* the only loop-carried add */
        }
#endif
        if (i)
            prev = p[i - 1];
        for (; i < bytes; i++)
            prev = p[i] = (uint8_t)(p[i] + prev);
    } else if (csize == 2) {
        uint16_t prev = 0, *q = (uint16_t *)(void *)p;
        size_t n = bytes / 2;
#ifdef UNDIFF_AVX2
        if (avx2)
            i = undiff16_avx2(q, n);
#endif
#ifdef __SSE2__
        __m128i carry = _mm_set1_epi16((short)(i ? q[i - 1] : 0));
        for (; i + 8 <= n; i += 8) {
            __m128i x = _mm_loadu_si128((const __m128i *)(const void *)(q + i));
            x = _mm_add_epi16(x, _mm_slli_si128(x, 2));
            x = _mm_add_epi16(x, _mm_slli_si128(x, 4));
            x = _mm_add_epi16(x, _mm_slli_si128(x, 8));
            __m128i t = _mm_shuffle_epi32(_mm_shufflehi_epi16(x, 0xff), 0xff); /* word 7 */
            _mm_storeu_si128((__m128i *)(void *)(q + i), _mm_add_epi16(x, carry));
            carry = _mm_add_epi16(carry, t);
        }
#endif
        if (i)
            prev = q[i - 1];
        for (; i < n; i++)
            prev = q[i] = (uint16_t)(q[i] + prev);
    }
}

/* Plain loop: channel c of texels [x0, w) of one row. */
#define ROW_TAIL(T, NC)                                                                       \
    do {                                                                                      \
        for (unsigned c = 0; c < (NC); c++) {                                                 \
            const T *s = (const T *)(const void *)(src + ((size_t)c * h + y) * w * csize);    \
            T *d = (T *)(void *)(dst + y * stride) + c;                                       \
            for (uint32_t x = x0; x < w; x++)                                                 \
                d[(size_t)x * (NC)] = s[x];                                                   \
        }                                                                                     \
    } while (0)

STU_LOADPATH
void st_ptx_planar_to_rows(size_t csize, unsigned nc, const uint8_t *src, uint32_t w,
                           uint32_t h, uint8_t *dst, size_t stride)
{
    size_t plane = (size_t)w * h * csize; /* bytes of one channel plane */
    for (uint32_t y = 0; y < h; y++) {
        uint32_t x0 = 0;
        const uint8_t *s0 = src + (size_t)y * w * csize;
        uint8_t *d = dst + y * stride;
        if (nc == 1) {
            memcpy(d, s0, (size_t)w * csize);
            continue;
        }
#ifdef __SSE2__
#define LD(k, off) _mm_loadu_si128((const __m128i *)(const void *)(s0 + (k) * plane + (off)))
#define ST(i, v) _mm_storeu_si128((__m128i *)(void *)(o + 16 * (i)), v)
        if (csize == 1 && nc == 4) {
            for (; x0 + 16 <= w; x0 += 16) {
                __m128i a = LD(0, x0), b = LD(1, x0), c = LD(2, x0), e = LD(3, x0);
                __m128i ab0 = _mm_unpacklo_epi8(a, b), ab1 = _mm_unpackhi_epi8(a, b);
                __m128i ce0 = _mm_unpacklo_epi8(c, e), ce1 = _mm_unpackhi_epi8(c, e);
                uint8_t *o = d + (size_t)x0 * 4;
                ST(0, _mm_unpacklo_epi16(ab0, ce0));
                ST(1, _mm_unpackhi_epi16(ab0, ce0));
                ST(2, _mm_unpacklo_epi16(ab1, ce1));
                ST(3, _mm_unpackhi_epi16(ab1, ce1));
            }
        } else if (csize == 1 && nc == 2) {
            for (; x0 + 16 <= w; x0 += 16) {
                __m128i a = LD(0, x0), b = LD(1, x0);
                uint8_t *o = d + (size_t)x0 * 2;
                ST(0, _mm_unpacklo_epi8(a, b));
                ST(1, _mm_unpackhi_epi8(a, b));
            }
        } else if (csize == 2 && nc == 4) {
            for (; x0 + 8 <= w; x0 += 8) {
                __m128i a = LD(0, 2 * x0), b = LD(1, 2 * x0), c = LD(2, 2 * x0), e = LD(3, 2 * x0);
                __m128i ab0 = _mm_unpacklo_epi16(a, b), ab1 = _mm_unpackhi_epi16(a, b);
                __m128i ce0 = _mm_unpacklo_epi16(c, e), ce1 = _mm_unpackhi_epi16(c, e);
                uint8_t *o = d + (size_t)x0 * 8;
                ST(0, _mm_unpacklo_epi32(ab0, ce0));
                ST(1, _mm_unpackhi_epi32(ab0, ce0));
                ST(2, _mm_unpacklo_epi32(ab1, ce1));
                ST(3, _mm_unpackhi_epi32(ab1, ce1));
            }
        } else if (csize == 2 && nc == 2) {
            for (; x0 + 8 <= w; x0 += 8) {
                __m128i a = LD(0, 2 * x0), b = LD(1, 2 * x0);
                uint8_t *o = d + (size_t)x0 * 4;
                ST(0, _mm_unpacklo_epi16(a, b));
                ST(1, _mm_unpackhi_epi16(a, b));
            }
        } else if (csize == 4 && nc == 4) {
            for (; x0 + 4 <= w; x0 += 4) {
                __m128i a = LD(0, 4 * x0), b = LD(1, 4 * x0), c = LD(2, 4 * x0), e = LD(3, 4 * x0);
                __m128i ab0 = _mm_unpacklo_epi32(a, b), ab1 = _mm_unpackhi_epi32(a, b);
                __m128i ce0 = _mm_unpacklo_epi32(c, e), ce1 = _mm_unpackhi_epi32(c, e);
                uint8_t *o = d + (size_t)x0 * 16;
                ST(0, _mm_unpacklo_epi64(ab0, ce0));
                ST(1, _mm_unpackhi_epi64(ab0, ce0));
                ST(2, _mm_unpacklo_epi64(ab1, ce1));
                ST(3, _mm_unpackhi_epi64(ab1, ce1));
            }
        } else if (csize == 4 && nc == 3) {
            /* 4 texels: r0 g0 b0 r1 | g1 b1 r2 g2 | b2 r3 g3 b3, shuffled as integers (moves
             * only: float bit patterns, NaNs included, pass unchanged) */
            for (; x0 + 4 <= w; x0 += 4) {
                __m128 r = _mm_castsi128_ps(LD(0, 4 * x0)), g = _mm_castsi128_ps(LD(1, 4 * x0));
                __m128 b = _mm_castsi128_ps(LD(2, 4 * x0));
                __m128 rg0 = _mm_unpacklo_ps(r, g), rg1 = _mm_unpackhi_ps(r, g);
                __m128 br0 = _mm_unpacklo_ps(b, r), br1 = _mm_unpackhi_ps(b, r);
                __m128 gb0 = _mm_unpacklo_ps(g, b), gb1 = _mm_unpackhi_ps(g, b);
                uint8_t *o = d + (size_t)x0 * 12;
                ST(0, _mm_castps_si128(_mm_shuffle_ps(rg0, br0, _MM_SHUFFLE(3, 0, 1, 0))));
                ST(1, _mm_castps_si128(_mm_shuffle_ps(gb0, rg1, _MM_SHUFFLE(1, 0, 3, 2))));
                ST(2, _mm_castps_si128(_mm_shuffle_ps(br1, gb1, _MM_SHUFFLE(3, 2, 3, 0))));
            }
        } else if (csize == 4 && nc == 2) {
            for (; x0 + 4 <= w; x0 += 4) {
                __m128i a = LD(0, 4 * x0), b = LD(1, 4 * x0);
                uint8_t *o = d + (size_t)x0 * 8;
                ST(0, _mm_unpacklo_epi32(a, b));
                ST(1, _mm_unpackhi_epi32(a, b));
            }
        }
#undef LD
#undef ST
#endif
        if (x0 == w)
            continue;
        switch (csize * 8 + nc) {
        case 8 + 2:  ROW_TAIL(uint8_t, 2); break;
        case 8 + 3:  ROW_TAIL(uint8_t, 3); break;
        case 8 + 4:  ROW_TAIL(uint8_t, 4); break;
        case 16 + 2: ROW_TAIL(uint16_t, 2); break;
        case 16 + 3: ROW_TAIL(uint16_t, 3); break;
        case 16 + 4: ROW_TAIL(uint16_t, 4); break;
        case 32 + 2: ROW_TAIL(float, 2); break; /* float: the set's own type for f32 */
        case 32 + 3: ROW_TAIL(float, 3); break;
        default:     ROW_TAIL(float, 4); break;
        }
    }
}
#undef ROW_TAIL

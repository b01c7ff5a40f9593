/* store/ptex/ptex_adler.c - Adler-32 (see ptex_adler.h), 16 bytes per step with SSE2 (part of
 * every x86-64 CPU), plain C elsewhere and for the tail.
 *
 * Adler-32 of bytes x[0..n) from (a0, b0): a = a0 + sum x[j], b = b0 + n*a0 + sum (n-j)*x[j],
 * both mod 65521. In blocks of 16 with m blocks in a round, byte i of block k weighs
 * (16 - i) + 16*(m-1-k): the first part is a multiply-add against constant weights, the second
 * is 16 times the running sum of the block sums before block k (vs1_acc below). A round is at
 * most 1024 blocks so that no 32-bit lane overflows (vs1_acc <= 2040 * 1024 * 1023 / 2 per
 * lane), then a and b are reduced mod 65521.
 */
#include "ptex_adler.h"

#ifdef __SSE2__
#include <emmintrin.h>
#endif

#define ADLER_BASE 65521u
#define ADLER_NMAX 5552u     /* scalar: largest n with 255n(n+1)/2 + (n+1)(BASE-1) < 2^32 */

static uint32_t adler_scalar(uint32_t a, uint32_t b, const uint8_t *p, size_t n, uint32_t *bo)
{
    while (n) {
        size_t k = n < ADLER_NMAX ? n : ADLER_NMAX;
        n -= k;
        while (k--) {
            a += *p++;
            b += a;
        }
        a %= ADLER_BASE;
        b %= ADLER_BASE;
    }
    *bo = b;
    return a;
}

uint32_t st_ptx_adler32(uint32_t adler, const uint8_t *p, size_t n)
{
    uint32_t a = adler & 0xffffu, b = adler >> 16;
#ifdef __SSE2__
    const __m128i zero = _mm_setzero_si128();
    const __m128i w_lo = _mm_setr_epi16(16, 15, 14, 13, 12, 11, 10, 9);
    const __m128i w_hi = _mm_setr_epi16(8, 7, 6, 5, 4, 3, 2, 1);
    while (n >= 16) {
        size_t m = n / 16 < 1024 ? n / 16 : 1024;
        __m128i vs1 = zero, vs2 = zero, vs1_acc = zero;
        for (size_t k = 0; k < m; k++, p += 16) {
            __m128i v = _mm_loadu_si128((const __m128i *)(const void *)p);
            vs1_acc = _mm_add_epi32(vs1_acc, vs1);
            vs1 = _mm_add_epi32(vs1, _mm_sad_epu8(v, zero));
            vs2 = _mm_add_epi32(vs2, _mm_madd_epi16(_mm_unpacklo_epi8(v, zero), w_lo));
            vs2 = _mm_add_epi32(vs2, _mm_madd_epi16(_mm_unpackhi_epi8(v, zero), w_hi));
        }
        uint32_t l1[4], l1a[4], l2[4];
        _mm_storeu_si128((__m128i *)(void *)l1, vs1);
        _mm_storeu_si128((__m128i *)(void *)l1a, vs1_acc);
        _mm_storeu_si128((__m128i *)(void *)l2, vs2);
        uint64_t s1 = (uint64_t)l1[0] + l1[2]; /* psadbw: sums in lanes 0 and 2 */
        uint64_t s1a = (uint64_t)l1a[0] + l1a[2];
        uint64_t s2 = (uint64_t)l2[0] + l2[1] + l2[2] + l2[3];
        uint64_t bb = b + (uint64_t)a * (16 * m) + 16 * s1a + s2;
        a = (uint32_t)((a + s1) % ADLER_BASE);
        b = (uint32_t)(bb % ADLER_BASE);
        n -= 16 * m;
    }
#endif
    a = adler_scalar(a, b, p, n, &b);
    return b << 16 | a;
}

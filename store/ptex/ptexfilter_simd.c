/* store/ptex/ptexfilter_simd.c - the AVX2 + FMA inner loop of the Ptex filters for 4-channel u8
 * data (two texels per instruction), chosen at run time when the CPU has it. Platform code
 * lives here so that ptexfilter.c stays portable; elsewhere pf_have_avx2() is 0.
 *
 * Owns: nothing but this loop. Its sums run in a different order than the portable loop, so
 * results differ from it (and from Ptex) by float rounding only.
 */
#include "ptexfilter_kernel.h"

#include <stddef.h>

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>

int pf_have_avx2(void)
{
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
}

__attribute__((target("avx2,fma")))
void pf_rows_u8x4_avx2(const uint8_t *base, size_t rowb, const float *ku, int uw,
                       const float *kv, int vw, float acc[4])
{
    __m128 a = _mm_loadu_ps(acc);
    for (int j = 0; j < vw; j++) {
        const uint8_t *p = base + (size_t)j * rowb;
        __m256 rs = _mm256_setzero_ps();
        int i = 0;
        for (; i + 1 < uw; i += 2) {
            __m128i b = _mm_loadl_epi64((const __m128i *)(const void *)(p + 4 * i));
            __m256 t = _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(b));
            __m256 w = _mm256_set_m128(_mm_set1_ps(ku[i + 1]), _mm_set1_ps(ku[i]));
            rs = _mm256_fmadd_ps(t, w, rs);
        }
        __m128 row = _mm_add_ps(_mm256_castps256_ps128(rs), _mm256_extractf128_ps(rs, 1));
        if (i < uw) {
            int x;
            __builtin_memcpy(&x, p + 4 * i, 4);
            __m128 t = _mm_cvtepi32_ps(_mm_cvtepu8_epi32(_mm_cvtsi32_si128(x)));
            row = _mm_fmadd_ps(t, _mm_set1_ps(ku[i]), row);
        }
        a = _mm_fmadd_ps(row, _mm_set1_ps(kv[j]), a);
    }
    _mm_storeu_ps(acc, a);
}

#else

int pf_have_avx2(void)
{
    return 0;
}

void pf_rows_u8x4_avx2(const uint8_t *base, size_t rowb, const float *ku, int uw,
                       const float *kv, int vw, float acc[4])
{
    (void)base; (void)rowb; (void)ku; (void)uw; (void)kv; (void)vw; (void)acc;
}

#endif

/* tests/unit/test_ptexfilter_w4sum.c - session 20 (wk20): the width-4 kernel's weight taken
 * from its build (ptexfilter_kernel.h pk_build_w4s: pk_width4_axis_s' sums of the hermite
 * taps, ptexfilter_simd.c's pf_kernel_eval2s_avx2 / pf_kernel_eval1s_avx2 summing the
 * evaluated taps in registers), the integer floor and ceil (pk_ifloor, pk_iceil) and the
 * division's vector store (pf_put_scaled).
 *
 * pk_build_w4s must build pk_build's kernel bit for bit and return the pk_weight that kernel
 * has after pk_strip_zeros (every width-4 filter and sharpness, with and without AVX2,
 * widths from a texel of the face to several faces, each case of pk_width4_axis on either
 * axis, footprints at and near texel centres where end taps are zero); the summing
 * evaluations the portable weights and pk_accumulate's sums for 1 to 12 taps; the integer
 * floor and ceil the float ones converted; pf_put_scaled the loop's products, nothing past
 * the nc values written. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <string.h>

#include "ptexfilter_kernel.h"
#include "sample.h"
#include "../common/skip_unless.h"

static uint32_t rng = 2020;
static float rnd01(void) /* [0, 1) */
{
    rng = rng * 1664525u + 1013904223u;
    return (float)(rng >> 8) / 16777216.0f;
}

static int same_bits(float x, float y)
{
    return memcmp(&x, &y, sizeof x) == 0;
}

static const unsigned filters[] = {ST_FILTER_PTEX_GAUSSIAN, ST_FILTER_PTEX_BICUBIC,
                                   ST_FILTER_PTEX_BSPLINE, ST_FILTER_PTEX_CATMULLROM,
                                   ST_FILTER_PTEX_MITCHELL};

/* A coordinate in [0, 1): anywhere, or on / a few ulps from a texel centre of a resolution
 * up to the face's (where the bicubic family's end taps are zero). */
static float coord(int fres)
{
    if (rnd01() < 0.5f)
        return rnd01();
    int r = (int)(rnd01() * (float)(fres + 3));
    float res = (float)(1 << r), x = ((float)(int)(rnd01() * res) + 0.5f) / res;
    int ulps = (int)(rnd01() * 5.0f) - 2;
    for (; ulps > 0; ulps--)
        x = nextafterf(x, 2.0f);
    for (; ulps < 0; ulps++)
        x = nextafterf(x, -1.0f);
    return x < 1.0f ? x : 0.5f;
}

/* A width relative to a face of 2^fres texels: 1/2^fres (and under: pk_width4_axis clamps
 * it) to several faces, log-uniform, or exactly a power of 2. */
static float width(int fres)
{
    float w = exp2f(-(float)fres - 1.0f + rnd01() * ((float)fres + 3.0f));
    return rnd01() < 0.2f ? exp2f((float)(int)log2f(w)) : w;
}

static void build_w4s_is_pk_build_and_its_stripped_weight(void **state)
{
    (void)state;
    long cases = 0, bad = 0;
    for (int avx2 = 0; avx2 <= 1; avx2++) {
        if (avx2 && !pf_have_avx2())
            break;
        for (size_t fi = 0; fi < sizeof filters / sizeof filters[0]; fi++)
            for (int sharp = 0; sharp < 3; sharp++) {
                pk_params p;
                pk_params_init(&p, filters[fi], 0.5f * (float)sharp, avx2);
                for (int t = 0; t < 20000; t++) {
                    int fu = (int)(rnd01() * 11.0f), fv = rnd01() < 0.3f ? fu : (int)(rnd01() * 11.0f);
                    float u = coord(fu), v = coord(fv), uw = width(fu);
                    float vw = rnd01() < 0.3f ? uw : width(fv);
                    pk a, b;
                    memset(&a, 0, sizeof a);
                    memset(&b, 0, sizeof b);
                    pk_build(&p, &a, u, v, uw, vw, fu, fv);
                    float w = pk_build_w4s(&p, &b, u, v, uw, vw, fu, fv);
                    int ok = a.ulog2 == b.ulog2 && a.vlog2 == b.vlog2 && a.u == b.u &&
                             a.v == b.v && a.uw == b.uw && a.vw == b.vw && a.ku0 == b.ku0 &&
                             a.kv0 == b.kv0 && a.rot == b.rot &&
                             memcmp(a.kub, b.kub, sizeof(float) * (size_t)a.uw) == 0 &&
                             memcmp(a.kvb, b.kvb, sizeof(float) * (size_t)a.vw) == 0;
                    pk_strip_zeros(&a);
                    if (ok && a.uw > 0 && a.vw > 0)
                        ok = same_bits(w, pk_weight(&a));
                    if (!ok && bad < 5)
                        print_message("differs: filter %u avx2 %d u %a v %a uw %a vw %a fres %d %d\n",
                                      filters[fi], avx2, (double)u, (double)v, (double)uw,
                                      (double)vw, fu, fv);
                    bad += !ok;
                    cases++;
                }
            }
    }
    print_message("%ld kernels\n", cases);
    assert_int_equal(bad, 0);
}

static void summing_evaluations_match_the_loops(void **state)
{
    (void)state;
    ST_SKIP_WITHOUT_AVX2();
    long bad = 0;
    for (size_t fi = 0; fi < sizeof filters / sizeof filters[0]; fi++) {
        pk_params p;
        pk_params_init(&p, filters[fi], 0.5f, 1);
        for (int t = 0; t < 20000; t++) {
            int nu = 1 + (int)(rnd01() * (PK_MAX / 2)), nv = 1 + (int)(rnd01() * (PK_MAX / 2));
            float x1u = -2.5f * rnd01(), su = t % 5 ? 1.0f / (1.0f + rnd01()) : 1.0f;
            float x1v = t % 11 ? -2.5f * rnd01() : -40.0f * rnd01(), sv = 1.0f / (1.0f + rnd01());
            float wu[PK_MAX], wv[PK_MAX], ru[PK_MAX], rv[PK_MAX];
            pk_kernel_eval(&p, x1u, su, ru, nu);
            pk_kernel_eval(&p, x1v, sv, rv, nv);
            pf_v4 s = pf_kernel_eval2s_avx2(&p, x1u, su, wu, nu, x1v, sv, wv, nv);
            bad += memcmp(wu, ru, sizeof(float) * (size_t)nu) != 0 ||
                   memcmp(wv, rv, sizeof(float) * (size_t)nv) != 0 ||
                   !same_bits(s[0], pk_accumulate(ru, nu)) ||
                   !same_bits(s[1], pk_accumulate(rv, nv));
            float s1 = pf_kernel_eval1s_avx2(&p, x1v, sv, wu, nv);
            bad += memcmp(wu, rv, sizeof(float) * (size_t)nv) != 0 ||
                   !same_bits(s1, pk_accumulate(rv, nv));
        }
    }
    assert_int_equal(bad, 0);
}

static void integer_floor_ceil_and_scaled_store(void **state)
{
    (void)state;
    long bad = 0;
    for (int t = 0; t < 200000; t++) {
        float x = (rnd01() - 0.5f) * (t % 3 ? 40.0f : 1e7f);
        if (t % 7 == 0)
            x = (float)(int)x; /* integral */
        bad += pk_ifloor(x) != (int)pk_floor(x) || pk_iceil(x) != (int)pk_ceil(x);
        unsigned nc = 1 + (unsigned)(t % 4);
        pf_v4 acc = {rnd01() * 300.0f, rnd01() * 300.0f, rnd01() * 300.0f, rnd01() * 300.0f};
        float scale = 1.0f / (rnd01() * 255.0f + 0.5f), out[5], ref[5];
        for (int i = 0; i < 5; i++)
            out[i] = ref[i] = -7.0f;
        pf_put_scaled(out, acc, scale, nc);
        for (unsigned ch = 0; ch < nc; ch++)
            ref[ch] = acc[ch] * scale;
        bad += memcmp(out, ref, sizeof out) != 0;
    }
    assert_int_equal(bad, 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(build_w4s_is_pk_build_and_its_stripped_weight),
        cmocka_unit_test(summing_evaluations_match_the_loops),
        cmocka_unit_test(integer_floor_ceil_and_scaled_store),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

/* tests/unit/test_ptexfilter_intwin.c - the window functions of 1-channel u8 and u16 texels
 * (ptexfilter_simd.c's pf_window_select and pf_small_select for those types: windows of at
 * most 4 x 4 texels with their shape as constants and the lanes past a row not cleared)
 * against window4's operations written out in scalar C (fmaf down the rows of 4 columns from
 * +0, the columns past the row 0, then fmaf(col, ku, +0) + 0, (q0 + q2) + (q1 + q3), added
 * to acc): bit for bit, for every shape up to 4 x 4 (and rows of up to 8 for the window
 * function), weights of both signs, zeros of both signs, denormals and large values, texels
 * 0 and the largest value, and the largest value just past the row.
 * Skipped on a CPU without AVX2 + FMA + F16C (the portable loops run there). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include "skip_unless.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "ptexfilter_kernel.h"
#include "sample.h"

static uint32_t rng = 11;
static float rndf(void) /* [0, 1) */
{
    rng = rng * 1664525u + 1013904223u;
    return (float)(rng >> 8) / 16777216.0f;
}

static float texel(unsigned dt, const uint8_t *p)
{
    if (dt == ST_DT_U8)
        return (float)*p;
    uint16_t v;
    memcpy(&v, p, 2);
    return (float)v;
}

/* window4's result for a 1-channel window of uw <= 4 columns: its operations in its order
 * (the FMAs exact-then-rounded, as fmaf; C11 contracts nothing). */
static float window4_ref(const uint8_t *base, size_t rowb, unsigned dt, const float *ku,
                         int uw, const float *kv, int vw, float acc)
{
    size_t es = st_dtype_size(dt);
    float col[4] = {0.0f, 0.0f, 0.0f, 0.0f};
    for (int j = 0; j < vw; j++)
        for (int i = 0; i < 4; i++) {
            float t = i < uw ? texel(dt, base + (size_t)j * rowb + (size_t)i * es) : 0.0f;
            col[i] = fmaf(t, kv[j], col[i]);
        }
    float q[4];
    for (int i = 0; i < 4; i++)
        q[i] = fmaf(col[i], i < uw ? ku[i] : 0.0f, 0.0f) + 0.0f;
    return acc + ((q[0] + q[2]) + (q[1] + q[3]));
}

static float weight(void)
{
    static const float odd[] = {0.0f, -0.0f, 1e-40f, -1e-40f, 1e-30f, -3e-39f, 1e20f, -1.0f};
    float r = rndf();
    if (r < 0.15f)
        return odd[(int)(rndf() * 8.0f)];
    return rndf() * 2.5f - 0.75f; /* the bicubic family's negative lobes too */
}

static void integer_windows_are_window4_bit_for_bit(void **state)
{
    (void)state;
    ST_SKIP_WITHOUT_AVX2();
    enum { RES = 16, SLACK = 64 };
    int cases = 0, small = 0;
    for (unsigned dt = ST_DT_U8; dt <= ST_DT_U16; dt++) {
        pf_window_fn win = pf_window_select(dt, 1), sm = pf_small_select(dt, 1);
        assert_non_null(win);
        assert_non_null(sm);
        size_t es = st_dtype_size(dt), rowb = RES * es;
        const float maxv = dt == ST_DT_U8 ? 255.0f : 65535.0f;
        uint8_t *face = malloc(RES * rowb + SLACK);
        assert_non_null(face);
        for (int r = 0; r < 40000; r++) {
            for (size_t i = 0; i < RES * RES; i++) {
                float x = rndf();
                float t = x < 0.2f ? 0.0f : x < 0.3f ? maxv : floorf(rndf() * maxv);
                if (dt == ST_DT_U8)
                    face[i] = (uint8_t)t;
                else {
                    uint16_t v = (uint16_t)t;
                    memcpy(face + i * es, &v, 2);
                }
            }
            memset(face + RES * rowb, 0xff, SLACK);
            int uw = 1 + r % 4, vw = 1 + (r / 4) % 4;
            if (r % 9 == 0) /* past the constant shapes: the general window */
                vw = 5 + r % 4;
            int u0 = r % 5 == 0 ? RES - uw : (int)(rndf() * (float)(RES - uw + 1));
            int v0 = r % 7 == 0 ? RES - vw : (int)(rndf() * (float)(RES - vw + 1));
            float ku[8], kv[8];
            for (int i = 0; i < 8; i++) {
                ku[i] = weight();
                kv[i] = weight();
            }
            const uint8_t *base = face + (size_t)v0 * rowb + (size_t)u0 * es;
            float acc0 = r % 3 == 0 ? -0.0f : rndf() * 4.0f - 2.0f;
            float want = window4_ref(base, rowb, dt, ku, uw, kv, vw, acc0);
            pf_v4 acc = {acc0, 2.0f, 3.0f, 4.0f};
            pf_v4 got = win(base, rowb, ku, uw, kv, vw, acc);
            assert_memory_equal(&got, &want, sizeof want); /* lane 0 (clang takes no &got[0]) */
            cases++;
            if (uw <= 2 && vw <= 2) {
                got = sm(base, rowb, ku, uw, kv, vw, acc);
                assert_memory_equal(&got, &want, sizeof want);
                small++;
            }
        }
        free(face);
    }
    print_message("%d windows (%d of them small) bit for bit window4's\n", cases, small);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(integer_windows_are_window4_bit_for_bit),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

/* tests/unit/test_ptex_unpack.c - the block unpacking steps of the Ptex reader
 * (ptex_unpack.h): the vector paths give the same bytes as the plain definition for every
 * channel size and count, every width (vector bodies and tails), strided destinations (tiles)
 * and random data. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <stdlib.h>
#include <string.h>

#include "ptex_unpack.h"

static uint32_t rng = 99;
static uint8_t rnd(void)
{
    rng = rng * 1664525u + 1013904223u;
    return (uint8_t)(rng >> 24);
}

static void planar_to_rows_matches_the_definition(void **state)
{
    (void)state;
    static const size_t csizes[] = {1, 2, 4};
    enum { MAXW = 70, MAXH = 3, PAD = 24 };
    static _Alignas(16) uint8_t src[4 * MAXW * MAXH * 4];
    static _Alignas(16) uint8_t got[(MAXW * 16 + PAD) * MAXH], want[sizeof got];
    for (size_t ci = 0; ci < 3; ci++)
        for (unsigned nc = 1; nc <= 4; nc++)
            for (uint32_t w = 1; w <= MAXW; w += w < 20 ? 1 : 7)
                for (uint32_t h = 1; h <= MAXH; h++) {
                    size_t cs = csizes[ci], ts = cs * nc;
                    size_t stride = w * ts + (h & 1 ? 0 : PAD); /* a tile inside wider rows */
                    for (size_t i = 0; i < (size_t)w * h * ts; i++)
                        src[i] = rnd();
                    memset(got, 0xee, sizeof got);
                    memset(want, 0xee, sizeof want);
                    st_ptx_planar_to_rows(cs, nc, src, w, h, got, stride);
                    for (unsigned c = 0; c < nc; c++)
                        for (uint32_t y = 0; y < h; y++)
                            for (uint32_t x = 0; x < w; x++)
                                memcpy(want + y * stride + x * ts + c * cs,
                                       src + (((size_t)c * h + y) * w + x) * cs, cs);
                    assert_memory_equal(got, want, sizeof got);
                }
}

static void undiff_is_a_running_sum(void **state)
{
    (void)state;
    enum { MAX = 600 };
    static _Alignas(16) uint8_t a[MAX], b[MAX];
    for (size_t cs = 1; cs <= 2; cs++)
        for (size_t n = 0; n < MAX; n += cs * (n < 80 ? 1 : 13)) {
            for (size_t i = 0; i < n; i++)
                a[i] = b[i] = rnd();
            st_ptx_undiff(cs, a, n);
            if (cs == 1) {
                uint8_t prev = 0;
                for (size_t i = 0; i < n; i++)
                    prev = b[i] = (uint8_t)(b[i] + prev);
            } else {
                uint16_t prev = 0;
                for (size_t i = 0; i + 1 < n; i += 2) {
                    uint16_t v;
                    memcpy(&v, b + i, 2);
                    prev = (uint16_t)(v + prev);
                    memcpy(b + i, &prev, 2);
                }
            }
            assert_memory_equal(a, b, n ? n : 1);
        }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(planar_to_rows_matches_the_definition),
        cmocka_unit_test(undiff_is_a_running_sum),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

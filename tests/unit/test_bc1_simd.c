/* tests/unit/test_bc1_simd.c - the BC1 encoder's AVX2 and SSE2 paths write the same blocks.
 *
 * Owns: the library's encoder, which takes the AVX2 twins (store/bc1/bc1_encode_avx2.c) on
 * CPUs that have them, compared block for block with the same encoder with the twins turned
 * off (st_bc1e_encode_block with avx2 = 0: every call site then takes its SSE2 path): random,
 * gradient and few-colour blocks, 1-bit alpha, per-texel weights, every level, and images of
 * the BC1 benchmark set (the image entry point against the blocks encoded one by one, edge
 * padding included). Does not own: the encoder's quality (test_bc1.c). On a CPU without AVX2
 * both sides run SSE2 and the comparison is trivially equal (the test says so).
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "bc1.h"
#include "bc1_encode_internal.h"
#include "image.h"
#include "image_io.h"
#include "../common/testdata.h"

/* The SSE2-only encoder: the library's block encoder with the AVX2 twins off. */
static void sse2only_encode_block_w(const uint8_t rgba[64], const float weight[16], int level,
                                    uint8_t out[8])
{
    st_bc1e_encode_block(rgba, weight, level, 0, out);
}

/* An image block by block, edge blocks padded by repeating the last row / column as
 * st_bc1_encode_image does (bc1.h). */
static void sse2only_encode_image(const uint8_t *rgba, uint32_t w, uint32_t h, int level,
                                  uint8_t *blocks)
{
    uint32_t bw = (w + 3) / 4, bh = (h + 3) / 4;
    for (uint32_t by = 0; by < bh; by++)
        for (uint32_t bx = 0; bx < bw; bx++) {
            uint8_t tmp[64];
            for (uint32_t t = 0; t < 16; t++) {
                uint32_t x = bx * 4 + (t & 3), y = by * 4 + (t >> 2);
                x = x < w ? x : w - 1;
                y = y < h ? y : h - 1;
                memcpy(tmp + 4 * t, rgba + ((size_t)y * w + x) * 4, 4);
            }
            sse2only_encode_block_w(tmp, NULL, level, blocks + ((size_t)by * bw + bx) * 8);
        }
}

static uint32_t rng_state = 777;
static uint32_t rnd(void)
{
    rng_state = rng_state * 1664525u + 1013904223u;
    return rng_state >> 8;
}

/* kind 0: noise, 1: gradient with noise, 2: a few colours, 3: nearly flat */
static void make_block(uint8_t px[64], int kind)
{
    uint8_t pal[4][3];
    for (int j = 0; j < 4; j++)
        for (int k = 0; k < 3; k++)
            pal[j][k] = (uint8_t)rnd();
    int base[3] = {(int)(rnd() % 220), (int)(rnd() % 220), (int)(rnd() % 220)};
    for (int t = 0; t < 16; t++) {
        for (int k = 0; k < 3; k++) {
            int v;
            if (kind == 0)
                v = (int)(rnd() & 255);
            else if (kind == 1)
                v = base[k] + 3 * (t & 3) + 2 * (t >> 2) + (int)(rnd() % 9) - 4;
            else if (kind == 2)
                v = pal[rnd() % (2 + (unsigned)t % 3)][k];
            else
                v = base[k] + (int)(rnd() % 3);
            px[4 * t + k] = (uint8_t)(v < 0 ? 0 : v > 255 ? 255 : v);
        }
        px[4 * t + 3] = 255;
    }
}

static void avx2_and_sse2_paths_write_the_same_blocks(void **state)
{
    (void)state;
    print_message("# CPU %s AVX2\n", st_bc1e_cpu_avx2() ? "has" : "has no");
    int differ = 0;
    for (int n = 0; n < 6000; n++) {
        uint8_t px[64], a[8], b[8];
        make_block(px, n % 4);
        int level = n % 3;
        float wt[16];
        const float *w = NULL;
        if (n % 5 == 1) { /* 1-bit alpha holes */
            for (int t = 0; t < 16; t++)
                if (rnd() % 4 == 0)
                    px[4 * t + 3] = (uint8_t)(rnd() % 128);
        } else if (n % 5 == 2) { /* per-texel weights, some zero */
            for (int t = 0; t < 16; t++)
                wt[t] = rnd() % 4 == 0 ? 0.0f : 0.05f + (float)(rnd() % 100) * 0.03f;
            w = wt;
        }
        st_bc1_encode_block_w(px, w, level, a);
        sse2only_encode_block_w(px, w, level, b);
        if (memcmp(a, b, 8) != 0 && differ++ < 5)
            print_message("# block %d (kind %d, level %d) differs\n", n, n % 4, level);
    }
    assert_int_equal(differ, 0);
}

static void avx2_and_sse2_paths_agree_on_real_images(void **state)
{
    (void)state;
    static const char *names[] = {"images/bc1-set/kodim23.png", "images/bc1-set/colobot_apollo.png"};
    for (int i = 0; i < 2; i++) {
        char path[1024];
        if (st_test_data_path(path, sizeof path, names[i]) != 0) {
            skip();
            return;
        }
        st_image im;
        st_error e;
        assert_int_equal(st_image_read(path, NULL, &im, &e), 0);
        assert_int_equal(im.dtype, ST_DT_U8);
        /* a 254x250 crop (partial edge blocks), RGB(A) to RGBA8 */
        uint32_t W = im.w < 254 ? im.w : 254, H = im.h < 250 ? im.h : 250;
        uint8_t *rgba = malloc((size_t)W * H * 4);
        assert_non_null(rgba);
        for (uint32_t y = 0; y < H; y++)
            for (uint32_t x = 0; x < W; x++) {
                const uint8_t *p = (const uint8_t *)im.data + ((size_t)y * im.w + x) * im.nchan;
                uint8_t *q = rgba + ((size_t)y * W + x) * 4;
                q[0] = p[0];
                q[1] = im.nchan >= 3 ? p[1] : p[0];
                q[2] = im.nchan >= 3 ? p[2] : p[0];
                q[3] = 255;
            }
        st_image_free(&im);
        size_t nb = (size_t)((W + 3) / 4) * ((H + 3) / 4) * 8;
        uint8_t *a = malloc(nb), *b = malloc(nb);
        assert_non_null(a);
        assert_non_null(b);
        for (int level = ST_BC1_FAST; level <= ST_BC1_BEST; level++) {
            assert_int_equal(st_bc1_encode_image(rgba, W, H, (size_t)W * 4, level, 1, a, &e), 0);
            sse2only_encode_image(rgba, W, H, level, b);
            assert_memory_equal(a, b, nb);
        }
        free(a);
        free(b);
        free(rgba);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(avx2_and_sse2_paths_write_the_same_blocks),
        cmocka_unit_test(avx2_and_sse2_paths_agree_on_real_images),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

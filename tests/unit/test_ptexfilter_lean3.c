/* tests/unit/test_ptexfilter_lean3.c - session 19 (gs12): the lean walks of ptexfilter_walk.c
 * for a kernel over one u edge and one v edge whose corner has no cornerface (lean_two3: a
 * vertex of valence 3, the corner piece dropped and its weight removed, as corner() does)
 * or one of whose two edges is at a mesh boundary (lean_fold_one: the boundary axis folded,
 * then lean_one's two pieces), and the loop-free sums of ptexfilter_kernel.h
 * (pk_accumulate4, pk_nonzero_mask24).
 *
 * The walks' outputs, coverage and status must be the general path's
 * (pf_batch_path(PF_PATH_GENERAL): every query through eval) bit for bit: queries near a
 * corner of a face or anywhere, footprints relative to the face (kernels at resolution 1,
 * 2, 4, 8 and finer, the axes alike or not), on files with valence-3 corners and rotated
 * neighbours (the cubes), valence-5 corners (holeycube: no cornerface, not valence 3, the
 * general walk's), and open meshes with faces of mixed sizes (the dispplane and nonquad
 * planes: boundary edges beside neighbours, smaller neighbours); as read, with a tenth of
 * the faces flagged constant, then subface, and under border modes with u and v unlike
 * (black along one axis only: each fold with its own axis' black); every kernel filter,
 * every mode. The sums against pk_accumulate's loop and pk_nonzero_mask12, bit for bit
 * (a NaN for a NaN: its sign and payload are the compiler's), over values with zeros of
 * both signs, NaN, infinities and subnormals, and garbage past the taps. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "ptex.h"
#include "ptexfilter.h"
#include "ptexfilter_kernel.h"
#include "sample.h"
#include "../common/pffiles.h"
#include "../common/pfpaths.h"
#include "../common/testdata.h"

enum { NQ = 3000 };

static uint32_t rng = 41;
static float rnd01(void) /* [0, 1) */
{
    rng = rng * 1664525u + 1013904223u;
    return (float)(rng >> 8) / 16777216.0f;
}

static const unsigned filters[] = {ST_FILTER_PTEX_BOX, ST_FILTER_PTEX_GAUSSIAN,
                                   ST_FILTER_PTEX_BICUBIC, ST_FILTER_PTEX_CATMULLROM,
                                   ST_FILTER_PTEX_MITCHELL};
enum { NF = sizeof filters / sizeof filters[0] };

/* Both paths on q, every filter and mode: the queries compared, or -1 (printed). */
static long agree(const st_set *s, const st_query *q, const char *what)
{
    return st_pf_paths_agree(s, q, NQ, what, filters, NF);
}

/* Queries: a uniform face, footprints relative to it (the axes alike but for every third),
 * (u, v) within a tenth of a corner for three in four, anywhere for the rest. */
static void corner_queries(const st_set *s, st_query *q)
{
    static const float rel[] = {0.25f, 0.3f, 0.5f, 0.75f, 1.0f, 0.125f, 0.0625f, 0.2f};
    for (int j = 0; j < NQ; j++) {
        uint32_t f = (uint32_t)(rnd01() * (float)s->info.nfaces) % s->info.nfaces;
        float ru = rel[(int)(rnd01() * 8) & 7];
        float rv = j % 3 == 1 ? rel[(int)(rnd01() * 8) & 7] : ru;
        float u = rnd01(), v = rnd01();
        if (j % 4 != 0) {
            u = rnd01() < 0.5f ? u * 0.1f : 1.0f - u * 0.1f;
            v = rnd01() < 0.5f ? v * 0.1f : 1.0f - v * 0.1f;
        }
        u = u < 0.99999994f ? u : 0.99999994f;
        v = v < 0.99999994f ? v : 0.99999994f;
        q[j] = (st_query){.face = f, .u = u, .v = v, .dudx = ru, .dvdy = rv};
    }
}

static long lean3_file(st_set *s, void *ctx, const char *path)
{
    st_query *q = ctx;
    corner_queries(s, q);
    long n = agree(s, q, path), c; /* also builds the table */
    uint8_t bu = s->info.border_u, bv = s->info.border_v;
    static const uint8_t modes[][2] = {{1, 0}, {0, 1}, {1, 1}, {2, 0}}; /* 1 black, 2 periodic */
    for (size_t i = 0; n >= 0 && i < sizeof modes / sizeof modes[0]; i++) {
        s->info.border_u = modes[i][0];
        s->info.border_v = modes[i][1];
        n = (c = agree(s, q, path)) < 0 ? -1 : n + c;
    }
    s->info.border_u = bu;
    s->info.border_v = bv;
    st_pf_flag_faces(s, ST_FACE_CONSTANT, 0);
    if (n >= 0)
        n = (c = agree(s, q, path)) < 0 ? -1 : n + c;
    st_pf_flag_faces(s, ST_FACE_SUBFACE, ST_FACE_CONSTANT);
    if (n >= 0)
        n = (c = agree(s, q, path)) < 0 ? -1 : n + c;
    return n;
}

static void lean_walks_of_valence3_and_boundary_corners_match_the_general_walk(void **state)
{
    (void)state;
    static const char *const files[] = {
        "ptex-ref/cube1_k6_u8.ptx",
        "ptex-ref/cube8_k6_u8.ptx",
        "ptex-ref/cube8_k6_u8_rot.ptx",
        "ptex-ref/cube8_k7varrot_f32.ptx",
        "ptx/wdas-ptex-samples/holeycube/holeycube.ptx",
        "ptx/wdas-ptex-2009/dispplane/rand_lo/pPlane1.ptx",
        "ptx/wdas-ptex-2009/dispplane/wave_lo/pPlane1.ptx",
        "ptx/wdas-ptex-2009/nonquad/test/pPlane1.ptx",
    };
    static st_query q[NQ];
    int found;
    long compared = st_pf_each_file(files, sizeof files / sizeof files[0], lean3_file, q, &found);
    assert_true(compared >= 0);
    if (!found) {
        print_message("SEAMTEX_DATA (%s) has none of the files: skipped\n", st_test_data_dir());
        skip();
    }
    print_message("%d files, %ld queries compared\n", found, compared);
}

/* A value for the sums: zeros of both signs, NaN, infinities, subnormals, or a float of
 * any magnitude and sign. */
static float odd_value(void)
{
    switch ((int)(rnd01() * 10)) {
    case 0: return 0.0f;
    case 1: return -0.0f;
    case 2: return NAN;
    case 3: return rnd01() < 0.5f ? INFINITY : -INFINITY;
    case 4: return 1e-40f * (rnd01() - 0.5f);
    default: return (rnd01() - 0.5f) * powf(2.0f, (float)(int)(rnd01() * 40) - 20);
    }
}

/* The same bits, or both NaN: which NaN a sum of two NaNs gives (x86 keeps the first
 * operand's) is the compiler's choice, as fadd commutes - clang puts the intrinsic sum's
 * operands the other way round, so inf + -inf (the default NaN, sign set) + NAN gave
 * 0x7fc00000 in pk_accumulate4 and 0xffc00000 in the loop. C and IEEE 754 leave the
 * payload and sign of a NaN result unspecified; the sums only promise "NaN stays NaN". */
static int same_bits(float a, float b)
{
    if (a != a && b != b)
        return 1;
    uint32_t x, y;
    memcpy(&x, &a, 4);
    memcpy(&y, &b, 4);
    return x == y;
}

static void loop_free_sums_match_the_loops(void **state)
{
    (void)state;
    long bad = 0;
    float w[PK_MAX];
    for (int t = 0; t < 200000; t++) {
        for (int i = 0; i < PK_MAX; i++)
            w[i] = odd_value(); /* past the taps: garbage the sums must ignore */
        int n4 = 1 + (int)(rnd01() * 4);
        bad += !same_bits(pk_accumulate4(w, n4), pk_accumulate(w, n4));
        int n12 = 1 + (int)(rnd01() * 12);
        for (int i = 0; i < n12; i++) /* zero taps at the ends, as pk_strip_zeros sees them */
            if (rnd01() < 0.3f)
                w[i] = rnd01() < 0.5f ? 0.0f : -0.0f;
        bad += pk_nonzero_mask24(w, n12) != pk_nonzero_mask12(w, n12);
    }
    assert_int_equal(bad, 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(loop_free_sums_match_the_loops),
        cmocka_unit_test(lean_walks_of_valence3_and_boundary_corners_match_the_general_walk),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
